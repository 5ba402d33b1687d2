//! # relight-view: the interactive viewer (`relight view`)
//!
//! A bundle relit on the GPU (`relight-gpu`'s frames: `sh`, `hybrid`, `sg`) under an
//! environment the user changes live, next to a progressively refined path-traced reference
//! of the same view (`relight_render::pathtrace`), with the error heat map and the relative
//! RMSE. Built on eframe/egui with its wgpu renderer (the wgpu of `relight-gpu`, one build).
//!
//! How a frame reaches the screen: `relight-gpu` renders into its own textures on its own
//! device and reads the linear-radiance image back (its `render` returns host memory); the
//! viewer tone-maps it on the CPU (`relight_render::tonemap`: `relight render`'s automatic
//! exposure of the first frame, times `2^EV` of the exposure control) and uploads it as an
//! egui texture. This costs a read-back and an upload per frame (measured in
//! docs/RESULTS.md, section GPU renderer) but keeps
//! `relight-gpu`'s frames exactly those its tests compare with the CPU renderer.
//!
//! Failure policy: a bundle or environment that fails to load, a method the GPU cannot
//! render yet, a GPU error are shown in the window (never a panic) and the viewer keeps
//! running; only a missing Vulkan driver (before the window opens), a script that does not
//! parse and a window that cannot open end [`run`] with an error. A scripted run (`--script`)
//! also ends with [`ViewError::Shown`] when any error was shown in the window, so tests and
//! scripts see it in the exit status; every error shown is printed on stdout as
//! `relight view: shown in the window: MESSAGE`.
//!
//! ```no_run
//! let args = relight_view::ViewArgs {
//!     bundle: "bake.relight".into(),
//!     env: None,
//!     script: None,
//!     size: (1280, 800),
//! };
//! if let Err(e) = relight_view::run(&args) {
//!     eprintln!("relight view: {e}");
//!     std::process::exit(1);
//! }
//! ```

mod app;
#[cfg(feature = "cli")]
pub mod cli;
pub mod env;
pub mod orbit;
pub mod reference;
pub mod script;
mod ui;

use std::path::PathBuf;

/// The shortcuts' text (a macro so that `--help` can `concat!` it).
macro_rules! shortcuts {
    () => {
        "left drag: orbit the camera about its target
right drag / shift + left drag: pan
scroll: zoom
ctrl + left drag: rotate the environment
R: reset the view (frame the whole scene)
C: the bundle's own camera
M: next method (sh <-> hybrid)
S: split view against the path-traced reference (off, reference, heat map)
G: draw the environment as background
[ and ]: rotate the environment by -15 / +15 degrees
- and =: exposure -0.5 / +0.5 EV
P: screenshot of the 3D view (relight-view-N.png and .exr in the current folder)
H or F1: this help
Q or Escape: quit"
    };
}
#[cfg_attr(not(feature = "cli"), allow(unused_imports))]
pub(crate) use shortcuts;

/// The keyboard and mouse shortcuts, one per line (`keys: what`), shown in the help panel
/// and in `relight view --help`.
pub const SHORTCUTS: &str = shortcuts!();

/// What `relight view` was asked for.
#[derive(Clone, Debug)]
pub struct ViewArgs {
    /// The baked bundle.
    pub bundle: PathBuf,
    /// An environment map to start with instead of the bundle's.
    pub env: Option<PathBuf>,
    /// A file of scripted actions ([`script`]).
    pub script: Option<PathBuf>,
    /// The window's inner size, logical pixels.
    pub size: (u32, u32),
}

/// Why `relight view` ended with an error.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The script does not parse (file and line named).
    #[error(transparent)]
    Script(#[from] script::ScriptError),
    /// No Vulkan adapter or device (the message says what to install).
    #[error(transparent)]
    Gpu(#[from] relight_gpu::GpuError),
    /// The window could not be opened or the event loop failed.
    #[error("cannot open the viewer's window: {0} (relight view needs a display: set DISPLAY, or run it under Xvfb)")]
    Window(String),
    /// The window size asked for is out of range.
    #[error("window size {0}x{1} is not in 64..=8192")]
    Size(u32, u32),
    /// A scripted run in which the window showed errors.
    #[error("the window showed {} error(s); the first: {}", .0.len(), .0.first().map(String::as_str).unwrap_or(""))]
    Shown(Vec<String>),
}

/// Open the viewer and run it until its window is closed (or its script quits).
///
/// # Errors
/// See [`ViewError`]: the script does not parse, no Vulkan adapter, no window, or (scripted
/// runs only) errors were shown in the window.
pub fn run(args: &ViewArgs) -> Result<(), ViewError> {
    let (w, h) = args.size;
    if !(64..=8192).contains(&w) || !(64..=8192).contains(&h) {
        return Err(ViewError::Size(w, h));
    }
    let script = args
        .script
        .as_deref()
        .map(script::Script::read)
        .transpose()?;
    let gpu = relight_gpu::Gpu::new()?;
    let baked = relight_method::read_any(&args.bundle);
    let outcome = app::Outcome::default();
    let scripted = script.is_some();
    let options = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_title(format!("relight view {}", args.bundle.display()))
            .with_inner_size([w as f32, h as f32])
            .with_drag_and_drop(true),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let shown = outcome.clone();
    eframe::run_native(
        "relight view",
        options,
        Box::new(|cc| {
            Ok(Box::new(app::App::new(
                cc,
                &gpu,
                baked.as_ref().map_err(|e| e.to_string()),
                args,
                script,
                shown,
            )))
        }),
    )
    .map_err(|e| ViewError::Window(e.to_string()))?;
    let errors = outcome.errors();
    if scripted && !errors.is_empty() {
        return Err(ViewError::Shown(errors));
    }
    Ok(())
}
