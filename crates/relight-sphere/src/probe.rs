//! Angular light probe (Debevec's "angular map") geometry.
//!
//! # Convention
//! An `N x N` image; pixel `(col, row)` has image-plane centre `a = 2 (col + 0.5) / N - 1`
//! (image right, +X) and `b = 1 - 2 (row + 0.5) / N` (image up, +Y). With `r = |(a, b)|`, the
//! point maps to the direction at angle `pi r` from **-Z** (the image centre looks at -Z):
//! `d = (sin(pi r) a / r, sin(pi r) b / r, -cos(pi r))`; the rim `r = 1` is +Z.
//!
//! # Which pixels are samples, and their exact solid angles
//! A pixel is a sample ("inside the disc") when its centre has `r < 1`. The solid angle
//! element is `dw = pi sin(pi r) dr dphi = d(1 - cos(pi r)) dphi`, so by Green's theorem the
//! solid angle of a region is the boundary integral `oint G(r) dphi` with
//! `G(r) = 1 - cos(pi min(r, 1))`, which automatically clips the region to the disc.
//! Each pixel square's boundary integral is computed with 16-point Gauss-Legendre on the
//! pieces of its edges inside the disc (the integrand `2 sin^2(pi r / 2) / r^2 * (p x dp)` is
//! analytic there) and analytically (`2 dphi`) outside, giving the solid angle of
//! `square ∩ disc` to about 1e-12. Rim pixels whose centre lies outside the disc but whose
//! square overlaps it give their (tiny: the density vanishes at the rim) solid angle to the
//! nearest inside pixel, so the sample weights sum to exactly 4 pi.

use crate::quadrature::gauss_legendre;
use crate::{Vec2, Vec3};
use std::f32::consts::PI;
use std::f64::consts::PI as PI64;

/// Image-plane point `(a, b)` (unit disc) of a unit direction.
#[inline]
pub fn dir_to_disc(dir: Vec3) -> Vec2 {
    let r = (-dir.z).clamp(-1.0, 1.0).acos() * (1.0 / PI);
    let s = (dir.x * dir.x + dir.y * dir.y).sqrt();
    if s <= 0.0 {
        return Vec2::new(r, 0.0);
    }
    Vec2::new(dir.x, dir.y) * (r / s)
}

/// Unit direction of the image-plane point `p = (a, b)`, `|p| <= 1`.
#[inline]
pub fn disc_to_dir(p: Vec2) -> Vec3 {
    let r = p.length();
    if r <= 0.0 {
        return -Vec3::Z;
    }
    let (s, c) = (PI * r).sin_cos();
    Vec3::new(s * p.x / r, s * p.y / r, -c)
}

/// Image-plane centre of pixel `(col, row)` of an `n x n` probe.
#[inline]
pub fn pixel_centre(n: usize, col: usize, row: usize) -> Vec2 {
    Vec2::new(
        2.0 * (col as f32 + 0.5) / n as f32 - 1.0,
        1.0 - 2.0 * (row as f32 + 0.5) / n as f32,
    )
}

/// Whether pixel `(col, row)` is a sample (its centre lies strictly inside the disc).
#[inline]
pub fn pixel_in_disc(n: usize, col: usize, row: usize) -> bool {
    let a = 2.0 * (col as f64 + 0.5) / n as f64 - 1.0;
    let b = 1.0 - 2.0 * (row as f64 + 0.5) / n as f64;
    a * a + b * b < 1.0
}

