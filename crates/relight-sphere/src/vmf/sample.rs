//! Importance sampling of the unit vMF lobe (paper section 5.1, eq. 10-12) as a matching
//! triple: [`sample_vmf`], [`vmf_pdf`], [`invert_vmf_sample`].
//!
//! # The warp
//! In the lobe's frame ([`Frame::from_normal`] of `mu`, `mu` along local +Z), `cos theta` has the
//! density `kappa exp(kappa cos theta) / (2 sinh kappa)` on `[-1, 1]` and `phi` is uniform. The
//! inverse CDF of `s = 1 - cos theta` from `u.x` is
//!
//! ```text
//! s = -ln(1 - u.x (1 - exp(-2 kappa))) / kappa,     phi = 2 pi u.y
//! ```
//! which is the paper's eq. 10, `cos theta = ln(e^kappa - 2 u sinh kappa) / kappa` (as printed
//! there the `arccos` and the division are misplaced), rewritten so that nothing overflows:
//! `1 - exp(-2 kappa)` is `-expm1(-2 kappa)` and the logarithm is `ln_1p`. For
//! `kappa >> 1` it becomes eq. 12, `s = -ln(1 - u.x) / kappa`; for `kappa -> 0`,
//! `s = 2 u.x` (uniform; used below `kappa = 1e-12`, error `O(kappa)`). Working with `s`
//! rather than `cos theta` keeps the sample's angle accurate at `kappa = 1e8`:
//! `sin theta = sqrt(s (2 - s))`. The inverse recovers `s` from a direction as
//! `(x^2 + y^2) / (1 + z)` in the local frame (no cancellation near the axis), then
//! `u.x = (1 - exp(-kappa s)) / (1 - exp(-2 kappa))`.
//!
//! The same function as [`crate::sg::sample_sg`] (a vMF is a normalised SG, same frame and
//! same use of `u`), but defined also at `kappa = 0` and accurate for very sharp lobes.

use super::VmfLobe;
use crate::warp::Frame;
use crate::{Vec2, Vec3};
use std::f64::consts::PI;

/// Below this concentration the warp is the uniform one (`s = 2 u.x`).
const UNIFORM_BELOW: f64 = 1e-12;

/// Samples the unit vMF lobe of unit `axis` and concentration `kappa >= 0` from `u` in
/// `[0, 1)^2` (module docs).
///
/// # Panics
/// Debug builds assert a unit axis and a finite `kappa >= 0`.
pub fn sample_vmf(axis: Vec3, kappa: f32, u: Vec2) -> Vec3 {
    debug_assert!(kappa >= 0.0 && kappa.is_finite());
    let k = kappa as f64;
    let ux = u.x as f64;
    let s = if k < UNIFORM_BELOW {
        2.0 * ux
    } else {
        -(-ux * -(-2.0 * k).exp_m1()).ln_1p() / k
    }
    .clamp(0.0, 2.0);
    let sin_t = (s * (2.0 - s)).sqrt();
    let phi = 2.0 * PI * u.y as f64;
    let local = Vec3::new(
        (sin_t * phi.cos()) as f32,
        (sin_t * phi.sin()) as f32,
        (1.0 - s) as f32,
    );
    Frame::from_normal(axis).to_world(local).normalize()
}

/// Density of [`sample_vmf`] per unit solid angle: the unit lobe `c(kappa) exp(kappa mu . w)`
/// ([`VmfLobe::eval_unit`]).
///
/// # Panics
/// Debug builds assert a unit `dir` and `kappa >= 0`.
#[inline]
pub fn vmf_pdf(axis: Vec3, kappa: f32, dir: Vec3) -> f32 {
    VmfLobe {
        axis,
        kappa,
        amplitude: Vec3::ONE,
    }
    .eval_unit(dir)
}

/// Inverse of [`sample_vmf`]: the `u` that maps to unit `dir` (module docs).
///
/// # Panics
/// Debug builds assert a unit axis and `kappa >= 0`.
pub fn invert_vmf_sample(axis: Vec3, kappa: f32, dir: Vec3) -> Vec2 {
    debug_assert!(kappa >= 0.0);
    let f = Frame::from_normal(axis);
    let d = [dir.x as f64, dir.y as f64, dir.z as f64];
    let dot = |v: Vec3| v.x as f64 * d[0] + v.y as f64 * d[1] + v.z as f64 * d[2];
    let (x, y, z) = (dot(f.s), dot(f.t), dot(f.n));
    let s = if z > 0.0 {
        (x * x + y * y) / (1.0 + z)
    } else {
        1.0 - z
    }
    .clamp(0.0, 2.0);
    let k = kappa as f64;
    let u0 = if k < UNIFORM_BELOW {
        0.5 * s
    } else {
        (-k * s).exp_m1() / (-2.0 * k).exp_m1()
    };
    let mut phi = y.atan2(x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    Vec2::new(
        u0.clamp(0.0, 1.0) as f32,
        ((phi / (2.0 * PI)) as f32).min(1.0 - f32::EPSILON),
    )
}

#[cfg(test)]
mod tests;
