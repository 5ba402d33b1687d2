//! [`GpuError`]: why the GPU renderer could not start or render.

use relight_method::MethodError;

/// Errors of the GPU renderer. Messages say what to install or change.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No Vulkan adapter was found (no loader, no driver, or none that wgpu accepts).
    #[error(
        "no Vulkan GPU adapter found ({0}); install a Vulkan driver and its loader: on Debian \
         `apt-get install mesa-vulkan-drivers libvulkan1` (Mesa's lavapipe runs on the CPU), \
         or your GPU vendor's driver"
    )]
    NoAdapter(String),
    /// The adapter was found but a device could not be created from it.
    #[error("cannot open the GPU device {adapter}: {message}")]
    Device {
        /// The adapter's name.
        adapter: String,
        /// What wgpu said.
        message: String,
    },
    /// The frame asks for something this renderer does not do (yet), or exceeds a device limit.
    #[error("{0}")]
    Unsupported(String),
    /// The method layer refused the settings or the environment.
    #[error(transparent)]
    Method(#[from] MethodError),
    /// The GPU reported an error while rendering (validation, out of memory, lost device).
    #[error("GPU error: {0}")]
    Render(String),
}
