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
    /// Hybrid: elbow threshold (thesis Fig. 4.5) on the lights' luminance. Default 0.02 (the
    /// decomposition's own default is 0.05): St Peter's many dim windows are cut to 10 by the
    /// elbow at 0.05; with 16 lights the hybrid's error against an 8192-spp reference falls
    /// from 0.0115 to 0.0083 (docs/RESULTS.md section 5).
    #[arg(long, default_value_t = 0.02)]
    pub threshold: f32,
    /// Hybrid: at most this many lights (one shadow map each). Default 16 (see `--threshold`).
    #[arg(long, default_value_t = 16)]
    pub max_lights: usize,
    /// Hybrid: a light must carry at least this fraction of the environment's luminous power.
    #[arg(long, default_value_t = 0.01)]
    pub min_share: f32,
    /// Hybrid: shadow map size (texels per side).
    #[arg(long, default_value_t = 2048)]
    pub shadow_map_size: u32,
    /// Hybrid: percentage-closer filtering kernel width, texels.
    #[arg(long, default_value_t = 3)]
    pub pcf: u32,
    /// Hybrid: the thesis' behaviour (the SH part keeps the lights' energy; point lights with
    /// hard PCF shadows) instead of relight's (caps removed before the SH projection; area
    /// lights the size of the radiance each cap removed, with soft shadows and the exact
    /// cosine over that disc).
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
            min_share: self.min_share,
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

/// The renderer's lights (world frame) of a decomposition of `env`.
///
/// relight's lights (`thesis = false`) are the size of the radiance their cap removed
/// ([`ExtractedLight::extent`], at most the cap radius): a 2-degree window extracted with a
/// 5-degree cap casts the penumbrae of a 2-degree source (St Peter's, 16 lights: hybrid error
/// 0.0098 -> 0.0083 against an 8192-spp reference, docs/RESULTS.md section 5). The thesis'
/// point lights keep the cap radius (unused by their hard shadows and plain cosine). Each
/// light's irradiance at normal incidence is that of a uniform disc of its radius `r` holding
/// the removed power: `power (1 + cos r) / 2` (`pi sin^2 r / (2 pi (1 - cos r))`).
///
/// [`ExtractedLight::extent`]: relight_sphere::decompose::ExtractedLight::extent
pub fn hybrid_lights(dec: &Decomposition, env: &Environment, thesis: bool) -> Vec<HybridLight> {
    dec.lights
        .iter()
        .map(|l| {
            let radius = if thesis { l.cap_radius } else { l.extent };
            let irradiance = l.power * (0.5 * (1.0 + radius.cos()));
            HybridLight::from_map_frame(l.dir, irradiance, radius, env)
        })
        .collect()
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
    let lights = hybrid_lights(&dec, env, opts.thesis);
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

#[cfg(test)]
mod tests {
    use super::*;
    use relight_sphere::decompose::sky_with_discs;

    #[test]
    fn lights_are_the_size_of_what_their_cap_removed() {
        // One 2-degree disc, extracted with the default 5-degree cap.
        let sun = Vec3::new(0.3, 0.8, 0.2).normalize();
        let env = Environment::new(sky_with_discs(32, &[(sun, 2.0, Vec3::splat(300.0))]));
        let d = HybridOpts::default().settings(5).unwrap().0;
        let dec = decompose_env(&env, &d).unwrap();
        assert_eq!(dec.lights.len(), 1);
        let l = &dec.lights[0];
        let ours = hybrid_lights(&dec, &env, false)[0];
        let thesis = hybrid_lights(&dec, &env, true)[0];
        // The disc is 2 degrees plus a 1-degree smoothstep edge, sampled by 2.8-degree texels:
        // its measured extent lies well inside the 5-degree cap.
        assert!(ours.cap_radius == l.extent && ours.cap_radius < 3.5f32.to_radians());
        assert_eq!(thesis.cap_radius, l.cap_radius);
        for (light, r) in [(ours, l.extent), (thesis, l.cap_radius)] {
            // Same power either way; only the normal-incidence factor (1 + cos r) / 2 differs.
            let expect = l.power * (0.5 * (1.0 + r.cos()));
            assert!((light.power - expect).abs().max_element() < 1e-6 * expect.max_element());
            assert!(light.dir.dot(l.dir) > 1.0 - 1e-6); // unrotated environment
        }
        // The thesis' light, at normal incidence, matches the decomposition's uniform cap.
        let e = l.irradiance(l.dir);
        assert!((thesis.power - e).abs().max_element() < 1e-5 * e.max_element());
    }
}
