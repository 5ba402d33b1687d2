//! Sample warps, low-discrepancy points and a small deterministic RNG.
//!
//! Conventions of this module:
//! * Warps map the unit square `[0,1)^2` to a domain; each comes as a matching triple
//!   `square_to_X` / `square_to_X_pdf` / `X_to_square` (pbrt-v4 `sampling.h`, Mitsuba 3 `warp.h`).
//!   Densities are per unit solid angle (spheres, hemispheres) or per unit area (disc).
//! * The **sphere** warp uses the world angles of the crate conventions (`cos theta = d.y`,
//!   `phi = 2 pi u.x`, `d = (sin phi sin theta, cos theta, -cos phi sin theta)`).
//! * **Hemisphere** warps live in a *local shading frame whose normal is +Z* (pbrt, Mitsuba);
//!   use [`Frame`] to go to and from world space.

use crate::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// `1 / (4 pi)`.
pub const INV_FOUR_PI: f32 = 0.25 * FRAC_1_PI;
/// `1 / (2 pi)`.
pub const INV_TWO_PI: f32 = 0.5 * FRAC_1_PI;

/// Uniform direction on the unit sphere: `cos theta = 1 - 2 u.y` (about +Y), `phi = 2 pi u.x`.
#[inline]
pub fn square_to_uniform_sphere(u: Vec2) -> Vec3 {
    let cos_theta = 1.0 - 2.0 * u.y;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sin_phi, cos_phi) = (2.0 * PI * u.x).sin_cos();
    Vec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta)
}

/// Density of [`square_to_uniform_sphere`] per unit solid angle: `1 / (4 pi)`.
#[inline]
pub fn square_to_uniform_sphere_pdf(_dir: Vec3) -> f32 {
    INV_FOUR_PI
}

/// Inverse of [`square_to_uniform_sphere`] (`dir` unit).
#[inline]
pub fn uniform_sphere_to_square(dir: Vec3) -> Vec2 {
    let mut ux = dir.x.atan2(-dir.z) * INV_TWO_PI;
    if ux < 0.0 {
        ux += 1.0;
    }
    Vec2::new(
        ux.min(1.0 - f32::EPSILON),
        (0.5 - 0.5 * dir.y).clamp(0.0, 1.0),
    )
}

/// Uniform direction on the local hemisphere `z >= 0`: `cos theta = u.x`, `phi = 2 pi u.y`.
#[inline]
pub fn square_to_uniform_hemisphere(u: Vec2) -> Vec3 {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u.y).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Density of [`square_to_uniform_hemisphere`]: `1 / (2 pi)` for `z >= 0`, else 0.
#[inline]
pub fn square_to_uniform_hemisphere_pdf(dir: Vec3) -> f32 {
    if dir.z >= 0.0 {
        INV_TWO_PI
    } else {
        0.0
    }
}

/// Inverse of [`square_to_uniform_hemisphere`].
#[inline]
pub fn uniform_hemisphere_to_square(dir: Vec3) -> Vec2 {
    let mut phi = dir.y.atan2(dir.x) * INV_TWO_PI;
    if phi < 0.0 {
        phi += 1.0;
    }
    Vec2::new(dir.z.clamp(0.0, 1.0), phi.min(1.0 - f32::EPSILON))
}

/// Shirley & Chiu (1997) concentric map from the square to the unit disc (area preserving,
/// low distortion).
#[inline]
pub fn square_to_concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, 0.25 * PI * (o.y / o.x))
    } else {
        (o.y, 0.5 * PI - 0.25 * PI * (o.x / o.y))
    };
    let (s, c) = theta.sin_cos();
    Vec2::new(r * c, r * s)
}

/// Density of [`square_to_concentric_disk`] per unit area: `1 / pi` inside the disc.
#[inline]
pub fn square_to_concentric_disk_pdf(p: Vec2) -> f32 {
    if p.length_squared() <= 1.0 {
        FRAC_1_PI
    } else {
        0.0
    }
}

/// Inverse of [`square_to_concentric_disk`].
#[inline]
pub fn concentric_disk_to_square(p: Vec2) -> Vec2 {
    let r = p.length();
    if r == 0.0 {
        return Vec2::splat(0.5);
    }
    let mut phi = p.y.atan2(p.x);
    if phi < -0.25 * PI {
        phi += 2.0 * PI;
    }
    // Four wedges of the concentric map: |x| > |y| for phi near 0 and pi, else |y| >= |x|.
    let (a, b) = if phi < 0.25 * PI {
        (r, phi * 4.0 / PI * r)
    } else if phi < 0.75 * PI {
        ((0.5 * PI - phi) * 4.0 / PI * r, r)
    } else if phi < 1.25 * PI {
        (-r, (phi - PI) * 4.0 / PI * -r)
    } else {
        ((phi - 1.5 * PI) * 4.0 / PI * r, -r)
    };
    Vec2::new(0.5 * (a + 1.0), 0.5 * (b + 1.0))
}

