//! The `sg` frame: the environment's Gaussian-prefiltered cube chain and SH (once per map),
//! then per camera the view blend per vertex and the lobe blend per pixel
//! (`relight_render::shade_sg`).

use super::SgBaked;
use crate::prefiltered::{check_prefilter_size, render_lit, set_lighting, Lit};
use crate::PrepareTimes;
use crate::{Frame, FrameOptions, FrameOutput, MethodError, MethodKind};
use relight_render::shade_sg::{SgLighting, SgRenderer};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;

/// Largest base face size of the prefiltered chain.
/// Settings of the `sg` frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(
    feature = "cli",
    command(next_help_heading = "SG render (--method sg)")
)]
pub struct SgFrameSettings {
    /// Face size of the finest level of the Gaussian-prefiltered cube chain (a power of two
    /// up to 1024; levels halve down to 1 texel).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgFrameSettings::default().prefilter_size))]
    pub prefilter_size: usize,
}

impl Default for SgFrameSettings {
    /// A 128-texel finest level.
    fn default() -> Self {
        SgFrameSettings {
            prefilter_size: 128,
        }
    }
}

/// The `sg` frame over a bake.
pub struct SgFrame<'a> {
    baked: &'a SgBaked,
    renderer: SgRenderer<'a>,
    prefilter_size: usize,
    lighting: Lit,
}

impl<'a> SgFrame<'a> {
    /// A frame over `baked`.
    ///
    /// # Errors
    /// [`MethodError::Settings`] for a prefilter size that is not a power of two up to 1024.
    pub fn new(baked: &'a SgBaked, s: &SgFrameSettings) -> Result<Self, MethodError> {
        check_prefilter_size(s.prefilter_size, "sg")?;
        Ok(SgFrame {
            baked,
            renderer: SgRenderer::new(&baked.scene.mesh, &baked.bake),
            prefilter_size: s.prefilter_size,
            lighting: None,
        })
    }

    /// Take a new rotation and scale of the prepared environment's map without prefiltering
    /// again (microseconds: only the diffuse SH is rotated).
    ///
    /// # Panics
    /// If no environment was prepared.
    pub fn set_rotation(&mut self, rotate_y_deg: f32, scale: f32) {
        let (lighting, env) = self.lighting.as_mut().expect("set_environment first");
        env.rotate_y_deg = rotate_y_deg;
        env.scale = scale;
        lighting.set_rotation(env);
    }
}

impl Frame for SgFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Sg
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareTimes, MethodError> {
        let (order, size) = (self.baked.bake.diffuse.order, self.prefilter_size);
        Ok(set_lighting(&mut self.lighting, env, || {
            SgLighting::new(env, order, size)
        }))
    }

    fn render(&self, camera: &Camera, opts: &FrameOptions) -> FrameOutput {
        render_lit(&self.lighting, camera, opts, |l, c, bg, ro| {
            let (img, t) = self.renderer.render(l, c, bg, ro);
            (img, t.vertex_ms, t.pixel_ms)
        })
    }

    fn summary(&self) -> String {
        let b = &self.baked.bake;
        format!(
            "SG: {} vertices, {} direct + {} indirect lobes per vertex and view, diffuse SH order {}",
            self.baked.scene.mesh.vertex_count(),
            b.direct.lobe_count,
            b.indirect.as_ref().map_or(0, |l| l.lobe_count),
            b.diffuse.order
        )
    }
}
