//! Helpers shared by the Mitsuba comparison tests: Mitsuba's two-seed render of an exported
//! scene, the object mask and the agreement measure (`mitsuba_agreement.rs` documents it).
#![allow(dead_code)] // each test file uses a subset

use relight_render::light::PointLight;
use relight_render::mitsuba::{export_mitsuba_lit, mitsuba_python, render_mitsuba};
use relight_render::Image;
use relight_scene::accel::{Ray, RayCaster};
use relight_scene::scene::Scene;

/// Pixels whose centre ray hits geometry.
pub fn object_mask(scene: &Scene, caster: &dyn RayCaster) -> Vec<bool> {
    let f = scene.camera.frame();
    let (w, h) = (scene.camera.width as usize, scene.camera.height as usize);
    (0..w * h)
        .map(|i| {
            let d = f.dir_at((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            caster
                .intersect(&Ray::new(f.origin, d, 0.0, f32::INFINITY))
                .is_some()
        })
        .collect()
}

/// relRMSE of `a` against `b`, the noise floor from the two variance images, and the mean
/// difference in units of its standard error, over masked pixels and channels.
pub struct Agreement {
    /// `sqrt(Σ (a - b)^2 / Σ b^2)`.
    pub rel_rmse: f64,
    /// `sqrt(Σ (var_a + var_b) / Σ b^2)`.
    pub floor: f64,
    /// `|Σ (a - b)|` in standard errors.
    pub bias_sigmas: f64,
}

/// Allowed ratio of relRMSE to the combined noise floor (`mitsuba_agreement.rs` derives it).
pub const K: f64 = 1.5;

/// Allowed mean difference, in standard errors (1 in 15 000 by chance).
pub const MAX_BIAS_SIGMAS: f64 = 4.0;

impl Agreement {
    /// Whether the two images agree: `relRMSE <= K floor` and the mean difference within
    /// [`MAX_BIAS_SIGMAS`] standard errors.
    pub fn holds(&self) -> bool {
        self.rel_rmse <= K * self.floor && self.bias_sigmas < MAX_BIAS_SIGMAS
    }
}

pub fn agreement(a: &Image, var_a: &Image, b: &Image, var_b: &Image, mask: &[bool]) -> Agreement {
    let (mut d2, mut b2, mut v) = (0.0f64, 0.0f64, 0.0f64);
    // Mean difference: summed per pixel over channels; channels of a pixel share their paths,
    // so the pixel's variance is bounded by (Σ_c sd_c)^2 (Cauchy-Schwarz), not Σ_c var_c.
    let (mut d, mut vd) = (0.0f64, 0.0f64);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        let (mut sd_a, mut sd_b) = (0.0f64, 0.0f64);
        for c in 0..3 {
            let (x, y) = (a.pixels[i][c] as f64, b.pixels[i][c] as f64);
            d2 += (x - y) * (x - y);
            b2 += y * y;
            v += var_a.pixels[i][c] as f64 + var_b.pixels[i][c] as f64;
            d += x - y;
            sd_a += (var_a.pixels[i][c] as f64).sqrt();
            sd_b += (var_b.pixels[i][c] as f64).sqrt();
        }
        vd += sd_a * sd_a + sd_b * sd_b;
    }
    Agreement {
        rel_rmse: (d2 / b2).sqrt(),
        floor: (v / b2).sqrt(),
        bias_sigmas: d.abs() / vd.sqrt().max(1e-30),
    }
}

/// Mitsuba's two renders of an exported scene: their mean and its per-pixel variance.
pub struct MitsubaResult {
    /// Mean of the two renders.
    pub mean: Image,
    /// Per-pixel variance of the mean, `(A - B)^2 / 4`.
    pub var: Image,
    /// The script's report line.
    pub report: String,
}

pub fn mitsuba_render(
    name: &str,
    scene: &Scene,
    spp: u32,
    max_depth: i32,
) -> Option<MitsubaResult> {
    mitsuba_render_lit(name, scene, spp, max_depth, &[])
}

/// [`mitsuba_render`] with point and spot `lights` besides the environment.
pub fn mitsuba_render_lit(
    name: &str,
    scene: &Scene,
    spp: u32,
    max_depth: i32,
    lights: &[PointLight],
) -> Option<MitsubaResult> {
    let python = match mitsuba_python() {
        Ok(p) => p,
        Err(e) => {
            relight_testdata::skip(&format!("Mitsuba comparison {name}: {e}"));
            return None;
        }
    };
    let dir = std::env::temp_dir().join(format!("relight-mitsuba-{name}-{}", std::process::id()));
    let json = export_mitsuba_lit(scene, &dir, spp, max_depth, lights).expect("export");
    let (imgs, report) = render_mitsuba(&python, &json, &dir.join("mitsuba"), &[1, 2], None)
        .expect("mitsuba render");
    let (a, b) = (&imgs[0], &imgs[1]);
    let mut mean = Image::new(a.width, a.height);
    let mut var = Image::new(a.width, a.height);
    for i in 0..a.pixels.len() {
        mean.pixels[i] = (a.pixels[i] + b.pixels[i]) * 0.5;
        let diff = a.pixels[i] - b.pixels[i];
        var.pixels[i] = diff * diff * 0.25;
    }
    let _ = std::fs::remove_dir_all(&dir);
    Some(MitsubaResult { mean, var, report })
}