/// Boundary integral `int G(r) dphi` along the straight segment `p0 -> p1`.
fn segment_integral(p0: [f64; 2], p1: [f64; 2], gl: &(Vec<f64>, Vec<f64>)) -> f64 {
    let d = [p1[0] - p0[0], p1[1] - p0[1]];
    // Split at the circle r = 1: |p0 + t d|^2 = 1.
    let qa = d[0] * d[0] + d[1] * d[1];
    let qb = 2.0 * (p0[0] * d[0] + p0[1] * d[1]);
    let qc = p0[0] * p0[0] + p0[1] * p0[1] - 1.0;
    let mut cuts = vec![0.0, 1.0];
    let disc = qb * qb - 4.0 * qa * qc;
    if qa > 0.0 && disc > 0.0 {
        let sq = disc.sqrt();
        for t in [(-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)] {
            if t > 0.0 && t < 1.0 {
                cuts.push(t);
            }
        }
    }
    cuts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let at = |t: f64| [p0[0] + t * d[0], p0[1] + t * d[1]];
    let mut total = 0.0;
    for k in 0..cuts.len() - 1 {
        let (t0, t1) = (cuts[k], cuts[k + 1]);
        if t1 <= t0 {
            continue;
        }
        let (q0, q1) = (at(t0), at(t1));
        let mid = at(0.5 * (t0 + t1));
        if mid[0] * mid[0] + mid[1] * mid[1] >= 1.0 {
            // Outside the disc G = 2: twice the signed angle swept.
            let cross = q0[0] * q1[1] - q0[1] * q1[0];
            let dot = q0[0] * q1[0] + q0[1] * q1[1];
            total += 2.0 * cross.atan2(dot);
        } else {
            // dphi = (q x dq) / r^2; (1 - cos(pi r)) / r^2 = 2 sin^2(pi r / 2) / r^2 (smooth at 0).
            let dq = [q1[0] - q0[0], q1[1] - q0[1]];
            let c = q0[0] * dq[1] - q0[1] * dq[0];
            let mut acc = 0.0;
            for (x, w) in gl.0.iter().zip(&gl.1) {
                let t = 0.5 * (x + 1.0);
                let p = [q0[0] + t * dq[0], q0[1] + t * dq[1]];
                let r2 = p[0] * p[0] + p[1] * p[1];
                let f = if r2 < 1e-24 {
                    0.5 * PI64 * PI64
                } else {
                    2.0 * (0.5 * PI64 * r2.sqrt()).sin().powi(2) / r2
                };
                acc += 0.5 * w * f;
            }
            total += acc * c;
        }
    }
    total
}

/// Solid angle of the intersection of the disc with the axis-aligned square
/// `[a0, a1] x [b0, b1]` of the image plane (`a0 < a1`, `b0 < b1`).
pub fn square_solid_angle(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    let gl = gauss_legendre(16);
    square_solid_angle_with(a0, a1, b0, b1, &gl)
}

fn square_solid_angle_with(a0: f64, a1: f64, b0: f64, b1: f64, gl: &(Vec<f64>, Vec<f64>)) -> f64 {
    // Counter-clockwise in the (a, b) plane.
    segment_integral([a0, b0], [a1, b0], gl)
        + segment_integral([a1, b0], [a1, b1], gl)
        + segment_integral([a1, b1], [a0, b1], gl)
        + segment_integral([a0, b1], [a0, b0], gl)
}

/// The samples of an `n x n` probe: which pixels, and their exact quadrature weights.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeSamples {
    /// Probe size `n`.
    pub size: usize,
    /// Pixel index (`row * n + col`) of each sample, in row-major order.
    pub pixels: Vec<u32>,
    /// Solid angle of each sample (sums to 4 pi).
    pub weights: Vec<f64>,
    /// Sample index of each pixel, `u32::MAX` outside the disc.
    pub sample_of_pixel: Vec<u32>,
}

impl ProbeSamples {
    /// Computes the samples and weights of an `n x n` probe (see module docs). Cost: about
    /// `4 n^2 x 16` sine evaluations.
    ///
    /// # Panics
    /// Debug builds assert `n >= 2` (a 1-pixel probe has no pixel centre inside the disc).
    pub fn new(n: usize) -> ProbeSamples {
        debug_assert!(n >= 2);
        let gl = gauss_legendre(16);
        let edge = |i: usize| 2.0 * i as f64 / n as f64 - 1.0; // a of column edge i
        let bedge = |j: usize| 1.0 - 2.0 * j as f64 / n as f64; // b of row edge j (top = 1)
                                                                // Shared edges: horizontal edge (row edge j, column i) oriented +a; vertical edge
                                                                // (column edge i, row j) oriented +b (from bedge(j + 1) up to bedge(j)).
        let mut horiz = vec![0.0; (n + 1) * n];
        for j in 0..=n {
            for i in 0..n {
                horiz[j * n + i] =
                    segment_integral([edge(i), bedge(j)], [edge(i + 1), bedge(j)], &gl);
            }
        }
        let mut vert = vec![0.0; n * (n + 1)];
        for j in 0..n {
            for i in 0..=n {
                vert[j * (n + 1) + i] =
                    segment_integral([edge(i), bedge(j + 1)], [edge(i), bedge(j)], &gl);
            }
        }
        let mut pixel_w = vec![0.0; n * n];
        for j in 0..n {
            for i in 0..n {
                // CCW: bottom (+a), right (+b), top (-a), left (-b).
                pixel_w[j * n + i] = horiz[(j + 1) * n + i] + vert[j * (n + 1) + i + 1]
                    - horiz[j * n + i]
                    - vert[j * (n + 1) + i];
            }
        }
        let mut sample_of_pixel = vec![u32::MAX; n * n];
        let mut pixels = Vec::new();
        let mut weights = Vec::new();
        for j in 0..n {
            for i in 0..n {
                if pixel_in_disc(n, i, j) {
                    sample_of_pixel[j * n + i] = pixels.len() as u32;
                    pixels.push((j * n + i) as u32);
                    weights.push(pixel_w[j * n + i]);
                }
            }
        }
        // Give rim slivers to the nearest inside pixel.
        for j in 0..n {
            for i in 0..n {
                let w = pixel_w[j * n + i];
                if sample_of_pixel[j * n + i] == u32::MAX && w > 0.0 {
                    let c = pixel_centre(n, i, j);
                    let target = nearest_sample(n, &sample_of_pixel, c.normalize_or_zero() * 0.999);
                    weights[target as usize] += w;
                }
            }
        }
        ProbeSamples {
            size: n,
            pixels,
            weights,
            sample_of_pixel,
        }
    }

