//! The spherical L2 distance between two weighted vMF lobes (paper section 4.1, eq. 7-8 and
//! appendix A): the measure the paper's angular and spatial refinement compare slices with.
//!
//! # Exact form
//! With `S(kappa) = int f^2 = c(kappa)^2 / c(2 kappa) = kappa coth(kappa) / (4 pi)` and the
//! cross term `X = int f0 f1 = c(kappa0) c(kappa1) / c(kappa_c)` ([`super::inner_product`]),
//!
//! ```text
//! |a0 f0 - a1 f1|^2 = a0^2 S0 + a1^2 S1 - 2 a0 a1 X
//!                   = (a0 sqrt(S0) - a1 sqrt(S1))^2 + 2 a0 a1 sqrt(S0 S1) (1 - exp(-L)),
//! L = ln(sqrt(S0 S1) / X) = h(kappa_c) + D - (h(2 kappa0) + h(2 kappa1)) / 2 >= 0
//! ```
//! (Cauchy-Schwarz), with `h` and `D = kappa0 + kappa1 - kappa_c` of the parent module. The
//! second line is what [`l2_distance_squared`] evaluates: both terms are non-negative and
//! computed without cancellation, so nearly equal lobes get a distance accurate to rounding
//! of its own size rather than of `S` (the first line loses everything there). For large
//! concentrations `h(k) = ln k + g(k)`, `g(k) = -ln(1 - exp(-2 k))` tiny, and the logarithm
//! `ln(kappa_c / (2 sqrt(kappa0 kappa1)))` is taken as `ln_1p` of
//! `(kappa_c^2 - 4 kappa0 kappa1) / (2 sqrt(kappa0 kappa1) (kappa_c + 2 sqrt(kappa0 kappa1)))`,
//! `kappa_c^2 - 4 kappa0 kappa1 = (kappa0 - kappa1)^2 - kappa0 kappa1 |mu0 - mu1|^2`.
//!
//! # The paper's large-kappa approximation (eq. 7)
//! For `kappa >> 1`, `c(kappa) ~ kappa exp(-kappa) / (2 pi)` and
//!
//! ```text
//! |a0 f0 - a1 f1|^2 ~ a0^2 kappa0 / (4 pi) + a1^2 kappa1 / (4 pi)
//!                     - a0 a1 kappa0 kappa1 exp(kappa_c - kappa0 - kappa1) / (pi kappa_c)
//! ```
//! ([`l2_distance_squared_large_kappa`]). This is the appendix's last line; eq. 7 as printed
//! has `exp(-kappa_c - ...)` and eq. 8 `kappa_c = 1 / |...|`, both typos (with them the cross
//! term would vanish for equal lobes). The approximation drops factors `1 - exp(-2 k)` for
//! `k` in `kappa0`, `kappa1` **and `kappa_c`**, and `kappa_c` is small for near-opposite
//! lobes of similar concentration. The paper's condition `kappa0, kappa1 >> 1` still makes that
//! harmless, because the cross term carries `exp(-D)`, `D ~ kappa0 + kappa1` there: measured
//! (test `large_kappa_approximation_error_table`, normalised by `a0^2 S0 + a1^2 S1`) the error
//! is 5e-2 to 1.3 at `kappa = 0.5`, up to 2.5e-2 at `kappa = 3` (the paper's smallest), 1e-7 at
//! 10 (f32 rounding) and nothing visible beyond. Only exactly opposite lobes of equal
//! concentration (`kappa_c = 0`) make the `1 / kappa_c` infinite.

use super::{combined_kappa, h, one_minus_dot, unit64, VmfLobe, LN_2PI};
use crate::Vec3;
use std::f64::consts::PI;

/// `S(kappa) = int f^2` of the unit lobe, `kappa coth(kappa) / (4 pi)` (`1 / (4 pi)` at 0),
/// computed as `exp(2 h(kappa) - h(2 kappa)) / (2 pi)` (no overflow).
///
/// # Panics
/// Debug builds assert `kappa >= 0`.
pub fn self_inner_product(kappa: f64) -> f64 {
    (2.0 * h(kappa) - h(2.0 * kappa) - LN_2PI).exp()
}

