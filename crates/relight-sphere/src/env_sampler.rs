//! Importance sampling of an environment map for the path tracer.
//!
//! A piecewise-constant 2D distribution (pbrt-v4 `PiecewiseConstant2D`, Mitsuba 3's envmap
//! warp) over the **bilinear cells** of a latlong version of the map: cell `(k, c)` spans
//! `theta in [theta_k, theta_{k+1}]` between rows `k` and `k + 1` (Mitsuba placement
//! `theta_k = pi k / (H - 1)`) and `u in [(c + 0.5)/W, (c + 1.5)/W]` between column centres
//! `c` and `c + 1` (wrapping). Its mass is `mean luminance of the 4 corner texels x exact cell
//! solid angle (2 pi / W)(cos theta_k - cos theta_{k+1})`, and within a cell directions are
//! uniform in solid angle (uniform `u` and `cos theta`), so the density is
//! `P(cell) / Omega(cell)`, with no `1 / sin(theta)` singularity at the poles.
//! Because the bilinear lookup in a cell only reads its four corners, the density is positive
//! wherever the interpolated map is non-zero.
//!
//! **Uniform mixture**: a fraction [`UNIFORM_FRACTION`] of the samples is drawn uniformly on the
//! sphere (`pdf = eps / 4pi + (1 - eps) p_env`). This keeps the pdf positive everywhere even if
//! the latlong resampling of a cube or probe map misses a tiny feature, or luminance is zero
//! for a non-zero (negative-component) texel. An all-zero map is sampled uniformly.

use crate::envmap::{luminance, EnvLayout, EnvMap};
use crate::latlong;
use crate::warp::{square_to_uniform_sphere, INV_FOUR_PI};
use crate::{Vec2, Vec3};
use std::f64::consts::PI;

/// Default fraction of uniform sphere samples mixed into [`EnvSampler`].
pub const UNIFORM_FRACTION: f32 = 0.02;

/// Environment importance sampler (see module docs). Directions and pdfs are in the map frame.
#[derive(Clone, Debug)]
pub struct EnvSampler {
    width: usize,
    height: usize,
    /// Uniform mixture weight actually used (1 for an all-zero map).
    eps: f32,
    /// `cos theta_k` of each row.
    cos_row: Vec<f64>,
    /// Marginal CDF over the `H - 1` cell rows (length `H`).
    row_cdf: Vec<f64>,
    /// Conditional CDFs over columns, `(H - 1) x (W + 1)`.
    col_cdf: Vec<f64>,
    /// Density (per steradian) of each cell under the environment part, `(H - 1) x W`.
    density: Vec<f32>,
}

impl EnvSampler {
    /// Sampler for `map` with the default uniform fraction [`UNIFORM_FRACTION`].
    pub fn new(map: &EnvMap) -> Self {
        Self::with_uniform_fraction(map, UNIFORM_FRACTION)
    }

    /// Sampler for `map` mixing in `fraction` of uniform sphere samples (`0 <= fraction <= 1`).
    /// Cube maps are resampled to a `4n x (2n + 1)` latlong, probes to `2n x (n + 1)`
    /// (widths capped at 4096).
    ///
    /// # Panics
    /// Debug builds assert `0 <= fraction <= 1`.
    pub fn with_uniform_fraction(map: &EnvMap, fraction: f32) -> Self {
        debug_assert!((0.0..=1.0).contains(&fraction));
        let resampled;
        let ll = match map.layout() {
            EnvLayout::LatLong => map,
            EnvLayout::Cube => {
                let w = (4 * map.width()).min(4096);
                resampled = map.to_latlong(w, w / 2 + 1);
                &resampled
            }
            EnvLayout::Probe => {
                let w = (2 * map.width()).min(4096);
                resampled = map.to_latlong(w, w / 2 + 1);
                &resampled
            }
        };
        let (w, h) = (ll.width(), ll.height());
        let lum: Vec<f64> = ll
            .texels()
            .iter()
            .map(|&t| luminance(t).max(0.0) as f64)
            .collect();
        let cos_row: Vec<f64> = (0..h)
            .map(|k| match k {
                0 => 1.0,
                _ if k + 1 == h => -1.0,
                _ => latlong::row_theta(h, k).cos(),
            })
            .collect();
        let rows = h - 1;
        let mut col_cdf = vec![0.0; rows * (w + 1)];
        let mut row_mass = vec![0.0; rows];
        let mut density = vec![0f32; rows * w];
        for k in 0..rows {
            let omega = 2.0 * PI / w as f64 * (cos_row[k] - cos_row[k + 1]);
            let cdf = &mut col_cdf[k * (w + 1)..(k + 1) * (w + 1)];
            for c in 0..w {
                let c1 = (c + 1) % w;
                let mean = 0.25
                    * (lum[k * w + c]
                        + lum[k * w + c1]
                        + lum[(k + 1) * w + c]
                        + lum[(k + 1) * w + c1]);
                cdf[c + 1] = cdf[c] + mean * omega;
            }
            row_mass[k] = cdf[w];
            if cdf[w] > 0.0 {
                let inv = 1.0 / cdf[w];
                cdf.iter_mut().for_each(|v| *v *= inv);
            }
            cdf[w] = 1.0;
        }
        let total: f64 = row_mass.iter().sum();
        let mut row_cdf = vec![0.0; h];
        for k in 0..rows {
            row_cdf[k + 1] = row_cdf[k] + row_mass[k];
        }
        let eps = if total > 0.0 && total.is_finite() {
            fraction
        } else {
            1.0
        };
        if total > 0.0 && total.is_finite() {
            row_cdf.iter_mut().for_each(|v| *v /= total);
            for k in 0..rows {
                let omega = 2.0 * PI / w as f64 * (cos_row[k] - cos_row[k + 1]);
                let cdf = &col_cdf[k * (w + 1)..(k + 1) * (w + 1)];
                let pk = row_mass[k] / total;
                for c in 0..w {
                    density[k * w + c] = (pk * (cdf[c + 1] - cdf[c]) / omega) as f32;
                }
            }
        }
        row_cdf[rows] = 1.0;
        EnvSampler {
            width: w,
            height: h,
            eps,
            cos_row,
            row_cdf,
            col_cdf,
            density,
        }
    }

