//! # relight-gpu: the headless GPU renderer (wgpu, WGSL, Vulkan)
//!
//! The `sh`, `hybrid`, `sg` and `cuts` frames of `relight-method` on the GPU: the same inputs (a
//! bake, an environment, a camera, [`FrameOptions`]) and the same output (a linear-radiance
//! [`Image`] plus per-pixel coverage), so a GPU frame is compared with the CPU frame pixel
//! by pixel. The interactive viewer (`relight-view`) draws with these frames.
//!
//! | method | once per environment | per frame |
//! |---|---|---|
//! | `sh` | SH projection + rotation (CPU), per-vertex SH dot product (compute pass) | raster pass, resolve pass |
//! | `hybrid` | decomposition, SH part (CPU), per-vertex dot product (compute pass), lights | one depth pass per light and the maps' min pyramids (compute pass) *when the lights changed* (cache key: light directions and map size), shading pass, resolve pass |
//! | `sg` | prefiltered chain (CPU) uploaded as a 6-layer texture with one mip per level | per-vertex view blend (CPU), upload of the blended lobes, lobe matching per triangle (compute pass), shading pass, resolve pass |
//! | `cuts` | light samples' power and illumination cut (CPU, the CPU frame's code) uploaded with every tree node's direction and spread; the vertex cuts once per bake | shading pass (per sample: the sec. 3.2 merge of the light cut and three vertex cuts, Eq. 5 with the BRDF), resolve pass |
//!
//! # Conventions
//! * Rasterisation matches `relight_render::raster`: Mitsuba's perspective camera, samples
//!   at sub-pixel centres on an `n x n` grid per pixel (a `n`-times larger target, then a
//!   box-filter resolve pass), nearest surface wins with ties to the triangle drawn first,
//!   clipping at `1e-5 x` the farthest vertex, perspective-correct interpolation, no
//!   back-face culling. Edge rules differ (the GPU's top-left rule against the CPU's
//!   `(-e, e^2)` nudge), so silhouette samples may differ.
//! * Data layouts the GPU reads are defined once in [`layout`] (`#[repr(C)]`, `Pod`, sizes
//!   asserted at compile time), each naming its WGSL twin in `src/shaders/`.
//! * One `.wgsl` file per method (`sh.wgsl`, `hybrid.wgsl` + `shadow.wgsl`, `sg.wgsl` +
//!   `sg_match.wgsl`, `cuts.wgsl`), with `common.wgsl` (camera, projection), `light.wgsl`, `sg_lobes.wgsl`
//!   and `sh_shade.wgsl` shared; a method adds its shader and one arm of [`frame_of`].
//! * The background ([`FrameOptions::background`]) is drawn in the resolve pass for latlong
//!   and cube maps (the CPU's bilinear fetch); an angular probe's background is refused.
//!
//! ```no_run
//! use relight_gpu::{frame_of, Gpu};
//! use relight_method::{read_any, FrameOptions, FrameSettings, MethodKind};
//! # fn demo(env: &relight_scene::scene::Environment) -> Result<(), relight_gpu::GpuError> {
//! let gpu = Gpu::new()?; // fails with what to install when there is no Vulkan driver
//! let baked = read_any(std::path::Path::new("bake.relight"))?;
//! let mut frame = frame_of(&gpu, &baked, &FrameSettings::default_for(MethodKind::Sh))?;
//! frame.set_environment(env)?;
//! let out = frame.render(&baked.scene().desc.camera, &FrameOptions::default())?;
//! println!("{} draw calls on {}", out.stats.draw_calls, out.stats.adapter);
//! # Ok(()) }
//! ```

mod context;
mod cuts;
mod error;
mod hybrid;
pub mod layout;
mod pipeline;
mod sg;
mod sh;

pub use context::Gpu;
pub use error::GpuError;

use relight_method::{Baked, FrameOptions, FrameSettings, MethodKind};
use relight_render::Image;
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use serde::Serialize;
use std::path::Path;

/// What one GPU frame cost: the counts carry over to a real GPU, the times (on lavapipe, a
/// CPU rasteriser) do not.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    /// The adapter that rendered it.
    pub adapter: String,
    /// Draw calls (shadow maps, shading, resolve).
    pub draw_calls: u32,
    /// Render and compute passes.
    pub passes: u32,
    /// Bytes written from the host to GPU buffers and textures in this frame.
    pub bytes_uploaded: u64,
    /// Shadow maps rendered in this frame (`hybrid`: only when its lights changed).
    pub shadow_maps_rendered: u32,
    /// CPU-side per-frame work before the GPU commands (SG's per-vertex view blend, the
    /// camera), milliseconds.
    pub cpu_ms: f64,
    /// Wall time of the whole frame, image read back to host memory, milliseconds.
    pub total_ms: f64,
}

/// What preparing an environment cost.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PrepareStats {
    /// CPU work on the environment (projection, rotation, decomposition, prefiltering), ms.
    pub environment_ms: f64,
    /// Uploads and GPU work (per-vertex SH dot products), ms.
    pub gpu_ms: f64,
    /// Bytes written to the GPU.
    pub bytes_uploaded: u64,
    /// Compute passes run.
    pub passes: u32,
}