/// `L = ln(sqrt(S0 S1) / X) >= 0` (module docs), without cancellation.
fn log_ratio(k0: f64, m0: [f64; 3], k1: f64, m1: [f64; 3]) -> f64 {
    let (kc, d) = combined_kappa(k0, m0, k1, m1);
    let dh = if kc.min(2.0 * k0).min(2.0 * k1) >= 1.0 {
        let g = |k: f64| -(-(-2.0 * k).exp()).ln_1p();
        let s = (k0 * k1).sqrt();
        // kappa_c^2 - 4 k0 k1 = (k0 - k1)^2 - k0 k1 |m0 - m1|^2, |m0 - m1|^2 = 2 (1 - m0 . m1).
        let num = (k0 - k1) * (k0 - k1) - 2.0 * k0 * k1 * one_minus_dot(m0, m1);
        let ratio = num / (2.0 * s * (kc + 2.0 * s));
        ratio.ln_1p() + g(kc) - 0.5 * (g(2.0 * k0) + g(2.0 * k1))
    } else {
        h(kc) - 0.5 * (h(2.0 * k0) + h(2.0 * k1))
    };
    (dh + d).max(0.0)
}

/// The exact squared L2 distance `int (f_a - f_b)^2` of two weighted lobes, per RGB channel
/// (module docs: computed without cancellation, so equal lobes give 0 and nearly equal ones a
/// small distance with full relative accuracy). Valid for every concentration, including 0.
pub fn l2_distance_squared(a: &VmfLobe, b: &VmfLobe) -> Vec3 {
    let (k0, k1) = (a.kappa as f64, b.kappa as f64);
    let (m0, m1) = (unit64(a.axis), unit64(b.axis));
    let (s0, s1) = (self_inner_product(k0), self_inner_product(k1));
    let shape = -(-log_ratio(k0, m0, k1, m1)).exp_m1() * 2.0 * (s0 * s1).sqrt();
    let per = |x: f32, y: f32| {
        let (x, y) = (x as f64, y as f64);
        let diff = x * s0.sqrt() - y * s1.sqrt();
        (diff * diff + x * y * shape) as f32
    };
    Vec3::new(
        per(a.amplitude.x, b.amplitude.x),
        per(a.amplitude.y, b.amplitude.y),
        per(a.amplitude.z, b.amplitude.z),
    )
}

/// The paper's large-kappa approximation of [`l2_distance_squared`] (eq. 7 with the
/// appendix's signs, module docs), per RGB channel. Only meaningful when `kappa0` and `kappa1`
/// are well above 1 (3 gives errors of a few per cent); for exactly opposite axes of equal
/// concentration (`kappa_c = 0`) the cross term is infinite and so is the result (never NaN:
/// a zero amplitude product drops the cross term).
pub fn l2_distance_squared_large_kappa(a: &VmfLobe, b: &VmfLobe) -> Vec3 {
    let (k0, k1) = (a.kappa as f64, b.kappa as f64);
    let (kc, d) = combined_kappa(k0, unit64(a.axis), k1, unit64(b.axis));
    let cross = k0 * k1 * (-d).exp() / (PI * kc);
    let per = |x: f32, y: f32| {
        let (x, y) = (x as f64, y as f64);
        let c = if x * y == 0.0 { 0.0 } else { x * y * cross };
        ((x * x * k0 + y * y * k1) / (4.0 * PI) - c) as f32
    };
    Vec3::new(
        per(a.amplitude.x, b.amplitude.x),
        per(a.amplitude.y, b.amplitude.y),
        per(a.amplitude.z, b.amplitude.z),
    )
}

/// `int (A - B)^2` of two mixtures per RGB channel, `sum <A_j, A_k> - 2 sum <A_j, B_k> +
/// sum <B_j, B_k>` with the exact inner products (clamped at 0). Unlike
/// [`l2_distance_squared`] this form cancels: its absolute accuracy is about `1e-7` times
/// `|A|^2 + |B|^2` (f32 products).
pub fn mixture_l2_distance_squared(a: &[VmfLobe], b: &[VmfLobe]) -> Vec3 {
    let ip = |x: &[VmfLobe], y: &[VmfLobe]| {
        let mut acc = [0f64; 3];
        for p in x {
            for q in y {
                let v = super::inner_product(p, q);
                acc[0] += v.x as f64;
                acc[1] += v.y as f64;
                acc[2] += v.z as f64;
            }
        }
        acc
    };
    let (aa, ab, bb) = (ip(a, a), ip(a, b), ip(b, b));
    let c = |i: usize| (aa[i] - 2.0 * ab[i] + bb[i]).max(0.0) as f32;
    Vec3::new(c(0), c(1), c(2))
}

#[cfg(test)]
mod tests;