    /// Index `i` with `cdf[i] <= u < cdf[i + 1]` and the remapped `u` in `[0, 1)`.
    fn search(cdf: &[f64], u: f64) -> (usize, f64) {
        let n = cdf.len() - 1;
        let i = cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(n - 1);
        let p = cdf[i + 1] - cdf[i];
        let f = if p > 0.0 {
            ((u - cdf[i]) / p).clamp(0.0, 1.0 - 1e-9)
        } else {
            0.5
        };
        (i, f)
    }

    /// Direction (map frame, unit) and its solid-angle pdf for the uniform sample `u`.
    pub fn sample(&self, u: Vec2) -> (Vec3, f32) {
        let eps = self.eps;
        if u.x < eps {
            let d = square_to_uniform_sphere(Vec2::new((u.x / eps).min(1.0 - 1e-7), u.y));
            return (d, self.pdf(d));
        }
        let ux = ((u.x - eps) / (1.0 - eps)) as f64;
        let (k, fy) = Self::search(&self.row_cdf, u.y as f64);
        let w = self.width;
        let (c, fx) = Self::search(&self.col_cdf[k * (w + 1)..(k + 1) * (w + 1)], ux);
        let mut uu = (c as f64 + 0.5 + fx) / w as f64;
        if uu >= 1.0 {
            uu -= 1.0;
        }
        let cos_t = self.cos_row[k] + fy * (self.cos_row[k + 1] - self.cos_row[k]);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let (sp, cp) = (2.0 * PI * uu).sin_cos();
        let d = Vec3::new((sp * sin_t) as f32, cos_t as f32, (-cp * sin_t) as f32);
        let pdf = eps * INV_FOUR_PI + (1.0 - eps) * self.density[k * w + c];
        (d, pdf)
    }

    /// Solid-angle density of [`EnvSampler::sample`] at unit direction `dir` (map frame).
    pub fn pdf(&self, dir: Vec3) -> f32 {
        let (w, h) = (self.width, self.height);
        let uv = latlong::dir_to_uv(dir);
        let y = uv.y * (h - 1) as f32;
        let k = (y.max(0.0) as usize).min(h - 2);
        let c = ((uv.x * w as f32 - 0.5).floor() as i64).rem_euclid(w as i64) as usize;
        self.eps * INV_FOUR_PI + (1.0 - self.eps) * self.density[k * w + c]
    }

