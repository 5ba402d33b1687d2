//! The `sh` frame: project the environment to SH once (optionally windowed and truncated),
//! rotate it into the world frame, one dot product per vertex, then rasterise any camera.

use super::ShBaked;
use crate::PrepareTimes;
use crate::{ms_since, Frame, FrameOptions, FrameOutput, MethodError, MethodKind};
use glam::Vec3;
use relight_render::raster::{self, RasterOptions};
use relight_render::shade_sh;
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use relight_sphere::sh::{self, sh_count, Window};
use relight_sphere::sh_rotate::ShRotation;
use std::time::Instant;

/// Settings of the `sh` frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShFrameSettings {
    /// Window of the lighting's SH against ringing (Sloan 2008).
    pub window: Window,
    /// SH order of the lighting, at most the bake's (`None`: the bake's). The SH basis is
    /// hierarchical, so this is the bake truncated to that order.
    pub sh_order: Option<usize>,
}

impl Default for ShFrameSettings {
    /// No window, the bake's order.
    fn default() -> Self {
        ShFrameSettings {
            window: Window::None,
            sh_order: None,
        }
    }
}

/// Check an SH order asked for against the bake's, `None` meaning the bake's.
pub(crate) fn lighting_order(
    asked: Option<usize>,
    bake_order: usize,
) -> Result<usize, MethodError> {
    match asked {
        None => Ok(bake_order),
        Some(o) if (1..=bake_order).contains(&o) => Ok(o),
        Some(o) => Err(MethodError::Settings(format!(
            "SH order {o} is not in 1..={bake_order} (the bake's order)"
        ))),
    }
}

/// SH lighting in the world frame: project the map to `order`, window, rotate by
/// `world_from_env`, scale.
pub fn world_light(env: &Environment, order: usize, window: Window) -> Vec<Vec3> {
    let mut c = sh::project_env(&env.map, order);
    sh::apply_window(&mut c, order, window);
    let mut c = ShRotation::new(order, env.world_from_env()).apply(&c);
    c.iter_mut().for_each(|v| *v *= env.scale);
    c
}

/// The `sh` frame over a bake.
pub struct ShFrame<'a> {
    baked: &'a ShBaked,
    window: Window,
    order: usize,
    /// Per-vertex radiance under the prepared environment.
    radiance: Vec<Vec3>,
    env: Option<Environment>,
}

impl<'a> ShFrame<'a> {
    /// A frame over `baked`.
    ///
    /// # Errors
    /// [`MethodError::Settings`] for an SH order above the bake's.
    pub fn new(baked: &'a ShBaked, s: &ShFrameSettings) -> Result<Self, MethodError> {
        if let Window::Sloan { lambda } = s.window {
            if !(lambda.is_finite() && lambda >= 0.0) {
                return Err(MethodError::Settings(format!(
                    "window sloan:{lambda}: lambda must be finite and non-negative"
                )));
            }
        }
        Ok(ShFrame {
            baked,
            window: s.window,
            order: lighting_order(s.sh_order, baked.transfer.order)?,
            radiance: vec![],
            env: None,
        })
    }

    /// The per-vertex radiance under the prepared environment.
    pub fn vertex_radiance(&self) -> &[Vec3] {
        &self.radiance
    }
}

impl Frame for ShFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Sh
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareTimes, MethodError> {
        let t0 = Instant::now();
        let mut light = world_light(env, self.order, self.window);
        // Truncation: zero lighting above the order asked for.
        light.resize(sh_count(self.baked.transfer.order), Vec3::ZERO);
        let environment_ms = ms_since(t0);
        let t1 = Instant::now();
        let b = self.baked;
        let albedo = (b.transfer.channels == 1).then_some(&b.albedo[..]);
        self.radiance = shade_sh::shade(&b.transfer, albedo, &light);
        self.env = Some(env.clone());
        Ok(PrepareTimes {
            environment_ms,
            shade_ms: ms_since(t1),
        })
    }

    fn render(&self, camera: &Camera, opts: &FrameOptions) -> FrameOutput {
        let env = self.env.as_ref().expect("set_environment before render");
        let t0 = Instant::now();
        let image = raster::render_with(
            &self.baked.scene.mesh,
            camera,
            &self.radiance,
            opts.background.then_some(env),
            &RasterOptions {
                supersample: opts.supersample,
            },
        )
        .image;
        FrameOutput::rasterised_since(image, t0)
    }

    fn summary(&self) -> String {
        format!(
            "SH order {} ({} transfer), {} vertices",
            self.order,
            self.baked.transfer.kind.name(),
            self.baked.transfer.vertex_count
        )
    }
}