/// A rendered GPU frame.
#[derive(Clone, Debug)]
pub struct GpuOutput {
    /// Linear radiance, as the CPU frame's `FrameOutput::image`.
    pub image: Image,
    /// Per pixel, covered samples / all samples (row-major like the image).
    pub coverage: Vec<f32>,
    /// What it cost.
    pub stats: FrameStats,
}

/// A method's GPU renderer over one bake: prepare an environment, render any camera.
pub trait GpuFrame {
    /// The method.
    fn method(&self) -> MethodKind;

    /// Prepare `env` (map, rotation, scale). Must be called before [`GpuFrame::render`].
    ///
    /// # Errors
    /// The method's refusal of the environment, a device limit, a GPU error.
    fn set_environment(&mut self, env: &Environment) -> Result<PrepareStats, GpuError>;

    /// Render `camera` under the prepared environment.
    ///
    /// # Errors
    /// No environment prepared, options the GPU renderer does not support (an angular
    /// probe's background), an image beyond the device's texture size, a GPU error.
    fn render(&mut self, camera: &Camera, opts: &FrameOptions) -> Result<GpuOutput, GpuError>;

    /// One line saying what is rendered.
    fn summary(&self) -> String;
}

/// The GPU frame of `settings`' method over `baked`.
///
/// # Errors
/// As `Baked::frame_of` (a bake of another kind, a part of a sharded bake, settings out of
/// range), and [`GpuError::Unsupported`] for a method without a GPU shader yet (`vmf`) and
/// for what the `cuts` frame does not render on the GPU yet (bakes of surface samples,
/// texture and normal maps, materials other than Lambert, the GGX conductor and the GGX
/// plastic).
pub fn frame_of<'a>(
    gpu: &'a Gpu,
    baked: &'a Baked,
    settings: &FrameSettings,
) -> Result<Box<dyn GpuFrame + 'a>, GpuError> {
    frame_of_path(gpu, baked, settings, Path::new("<bake>"))
}

/// [`frame_of`] naming the bundle `path` in messages.
///
/// # Errors
/// As [`frame_of`].
pub fn frame_of_path<'a>(
    gpu: &'a Gpu,
    baked: &'a Baked,
    settings: &FrameSettings,
    path: &Path,
) -> Result<Box<dyn GpuFrame + 'a>, GpuError> {
    // The CPU frame's checks, word for word (wrong bake kind, partial bake, settings).
    drop(baked.frame_of(settings, path)?);
    match (baked, settings) {
        (Baked::Sh(b), FrameSettings::Sh(s)) => Ok(Box::new(sh::ShGpuFrame::new(gpu, b, s)?)),
        (Baked::Sh(b), FrameSettings::Hybrid(s)) => {
            Ok(Box::new(hybrid::HybridGpuFrame::new(gpu, b, s)?))
        }
        (Baked::Sg(b), FrameSettings::Sg(s)) => Ok(Box::new(sg::SgGpuFrame::new(gpu, b, s)?)),
        (Baked::Cuts(b), FrameSettings::Cuts(s)) => {
            Ok(Box::new(cuts::CutsGpuFrame::new(gpu, b, s)?))
        }
        (_, s) => Err(GpuError::Unsupported(format!(
            "--method {} has no GPU renderer yet (the GPU renders sh, hybrid, sg and cuts)",
            s.method().name()
        ))),
    }
}

/// One frame rendered from scratch (`relight render --gpu`): its image, a line saying what it
/// cost, and the costs.
#[derive(Clone, Debug)]
pub struct OneFrame {
    /// The frame.
    pub output: GpuOutput,
    /// Preparing the environment.
    pub prepare: PrepareStats,
    /// The frame's summary, adapter and costs in one line.
    pub line: String,
}

/// Start the GPU, prepare `env` and render `camera` once with `settings`' method over `baked`
/// (read from `path`, named in errors).
///
/// # Errors
/// No Vulkan adapter, and as [`frame_of_path`], [`GpuFrame::set_environment`] and
/// [`GpuFrame::render`].
pub fn render_once(
    baked: &Baked,
    settings: &FrameSettings,
    path: &Path,
    env: &Environment,
    camera: &Camera,
    opts: &FrameOptions,
) -> Result<OneFrame, GpuError> {
    let gpu = Gpu::new()?;
    let mut frame = frame_of_path(&gpu, baked, settings, path)?;
    let prepare = frame.set_environment(env)?;
    let output = frame.render(camera, opts)?;
    let s = &output.stats;
    let line = format!(
        "{} on {}: environment {:.1} ms and uploads + GPU per-vertex work {:.1} ms (once per environment); frame {:.1} ms ({} passes, {} draw calls, {} bytes uploaded, CPU {:.2} ms)",
        frame.summary(),
        s.adapter,
        prepare.environment_ms,
        prepare.gpu_ms,
        s.total_ms,
        s.passes,
        s.draw_calls,
        s.bytes_uploaded,
        s.cpu_ms
    );
    Ok(OneFrame {
        output,
        prepare,
        line,
    })
}