    /// The uniform mixture fraction in use (1 for an all-zero map).
    pub fn uniform_fraction(&self) -> f32 {
        self.eps
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chi2::{chi2_sphere_test, ChiTest};
    use crate::warp::Rng;

    fn sunny(d: Vec3) -> Vec3 {
        let sun = Vec3::new(0.3, 0.8, -0.52).normalize();
        let s = if d.dot(sun) > 0.97 { 40.0 } else { 0.0 };
        Vec3::new(
            0.2 + 0.1 * d.y.max(0.0) + s,
            0.3 + s,
            0.5 * (1.0 + d.x).powi(2) + s,
        )
    }

    fn pdf_integral(s: &EnvSampler) -> f64 {
        // Midpoint rule on a fine (z, phi) grid (dw = dz dphi); the pdf is piecewise constant,
        // so the error is the fraction of grid cells straddling a discontinuity (~1e-4).
        let (nz, np) = (1200, 2400);
        let mut acc = 0.0;
        for a in 0..nz {
            let z = 1.0 - 2.0 * (a as f64 + 0.5) / nz as f64;
            let r = (1.0 - z * z).sqrt();
            for b in 0..np {
                let phi = 2.0 * PI * (b as f64 + 0.5) / np as f64;
                let d = Vec3::new((r * phi.cos()) as f32, z as f32, (r * phi.sin()) as f32);
                acc += s.pdf(d) as f64;
            }
        }
        acc * 4.0 * PI / (nz * np) as f64
    }

    #[test]
    fn chi2_and_normalisation_every_layout() {
        let maps = [
            EnvMap::latlong_from_fn(48, 25, sunny),
            EnvMap::cube_from_fn(12, sunny),
            EnvMap::probe_from_fn(32, sunny),
        ];
        for m in &maps {
            let s = EnvSampler::new(m);
            let mut rng = Rng::new(11, 4);
            let t = ChiTest {
                z_bins: 24,
                phi_bins: 48,
                samples: 300_000,
                sub: 12,
            };
            let res = chi2_sphere_test(&t, |_| s.sample(rng.next_vec2()).0, |d| s.pdf(d) as f64);
            // The chi2 helper integrates the pdf at only 12 x 12 points per bin; accept its
            // normalisation loosely and check it precisely below.
            assert!(res.z_score < 4.5, "{:?}: {res:?}", m.layout());
            let i = pdf_integral(&s);
            assert!((i - 1.0).abs() < 2e-3, "{:?}: integral {i}", m.layout());
        }
    }

    #[test]
    fn sample_pdf_matches_pdf_and_is_positive() {
        let m = EnvMap::latlong_from_fn(40, 21, sunny);
        let s = EnvSampler::new(&m);
        let mut rng = Rng::new(2, 2);
        let mut mismatches = 0;
        for _ in 0..20_000 {
            let (d, p) = s.sample(rng.next_vec2());
            assert!((d.length() - 1.0).abs() < 1e-4);
            assert!(p > 0.0);
            // A sample rounded onto a cell boundary may be attributed to the neighbour cell.
            if (p - s.pdf(d)).abs() > 1e-4 * p {
                mismatches += 1;
            }
        }
        assert!(
            mismatches < 20,
            "{mismatches} sample pdfs differ from pdf()"
        );
        // Without the mixture the pdf is still positive wherever the map is non-zero.
        let sparse =
            EnvMap::latlong_from_fn(40, 21, |d| if d.x > 0.9 { Vec3::ONE } else { Vec3::ZERO });
        let s0 = EnvSampler::with_uniform_fraction(&sparse, 0.0);
        for _ in 0..20_000 {
            let d = crate::warp::square_to_uniform_sphere(rng.next_vec2());
            if sparse.eval(d).max_element() > 0.0 {
                assert!(s0.pdf(d) > 0.0, "{d}");
            }
        }
    }

    #[test]
    fn proportional_to_luminance_for_smooth_maps() {
        // pdf / L should be nearly constant (up to the mixture) on a smooth, bright map.
        let f = |d: Vec3| Vec3::splat(1.0 + 0.8 * d.y);
        let m = EnvMap::latlong_from_fn(128, 65, f);
        let s = EnvSampler::with_uniform_fraction(&m, 0.0);
        let total = 4.0 * std::f32::consts::PI; // int (1 + 0.8 y) dw
        let mut rng = Rng::new(3, 3);
        for _ in 0..1000 {
            let d = crate::warp::square_to_uniform_sphere(rng.next_vec2());
            let expect = f(d).x / total;
            // Within a cell L varies by at most 0.8 * (row spacing pi / 64) around its mean.
            let tol = 0.8 * std::f32::consts::PI / 64.0 / total;
            assert!(
                (s.pdf(d) - expect).abs() < tol,
                "{d}: {} vs {expect}",
                s.pdf(d)
            );
        }
    }

    #[test]
    fn zero_map_is_uniform() {
        let s = EnvSampler::new(&EnvMap::constant(Vec3::ZERO));
        assert_eq!(s.uniform_fraction(), 1.0);
        let (d, p) = s.sample(Vec2::new(0.3, 0.6));
        assert!((d.length() - 1.0).abs() < 1e-5 && (p - INV_FOUR_PI).abs() < 1e-7);
    }
}
