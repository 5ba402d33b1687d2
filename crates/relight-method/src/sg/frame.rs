//! The `sg` frame: the environment's Gaussian-prefiltered cube chain and SH (once per map),
//! then per camera the view blend per vertex and the lobe blend per pixel
//! (`relight_render::shade_sg`).

use super::SgBaked;
use crate::prefiltered::{check_prefilter_size, render_lit, set_lighting, Lit};
use crate::PrepareTimes;
use crate::{Frame, FrameOptions, FrameOutput, MethodError, MethodKind};
use relight_bake::sg::SgBake;
use relight_render::shade_sg::{LobeBlend, SgLighting, SgRenderer, ShadeOptions};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;

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
    /// How a vertex's lobes are blended across its three nearest views (`linear`: the
    /// thesis' parameters; `energy`: integrals, shape weighted by energy; `split`: the first
    /// lobe linear, the later ones by energy) [default: linear; for a half-vector bake of two
    /// or more lobes energy if nested, split if additive]
    #[cfg_attr(feature = "cli", arg(long = "sg-view-blend", value_enum))]
    pub view_blend: Option<SgViewBlend>,
    /// How a pixel blends its triangle's three corners' lobes [default: energy for a bake
    /// in the light domain, linear for one in the half-vector domain]
    #[cfg_attr(feature = "cli", arg(long = "sg-corner-blend", value_enum))]
    pub corner_blend: Option<SgBlend>,
    /// Which blends permute lobes to a reference's before blending (section 3.4's flips)
    /// [default: both, or none for a half-vector bake]
    #[cfg_attr(feature = "cli", arg(long = "sg-match", value_enum))]
    pub matching: Option<SgMatch>,
}

/// A lobe blend of the frame (`relight_render::shade_sg::LobeBlend`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SgBlend {
    /// Axis, sharpness and amplitude linear (the thesis, section 2.3).
    Linear,
    /// Energies linear, axis and sharpness weighted by energy.
    Energy,
}

/// The blend of a vertex's three nearest views.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SgViewBlend {
    /// Every lobe linear (the thesis, section 2.3).
    Linear,
    /// Every lobe by energy.
    Energy,
    /// Each component's first lobe linear, the later ones by energy (additive lobes:
    /// `ShadeOptions::ADDITIVE_HALF_VECTOR`).
    Split,
}

/// Which blends match lobes before blending.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SgMatch {
    /// Slot `k` with slot `k` everywhere (the thesis).
    None,
    /// Across views only.
    Views,
    /// Across a triangle's corners only.
    Corners,
    /// Both.
    Both,
}

impl std::fmt::Display for SgBlend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SgBlend::Linear => "linear",
            SgBlend::Energy => "energy",
        })
    }
}

impl std::fmt::Display for SgMatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SgMatch::None => "none",
            SgMatch::Views => "views",
            SgMatch::Corners => "corners",
            SgMatch::Both => "both",
        })
    }
}

impl SgFrameSettings {
    /// The renderer's interpolation options for `bake` (what is not set takes
    /// `ShadeOptions::for_bake`).
    pub fn shade_options(&self, bake: &SgBake) -> ShadeOptions {
        let blend = |b| match b {
            SgBlend::Linear => LobeBlend::Linear,
            SgBlend::Energy => LobeBlend::Energy,
        };
        let by_bake = ShadeOptions::for_bake(bake);
        let (match_views, match_corners) = match self.matching {
            None => (by_bake.match_views, by_bake.match_corners),
            Some(m) => (
                matches!(m, SgMatch::Views | SgMatch::Both),
                matches!(m, SgMatch::Corners | SgMatch::Both),
            ),
        };
        let (views, later_views) = match self.view_blend {
            None => (by_bake.views, by_bake.later_views),
            Some(SgViewBlend::Linear) => (LobeBlend::Linear, LobeBlend::Linear),
            Some(SgViewBlend::Energy) => (LobeBlend::Energy, LobeBlend::Energy),
            Some(SgViewBlend::Split) => (LobeBlend::Linear, LobeBlend::Energy),
        };
        ShadeOptions {
            views,
            later_views,
            match_views,
            corners: self.corner_blend.map_or(by_bake.corners, blend),
            match_corners,
        }
    }
}

impl Default for SgFrameSettings {
    /// A 128-texel finest level; the renderer's default interpolation
    /// (`ShadeOptions::for_bake`: light-domain lobes views linear, corners by energy, matched
    /// in both blends; one half-vector lobe linear, unmatched; nested half-vector lobes
    /// views by energy, corners linear, unmatched; additive ones the same but the first
    /// lobe's views linear; the test `frame_settings_map_onto_the_renderers_interpolation`
    /// keeps the two equal).
    fn default() -> Self {
        SgFrameSettings {
            prefilter_size: 128,
            view_blend: None,
            corner_blend: None,
            matching: None,
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
            renderer: SgRenderer::new(&baked.scene.mesh, &baked.bake)
                .with_options(s.shade_options(&baked.bake)),
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
