//! The `vmf` frame: the environment's vMF-prefiltered chain, kappa doubling per level (once
//! per map), then per camera the eq. 6 view blend per vertex and the eq. 6 blend per pixel
//! with one fetch per lobe (`relight_render::shade_vmf`, paper section 6.2).

use super::VmfBaked;
use crate::{
    ms_since, Frame, FrameOptions, FrameOutput, FrameTimes, MethodError, MethodKind, PrepareTimes,
};
use relight_render::raster::RasterOptions;
use relight_render::shade_sg::SgLighting;
use relight_render::shade_vmf::{kappa_resolved, vmf_lighting, VmfRenderer};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use std::time::Instant;

/// Largest finest face size of the prefiltered chain.
pub const MAX_PREFILTER_SIZE: usize = 1024;

/// Settings of the `vmf` frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(
    feature = "cli",
    command(next_help_heading = "vMF render (--method vmf)")
)]
pub struct VmfFrameSettings {
    /// Face size of the finest level of the vMF-prefiltered cube chain (a power of two up to
    /// 1024; kappa doubles per level, the finest resolves kappa = size^2 / 4; sharper lobes
    /// are widened to it with their energy kept).
    #[cfg_attr(feature = "cli", arg(id = "vmf_prefilter_size", long = "vmf-prefilter-size", default_value_t = VmfFrameSettings::default().prefilter_size))]
    pub prefilter_size: usize,
}

impl Default for VmfFrameSettings {
    /// A 128-texel finest level (kappa up to 4096).
    fn default() -> Self {
        VmfFrameSettings {
            prefilter_size: 128,
        }
    }
}

/// The `vmf` frame over a bake.
pub struct VmfFrame<'a> {
    baked: &'a VmfBaked,
    renderer: VmfRenderer<'a>,
    prefilter_size: usize,
    lighting: Option<(SgLighting, Environment)>,
}

impl<'a> VmfFrame<'a> {
    /// A frame over `baked` (a whole bake).
    ///
    /// # Errors
    /// [`MethodError::Settings`] for a prefilter size that is not a power of two up to 1024.
    pub fn new(baked: &'a VmfBaked, s: &VmfFrameSettings) -> Result<Self, MethodError> {
        if !s.prefilter_size.is_power_of_two() || s.prefilter_size > MAX_PREFILTER_SIZE {
            return Err(MethodError::Settings(format!(
                "vmf prefilter size {} is not a power of two up to {MAX_PREFILTER_SIZE}",
                s.prefilter_size
            )));
        }
        Ok(VmfFrame {
            baked,
            renderer: VmfRenderer::new(&baked.scene.mesh, &baked.bake),
            prefilter_size: s.prefilter_size,
            lighting: None,
        })
    }
}

impl Frame for VmfFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Vmf
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareTimes, MethodError> {
        let t0 = Instant::now();
        let order = self.baked.settings.diffuse_sh_order as usize;
        let lighting = vmf_lighting(env, self.prefilter_size, order);
        self.lighting = Some((lighting, env.clone()));
        Ok(PrepareTimes {
            environment_ms: ms_since(t0),
            shade_ms: 0.0,
        })
    }

    fn render(&self, camera: &Camera, opts: &FrameOptions) -> FrameOutput {
        let (lighting, env) = self
            .lighting
            .as_ref()
            .expect("set_environment before render");
        let (img, t) = self.renderer.render(
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
                vertex_ms: t.vertex_ms,
                pixel_ms: t.pixel_ms,
            },
        }
    }

    fn summary(&self) -> String {
        let b = &self.baked.bake;
        let chain = self.lighting.as_ref().map_or(String::new(), |(l, _)| {
            format!(
                ", chain of {} levels up to kappa {}",
                l.prefiltered().levels().len(),
                kappa_resolved(l)
            )
        });
        format!(
            "vmf: {} vertices, {:.1} views per vertex, 6 lobes per slice{chain}",
            self.baked.scene.mesh.vertex_count(),
            b.slices.len() as f64 / b.vertex_count().max(1) as f64
        )
    }
}
