//! The `vmf` frame: the environment's vMF-prefiltered chain, kappa doubling per level (once
//! per map), then per camera the eq. 6 view blend per vertex and the eq. 6 blend per pixel
//! with one fetch per lobe (`relight_render::shade_vmf`, paper section 6.2).

use super::VmfBaked;
use crate::prefiltered::{check_prefilter_size, render_lit, set_lighting, Lit};
use crate::{Frame, FrameOptions, FrameOutput, MethodError, MethodKind, PrepareTimes};
use relight_render::shade_vmf::{kappa_resolved, vmf_lighting, VmfRenderer};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;

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
    lighting: Lit,
}

impl<'a> VmfFrame<'a> {
    /// A frame over `baked` (a whole bake).
    ///
    /// # Errors
    /// [`MethodError::Settings`] for a prefilter size that is not a power of two up to 1024.
    pub fn new(baked: &'a VmfBaked, s: &VmfFrameSettings) -> Result<Self, MethodError> {
        check_prefilter_size(s.prefilter_size, "vmf")?;
        Ok(VmfFrame {
            baked,
            renderer: VmfRenderer::new(&baked.scene.mesh, &baked.bake).with_vertex_materials(
                relight_bake::sg::transport::vertex_materials(
                    &baked.scene.mesh,
                    &baked.scene.materials,
                ),
            ),
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
        let order = self.baked.settings.diffuse_sh_order as usize;
        let size = self.prefilter_size;
        Ok(set_lighting(&mut self.lighting, env, || {
            vmf_lighting(env, size, order)
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
