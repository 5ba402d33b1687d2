//! Test helper: chi-square goodness-of-fit of a direction sampler against its pdf
//! (in the spirit of Mitsuba 3's `chi2` test harness). Compiled for tests only.

use crate::Vec3;
use std::f64::consts::PI;

/// Parameters of a chi-square test over the sphere.
#[derive(Clone, Debug)]
pub struct ChiTest {
    /// Bins in `z` (equal solid angle), polar axis +Z.
    pub z_bins: usize,
    /// Bins in `phi = atan2(y, x)`.
    pub phi_bins: usize,
    /// Number of samples drawn.
    pub samples: usize,
    /// Sub-samples per bin side when integrating the pdf (midpoint rule in `(z, phi)`).
    pub sub: usize,
}

impl Default for ChiTest {
    fn default() -> Self {
        ChiTest {
            z_bins: 16,
            phi_bins: 32,
            samples: 200_000,
            sub: 8,
        }
    }
}

/// Outcome of [`chi2_sphere_test`] (all fields are shown by `Debug` in failure messages).
#[allow(dead_code)]
#[derive(Clone, Debug)]
pub struct ChiResult {
    /// The chi-square statistic.
    pub chi2: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Wilson-Hilferty normal score of the statistic.
    pub z_score: f64,
    /// Integral of the pdf over the sphere (should be 1).
    pub pdf_integral: f64,
    /// Whether the test accepted the sampler.
    pub passed: bool,
}

fn bin_of(d: Vec3, t: &ChiTest) -> usize {
    let z = (d.z as f64).clamp(-1.0, 1.0);
    let zi = (((1.0 - z) * 0.5 * t.z_bins as f64) as usize).min(t.z_bins - 1);
    let mut phi = (d.y as f64).atan2(d.x as f64);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let pi_ = ((phi / (2.0 * PI) * t.phi_bins as f64) as usize).min(t.phi_bins - 1);
    zi * t.phi_bins + pi_
}

/// Draws `t.samples` directions from `sample(i)` and compares their histogram with the
/// integral of `pdf` over each bin. Bins with an expected count below 5 are pooled. The
/// statistic is converted to a normal score with the Wilson-Hilferty approximation and the
/// test passes when the score is below 4.5 (a false alarm probability of about 3e-6) and the
/// pdf integrates to 1 within 1e-3.
pub fn chi2_sphere_test(
    t: &ChiTest,
    mut sample: impl FnMut(usize) -> Vec3,
    pdf: impl Fn(Vec3) -> f64,
) -> ChiResult {
    let nb = t.z_bins * t.phi_bins;
    let mut observed = vec![0f64; nb];
    for i in 0..t.samples {
        let d = sample(i);
        observed[bin_of(d, t)] += 1.0;
    }
    let mut expected = vec![0f64; nb];
    let dz = 2.0 / t.z_bins as f64;
    let dphi = 2.0 * PI / t.phi_bins as f64;
    let k = t.sub;
    for zi in 0..t.z_bins {
        for pi_ in 0..t.phi_bins {
            let mut acc = 0.0;
            for a in 0..k {
                for b in 0..k {
                    let z = 1.0 - (zi as f64 + (a as f64 + 0.5) / k as f64) * dz;
                    let phi = (pi_ as f64 + (b as f64 + 0.5) / k as f64) * dphi;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let d = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                    acc += pdf(d);
                }
            }
            expected[zi * t.phi_bins + pi_] = acc * dz * dphi / (k * k) as f64;
        }
    }
    let pdf_integral: f64 = expected.iter().sum();
    let n = t.samples as f64;
    let (mut chi2, mut dof) = (0.0, 0usize);
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    let mut impossible = false;
    for (e, o) in expected.iter().map(|e| e * n).zip(observed.iter().copied()) {
        if e < 1e-9 && o > 0.0 {
            impossible = true;
        }
        if e < 5.0 {
            pool_e += e;
            pool_o += o;
        } else {
            chi2 += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pool_e > 0.0 {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        dof += 1;
    }
    let dof = dof.saturating_sub(1).max(1);
    let kf = dof as f64;
    let z_score = ((chi2 / kf).cbrt() - (1.0 - 2.0 / (9.0 * kf))) / (2.0 / (9.0 * kf)).sqrt();
    let passed = !impossible && z_score < 4.5 && (pdf_integral - 1.0).abs() < 1e-3;
    ChiResult {
        chi2,
        dof,
        z_score,
        pdf_integral,
        passed,
    }
}
