//! What the frames on a prefiltered environment (`sg`, Green 2005 sec. 3.3; `vmf`,
//! Laurijssen & Dutré 2009 sec. 6.2) share: the lighting kept with its environment (for the
//! background), set and timed by `set_environment`, and the output of a deferred render.

use crate::{ms_since, FrameOptions, FrameOutput, FrameTimes, MethodError, PrepareTimes};
use relight_render::raster::{RasterOptions, Rendered};
use relight_render::shade_sg::SgLighting;
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use std::time::Instant;

/// A frame's prefiltered lighting and the environment it came from (`None` before
/// `set_environment`).
pub(crate) type Lit = Option<(SgLighting, Environment)>;

/// Store `make()`'s lighting of `env` in `slot`, timed as the environment's preparation.
pub(crate) fn set_lighting(
    slot: &mut Lit,
    env: &Environment,
    make: impl FnOnce() -> SgLighting,
) -> PrepareTimes {
    let t0 = Instant::now();
    *slot = Some((make(), env.clone()));
    PrepareTimes {
        environment_ms: ms_since(t0),
        shade_ms: 0.0,
    }
}

/// Render with `slot`'s lighting: `render(lighting, camera, background, raster options)`
/// returns the image and its per-vertex and per-pixel milliseconds.
///
/// # Panics
/// Before `set_environment` (the `Frame` contract).
pub(crate) fn render_lit(
    slot: &Lit,
    camera: &Camera,
    opts: &FrameOptions,
    render: impl FnOnce(
        &SgLighting,
        &Camera,
        Option<&Environment>,
        &RasterOptions,
    ) -> (Rendered, f64, f64),
) -> FrameOutput {
    let (lighting, env) = slot.as_ref().expect("set_environment before render");
    let (img, vertex_ms, pixel_ms) = render(
        lighting,
        camera,
        opts.background.then_some(env),
        &RasterOptions {
            supersample: opts.supersample,
        },
    );
    FrameOutput {
        image: img.image,
        times: FrameTimes {
            vertex_ms,
            pixel_ms,
        },
    }
}

/// Largest finest face size of a prefiltered chain.
pub const MAX_PREFILTER_SIZE: usize = 1024;

/// `size` as the finest face of `method`'s prefiltered chain: a power of two up to
/// [`MAX_PREFILTER_SIZE`].
///
/// # Errors
/// [`MethodError::Settings`] naming the method and the size otherwise.
pub(crate) fn check_prefilter_size(size: usize, method: &str) -> Result<(), MethodError> {
    if size.is_power_of_two() && size <= MAX_PREFILTER_SIZE {
        Ok(())
    } else {
        Err(MethodError::Settings(format!(
            "{method} prefilter size {size} is not a power of two up to {MAX_PREFILTER_SIZE}"
        )))
    }
}