/// Cosine-weighted direction on the local hemisphere `z >= 0` (Malley's method over the
/// concentric disc).
#[inline]
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3 {
    let p = square_to_concentric_disk(u);
    let z = (1.0 - p.length_squared()).max(0.0).sqrt();
    Vec3::new(p.x, p.y, z)
}

/// Density of [`square_to_cosine_hemisphere`]: `cos theta / pi` (0 below the horizon).
#[inline]
pub fn square_to_cosine_hemisphere_pdf(dir: Vec3) -> f32 {
    dir.z.max(0.0) * FRAC_1_PI
}

/// Inverse of [`square_to_cosine_hemisphere`].
#[inline]
pub fn cosine_hemisphere_to_square(dir: Vec3) -> Vec2 {
    concentric_disk_to_square(Vec2::new(dir.x, dir.y))
}

/// An orthonormal frame `(s, t, n)`; local coordinates have the normal `n` along +Z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent (`s x t = n`).
    pub t: Vec3,
    /// Normal.
    pub n: Vec3,
}

impl Frame {
    /// Right-handed frame around the unit normal `n`, branchless construction of
    /// Duff et al. 2017, "Building an Orthonormal Basis, Revisited" (JCGT 6(1), Listing 3).
    ///
    /// # Panics
    /// Debug builds assert that `n` is unit length.
    #[inline]
    pub fn from_normal(n: Vec3) -> Frame {
        debug_assert!(
            (n.length_squared() - 1.0).abs() < 1e-3,
            "normal must be unit"
        );
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// Local (normal = +Z) to world.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }

    /// World to local (normal = +Z).
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
}

/// Van der Corput radical inverse in base 2 of `i`, in `[0, 1)` (bit reversal).
#[inline]
pub fn radical_inverse_base2(i: u32) -> f32 {
    // Keep 24 significant bits so the result is exactly representable and < 1.
    (i.reverse_bits() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Radical inverse of `i` in any `base >= 2`, in `[0, 1)` (computed in f64).
///
/// # Panics
/// Debug builds assert `base >= 2`.
pub fn radical_inverse(base: u32, mut i: u64) -> f64 {
    debug_assert!(base >= 2);
    let inv = 1.0 / base as f64;
    let (mut result, mut f) = (0.0f64, inv);
    while i > 0 {
        result += (i % base as u64) as f64 * f;
        i /= base as u64;
        f *= inv;
    }
    result.min(1.0 - f64::EPSILON)
}

/// Point `i` of the `n`-point Hammersley set: `((i + 0.5) / n, radical_inverse_base2(i))`.
///
/// # Panics
/// Debug builds assert `i < n`.
#[inline]
pub fn hammersley(i: u32, n: u32) -> Vec2 {
    debug_assert!(i < n);
    Vec2::new((i as f32 + 0.5) / n as f32, radical_inverse_base2(i))
}

/// Cranley-Patterson rotation (Cranley & Patterson 1976): `frac(u + shift)` per component,
/// randomising a low-discrepancy set while keeping its structure.
#[inline]
pub fn cranley_patterson(u: Vec2, shift: Vec2) -> Vec2 {
    let mut v = u + shift;
    v -= v.floor();
    // Guard against 1.0 from rounding of (1 - tiny) + shift.
    v.min(Vec2::splat(1.0 - f32::EPSILON))
}

/// PCG32 random number generator (O'Neill 2014, "PCG: A Family of Simple Fast Space-Efficient
/// Statistically Good Algorithms for Random Number Generation", XSH-RR output on a 64-bit LCG).
///
/// Deterministic for a given `(seed, stream)`; distinct streams give independent sequences.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    const MULT: u64 = 6364136223846793005;

    /// Generator seeded with `seed` on sequence `stream`.
    pub fn new(seed: u64, stream: u64) -> Rng {
        let mut rng = Rng {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// Next uniformly distributed `u32`.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform `f32` in `[0, 1)` (24 random bits).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Uniform `f64` in `[0, 1)` (53 random bits).
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        (hi | lo) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Two uniform numbers in `[0, 1)`.
    #[inline]
    pub fn next_vec2(&mut self) -> Vec2 {
        let x = self.next_f32();
        Vec2::new(x, self.next_f32())
    }

    /// Uniform integer in `0..n` (Lemire's multiply-shift; tiny bias below 2^-32 * n).
    ///
    /// # Panics
    /// Debug builds assert `n > 0`.
    #[inline]
    pub fn next_below(&mut self, n: u32) -> u32 {
        debug_assert!(n > 0);
        ((self.next_u32() as u64 * n as u64) >> 32) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chi2::{chi2_sphere_test, ChiTest};

    fn assert_warp(
        name: &str,
        warp: impl Fn(Vec2) -> Vec3,
        pdf: impl Fn(Vec3) -> f32,
        inverse: impl Fn(Vec3) -> Vec2,
    ) {
        let mut rng = Rng::new(7, 3);
        let res = chi2_sphere_test(
            &ChiTest::default(),
            |_| warp(rng.next_vec2()),
            |d| pdf(d) as f64,
        );
        assert!(res.passed, "{name}: {res:?}");
        let mut rng = Rng::new(1, 1);
        for _ in 0..2000 {
            let u = rng.next_vec2();
            let d = warp(u);
            assert!((d.length() - 1.0).abs() < 1e-5, "{name}: not unit");
            let back = inverse(d);
            assert!(
                (back - u).abs().max_element() < 2e-4,
                "{name}: inverse {u} -> {back}"
            );
        }
    }

    #[test]
    fn uniform_sphere_chi2_and_inverse() {
        assert_warp(
            "sphere",
            square_to_uniform_sphere,
            square_to_uniform_sphere_pdf,
            uniform_sphere_to_square,
        );
        // Convention: u.x = 0.25 is +X, u.y = 0 is +Y.
        let d = square_to_uniform_sphere(Vec2::new(0.25, 0.5));
        assert!((d - Vec3::X).length() < 1e-6);
    }

    #[test]
    fn uniform_hemisphere_chi2_and_inverse() {
        assert_warp(
            "uniform hemisphere",
            square_to_uniform_hemisphere,
            square_to_uniform_hemisphere_pdf,
            uniform_hemisphere_to_square,
        );
    }

    #[test]
    fn cosine_hemisphere_chi2_and_inverse() {
        assert_warp(
            "cosine hemisphere",
            square_to_cosine_hemisphere,
            square_to_cosine_hemisphere_pdf,
            cosine_hemisphere_to_square,
        );
    }

    #[test]
    fn chi2_detects_wrong_pdf() {
        // The test must be able to fail: uniform samples against the cosine pdf.
        let mut rng = Rng::new(5, 0);
        let res = chi2_sphere_test(
            &ChiTest::default(),
            |_| square_to_uniform_hemisphere(rng.next_vec2()),
            |d| square_to_cosine_hemisphere_pdf(d) as f64,
        );
        assert!(!res.passed);
    }

    #[test]
    fn frame_is_orthonormal() {
        let mut rng = Rng::new(3, 9);
        let mut normals: Vec<Vec3> = (0..1000)
            .map(|_| square_to_uniform_sphere(rng.next_vec2()))
            .collect();
        normals.extend([
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.0, 0.0, -0.99999994),
        ]);
        for n in normals {
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5 && (f.t.length() - 1.0).abs() < 1e-5);
            assert!(
                f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5
            );
            assert!((f.s.cross(f.t) - n).length() < 1e-5, "right-handed");
            let v = Vec3::new(0.3, -0.5, 0.8);
            assert!((f.to_local(f.to_world(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn radical_inverse_and_hammersley() {
        assert_eq!(radical_inverse_base2(1), 0.5);
        assert_eq!(radical_inverse_base2(2), 0.25);
        assert_eq!(radical_inverse_base2(3), 0.75);
        assert!((radical_inverse(3, 5) - (2.0 / 3.0 + 1.0 / 9.0)).abs() < 1e-12);
        assert!((radical_inverse(2, 6) - radical_inverse_base2(6) as f64).abs() < 1e-7);
        // Hammersley: the mean of a smooth function converges fast.
        let n = 1024;
        let mean: f64 = (0..n)
            .map(|i| {
                let u = hammersley(i, n);
                (u.x * u.y) as f64
            })
            .sum::<f64>()
            / n as f64;
        assert!((mean - 0.25).abs() < 1e-3);
        let c = cranley_patterson(Vec2::new(0.75, 0.1), Vec2::new(0.5, 0.2));
        assert!((c - Vec2::new(0.25, 0.3)).length() < 1e-6);
    }

    #[test]
    fn rng_is_deterministic_and_uniform() {
        let mut a = Rng::new(42, 54);
        let mut b = a;
        for _ in 0..10 {
            assert_eq!(a.next_u32(), b.next_u32());
        }
        let mut c = Rng::new(42, 55);
        let same = (0..100).filter(|_| a.next_u32() == c.next_u32()).count();
        assert!(same < 3, "streams must differ");
        let mut hist = [0u32; 16];
        let n = 160_000;
        for _ in 0..n {
            let x = a.next_f32();
            assert!((0.0..1.0).contains(&x));
            hist[(x * 16.0) as usize] += 1;
        }
        // Chi-square with 15 dof: 99.99% quantile is about 45.
        let e = n as f64 / 16.0;
        let chi: f64 = hist.iter().map(|&h| (h as f64 - e).powi(2) / e).sum();
        assert!(chi < 45.0, "chi2 {chi}");
        for _ in 0..1000 {
            let x = a.next_f64();
            assert!((0.0..1.0).contains(&x));
            assert!(a.next_below(7) < 7);
        }
    }
}
