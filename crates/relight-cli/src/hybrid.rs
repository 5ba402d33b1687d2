//! The `hybrid` render path (thesis 4.3-4.4): the environment is decomposed into a low-order
//! SH part, relit by the SH PRT bake, plus a few cap lights rendered with shadow maps.

use crate::store::ShBake;
use anyhow::{bail, Result};
use glam::Vec3;
use relight_render::hybrid::{self, HybridLight, ShadowSettings};
use relight_render::{shade_sh, Image};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use relight_sphere::decompose::{DecomposeSettings, Decomposer, Decomposition};
use relight_sphere::sh::sh_count;
use relight_sphere::sh_rotate::ShRotation;
use std::time::Instant;

/// Options of the hybrid method (every default documented here and in `relight render --help`).
#[derive(clap::Args, Clone, Debug)]
pub struct HybridOpts {
    /// Hybrid: SH order of the environment's slowly varying part (default: the bake's order).
    #[arg(long)]
    pub sh_order: Option<usize>,
    /// Hybrid: standard deviation of the spherical Gaussian smoothing kernel, degrees.
    #[arg(long, default_value_t = 2.5)]
    pub kernel_deg: f32,
    /// Hybrid: cap radius R of every extracted light, degrees.
    #[arg(long, default_value_t = 5.0)]
    pub light_radius: f32,
    /// Hybrid: elbow threshold (thesis Fig. 4.5) on the lights' luminance.
    #[arg(long, default_value_t = 0.05)]
    pub threshold: f32,
    /// Hybrid: at most this many lights.
    #[arg(long, default_value_t = 8)]
    pub max_lights: usize,
    /// Hybrid: shadow map size (texels per side).
    #[arg(long, default_value_t = 2048)]
    pub shadow_map_size: u32,
    /// Hybrid: percentage-closer filtering kernel width, texels.
    #[arg(long, default_value_t = 3)]
    pub pcf: u32,
    /// Hybrid: the thesis' behaviour (the SH part keeps the lights' energy; point lights with
    /// hard PCF shadows) instead of relight's (caps removed before the SH projection; area
    /// lights with soft shadows sized to the cap and the exact cosine over the cap).
    #[arg(long)]
    pub thesis: bool,
}

impl Default for HybridOpts {
    /// The same defaults as the command line's.
    fn default() -> Self {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrap {
            #[command(flatten)]
            o: HybridOpts,
        }
        Wrap::parse_from(["relight"]).o
    }
}

impl HybridOpts {
    /// Decomposition and shadow settings for a bake of SH order `bake_order`.
    pub fn settings(&self, bake_order: usize) -> Result<(DecomposeSettings, ShadowSettings)> {
        let sh_order = self.sh_order.unwrap_or(bake_order);
        if sh_order > bake_order {
            bail!("--sh-order {sh_order} is above the bake's order {bake_order}");
        }
        let d = DecomposeSettings {
            sh_order,
            kernel_deg: self.kernel_deg,
            light_radius_deg: self.light_radius,
            threshold: self.threshold,
            max_lights: self.max_lights,
            remove_caps: !self.thesis,
            ..DecomposeSettings::default()
        };
        d.validate()
            .map_err(|e| anyhow::anyhow!("hybrid settings: {e}"))?;
        if !(16..=16384).contains(&self.shadow_map_size) {
            bail!(
                "--shadow-map-size {} is not in 16..=16384",
                self.shadow_map_size
            );
        }
        let s = ShadowSettings {
            map_size: self.shadow_map_size,
            pcf_taps: self.pcf.max(1),
            area_light: !self.thesis,
            ..ShadowSettings::default()
        };
        Ok((d, s))
    }
}

/// Where the time of one hybrid frame goes.
pub struct HybridTimes {
    /// Decomposition of the environment (only when it changes).
    pub decompose_ms: f64,
    /// SH PRT of the slowly varying part.
    pub shade_ms: f64,
    /// Shadow maps and per-pixel lighting.
    pub render_ms: f64,
}

/// Decompose `env` (in its own frame) with a prepared decomposer.
pub fn decompose_env(env: &Environment, d: &DecomposeSettings) -> Result<Decomposition> {
    let dec = Decomposer::new(d, env.map.layout(), env.map.width(), env.map.height())
        .map_err(|e| anyhow::anyhow!("decomposition: {e}"))?;
    dec.run(&env.map)
        .map_err(|e| anyhow::anyhow!("decomposition: {e}"))
}

/// Render a bake with the hybrid method.
pub fn relight_hybrid(
    bake: &ShBake,
    env: &Environment,
    camera: &Camera,
    opts: &HybridOpts,
    supersample: u32,
    background: bool,
) -> Result<(Image, HybridTimes, Decomposition)> {
    let order = bake.transfer.order;
    let (d, s) = opts.settings(order)?;
    let t0 = Instant::now();
    let dec = decompose_env(env, &d)?;
    let t1 = Instant::now();
    // SH part: map frame -> world, scaled, zero-padded to the bake's order.
    let mut light = ShRotation::new(d.sh_order, env.world_from_env()).apply(&dec.sh);
    light.iter_mut().for_each(|c| *c *= env.scale);
    light.resize(sh_count(order), Vec3::ZERO);
    let albedo = (bake.transfer.channels == 1).then_some(&bake.albedo[..]);
    let radiance = shade_sh::shade(&bake.transfer, albedo, &light);
    let t2 = Instant::now();
    let lights: Vec<HybridLight> = dec
        .lights
        .iter()
        // The renderer wants the irradiance at normal incidence; the decomposition's `power`
        // is the cap's integral of radiance (they differ by pi sin^2 R / (2 pi (1 - cos R))).
        .map(|l| HybridLight::from_map_frame(l.dir, l.irradiance(l.dir), l.cap_radius, env))
        .collect();
    let img = hybrid::render_hybrid(
        &bake.mesh,
        camera,
        &radiance,
        &bake.albedo,
        &lights,
        &s,
        background.then_some(env),
        supersample,
    );
    let t3 = Instant::now();
    let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
    Ok((
        img,
        HybridTimes {
            decompose_ms: ms(t0, t1),
            shade_ms: ms(t1, t2),
            render_ms: ms(t2, t3),
        },
        dec,
    ))
}