    /// Sample index nearest to the image-plane point `p` (searches a 5 x 5 neighbourhood,
    /// then all samples).
    pub fn nearest(&self, p: Vec2) -> u32 {
        nearest_sample(self.size, &self.sample_of_pixel, p)
    }
}

fn nearest_sample(n: usize, sample_of_pixel: &[u32], p: Vec2) -> u32 {
    let col = (((p.x + 1.0) * 0.5 * n as f32) as i64).clamp(0, n as i64 - 1);
    let row = (((1.0 - p.y) * 0.5 * n as f32) as i64).clamp(0, n as i64 - 1);
    let consider = |best: &mut (f32, u32), i: usize, j: usize| {
        let s = sample_of_pixel[j * n + i];
        if s != u32::MAX {
            let d = (pixel_centre(n, i, j) - p).length_squared();
            if d < best.0 {
                *best = (d, s);
            }
        }
    };
    let mut best = (f32::INFINITY, u32::MAX);
    for j in (row - 2).max(0)..=(row + 2).min(n as i64 - 1) {
        for i in (col - 2).max(0)..=(col + 2).min(n as i64 - 1) {
            consider(&mut best, i as usize, j as usize);
        }
    }
    if best.1 == u32::MAX {
        for j in 0..n {
            for i in 0..n {
                consider(&mut best, i, j);
            }
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn convention() {
        assert!((disc_to_dir(Vec2::ZERO) + Vec3::Z).length() < 1e-6);
        assert!((disc_to_dir(Vec2::new(0.5, 0.0)) - Vec3::X).length() < 1e-6);
        assert!((disc_to_dir(Vec2::new(0.0, 0.5)) - Vec3::Y).length() < 1e-6);
        assert!((disc_to_dir(Vec2::new(0.0, 1.0)) - Vec3::Z).length() < 1e-6);
        for p in [
            Vec2::new(0.3, -0.2),
            Vec2::new(-0.7, 0.1),
            Vec2::new(0.01, 0.9),
        ] {
            assert!((dir_to_disc(disc_to_dir(p)) - p).length() < 1e-5);
        }
    }

    #[test]
    fn square_solid_angle_matches_brute_force() {
        // Midpoint integration of pi sin(pi r) / r over the square, clipped to the disc.
        for (a0, a1, b0, b1) in [
            (0.1, 0.3, -0.2, 0.05),
            (-0.05, 0.05, -0.05, 0.05),
            (0.6, 0.9, 0.5, 0.8),
        ] {
            let k = 1500;
            let mut acc = 0.0;
            for x in 0..k {
                for y in 0..k {
                    let a: f64 = a0 + (a1 - a0) * (x as f64 + 0.5) / k as f64;
                    let b: f64 = b0 + (b1 - b0) * (y as f64 + 0.5) / k as f64;
                    let r = (a * a + b * b).sqrt();
                    if r < 1.0 {
                        acc += PI64 * (PI64 * r).sin() / r;
                    }
                }
            }
            acc *= (a1 - a0) * (b1 - b0) / (k * k) as f64;
            let exact = square_solid_angle(a0, a1, b0, b1);
            assert!(
                (acc - exact).abs() < 2e-5 * exact.max(1e-3),
                "{acc} vs {exact}"
            );
        }
        // The whole image square is the whole sphere.
        assert!((square_solid_angle(-1.0, 1.0, -1.0, 1.0) - 4.0 * PI64).abs() < 1e-12);
    }

    #[test]
    fn weights_sum_to_4pi() {
        for n in [2, 3, 8, 33, 64] {
            let s = ProbeSamples::new(n);
            let total: f64 = s.weights.iter().sum();
            assert!((total - 4.0 * PI64).abs() < 1e-10, "n={n}: {total}");
            assert!(s.weights.iter().all(|&w| w > 0.0));
        }
    }
}
