//! The mean cosine `A(kappa) = coth kappa - 1 / kappa` of the unit vMF lobe, its inverse (the
//! maximum-likelihood concentration, and the paper's eq. 13 approximation of it), and the
//! moment-matched convolution of a lobe with a vMF kernel (paper section 6.2; parent module
//! docs, "Closed forms").

use super::{log_unit_inner_product, unit64, VmfLobe};
use crate::Vec3;

/// Coefficients of `coth x - 1/x = x/3 - x^3/45 + 2 x^5/945 - x^7/4725 + 2 x^9/93555 - ...`.
const LANGEVIN_SERIES: [f64; 5] = [
    1.0 / 3.0,
    -1.0 / 45.0,
    2.0 / 945.0,
    -1.0 / 4725.0,
    2.0 / 93555.0,
];

/// Below this `kappa` the Langevin function is evaluated by its series (relative truncation
/// error below `1e-16` at 0.1: the next term is `1382 x^11 / 638512875`).
const SERIES_BELOW: f64 = 0.1;

/// Mean cosine `A(kappa) = E[mu . w] = coth kappa - 1 / kappa` of the unit lobe (the
/// Langevin function): `~ kappa / 3` for small `kappa`, `~ 1 - 1 / kappa` for large, relative
/// accuracy about 1e-14 everywhere.
///
/// # Panics
/// Debug builds assert `kappa >= 0`.
pub fn mean_cosine(kappa: f64) -> f64 {
    debug_assert!(kappa >= 0.0);
    if kappa < SERIES_BELOW {
        let x2 = kappa * kappa;
        kappa
            * LANGEVIN_SERIES
                .iter()
                .rev()
                .fold(0.0, |acc, c| acc * x2 + c)
    } else {
        1.0 - one_minus_mean_cosine(kappa)
    }
}

/// `1 - A(kappa) = 1 / kappa - 2 exp(-2 kappa) / (1 - exp(-2 kappa))`, accurate also where
/// `A` is close to 1 (large `kappa`; `+inf` gives 0).
///
/// # Panics
/// Debug builds assert `kappa >= 0`.
pub fn one_minus_mean_cosine(kappa: f64) -> f64 {
    debug_assert!(kappa >= 0.0);
    if kappa < SERIES_BELOW {
        1.0 - mean_cosine(kappa)
    } else if kappa.is_infinite() {
        0.0
    } else {
        let e = (-2.0 * kappa).exp();
        1.0 / kappa - 2.0 * e / -(-2.0 * kappa).exp_m1()
    }
}

/// `A'(kappa) = 1 / kappa^2 - 1 / sinh^2 kappa` (= `1 - A^2 - 2 A / kappa`), each form where
/// it has no cancellation.
pub(crate) fn mean_cosine_derivative(kappa: f64) -> f64 {
    if kappa < 1.0 {
        let a = mean_cosine(kappa);
        if kappa < 1e-8 {
            1.0 / 3.0
        } else {
            1.0 - a * a - 2.0 * a / kappa
        }
    } else {
        let e = (-2.0 * kappa).exp();
        let t = -(-2.0 * kappa).exp_m1();
        1.0 / (kappa * kappa) - 4.0 * e / (t * t)
    }
}

/// The `kappa` whose mean cosine is `r`, i.e. `A^{-1}(r)` (the maximum-likelihood
/// concentration of a mean resultant length `r`): 0 for `r <= 0`, `+inf` for `r >= 1`.
/// Safeguarded Newton iteration in `ln kappa` on `ln(1 - A)`, started from Banerjee et al.'s
/// approximation `r (3 - r^2) / (1 - r^2)` (paper eq. 13); relative accuracy about 1e-13.
pub fn kappa_from_mean_cosine(r: f64) -> f64 {
    kappa_from_mean_cosine_q(r, 1.0 - r)
}

/// [`kappa_from_mean_cosine`] given `q = 1 - r` directly (accurate when `r` is within rounding
/// of 1, e.g. `q` accumulated as a mean of `1 - mu . w`): 0 for `q >= 1`, `+inf` for `q <= 0`.
pub fn kappa_from_one_minus_mean_cosine(q: f64) -> f64 {
    kappa_from_mean_cosine_q(1.0 - q, q)
}

/// The Banerjee et al. approximation of `A^{-1}` (paper eq. 13), `r (3 - r^2) / (1 - r^2)`,
/// from `r` and `q = 1 - r` (`1 - r^2 = q (1 + r)`): 0 for `r <= 0`, `+inf` for `q <= 0`.
pub fn kappa_banerjee(r: f64, q: f64) -> f64 {
    if r <= 0.0 || q >= 1.0 || r.is_nan() || q.is_nan() {
        0.0
    } else if q <= 0.0 {
        f64::INFINITY
    } else {
        r * (3.0 - r * r) / (q * (1.0 + r))
    }
}

fn kappa_from_mean_cosine_q(r: f64, q: f64) -> f64 {
    if r <= 0.0 || q >= 1.0 || r.is_nan() || q.is_nan() {
        return 0.0;
    }
    if q <= 0.0 {
        return f64::INFINITY;
    }
    // g(u) = ln(1 - A(e^u)) - ln q, decreasing in u = ln kappa; for large kappa it is close to
    // -u - ln q (linear), for small kappa -e^u / 3 - ln q.
    let target = if r < 0.5 { (-r).ln_1p() } else { q.ln() };
    let lq = |k: f64| {
        let a = mean_cosine(k);
        if a < 0.5 {
            (-a).ln_1p()
        } else {
            one_minus_mean_cosine(k).ln()
        }
    };
    let mut u = kappa_banerjee(r, q).ln();
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for _ in 0..100 {
        let k = u.exp();
        let g = lq(k) - target;
        if g > 0.0 {
            lo = u;
        } else {
            hi = u;
        }
        // dg/du = -k A'(k) / (1 - A(k)).
        let dg = -k * mean_cosine_derivative(k) / one_minus_mean_cosine(k);
        let mut next = u - g / dg;
        if !(next > lo && next < hi && next.is_finite()) {
            next = if lo.is_finite() && hi.is_finite() {
                0.5 * (lo + hi)
            } else if lo.is_finite() {
                lo + 1.0
            } else {
                hi - 1.0
            };
        }
        let step = (next - u).abs();
        u = next;
        if step < 1e-15 * u.abs().max(1.0) {
            break;
        }
    }
    u.exp()
}

/// The vMF approximation of the spherical convolution of `lobe` with the normalised zonal vMF
/// kernel of concentration `kernel_kappa`, `w -> int f(s) c(k2) exp(k2 s . w) ds`: the same axis
/// and amplitude, and `kappa3` with `A(kappa3) = A(kappa1) A(kappa2)` (module docs), solved
/// through `1 - A3 = q1 + q2 - q1 q2`, `q = 1 - A` (so large concentrations lose no digits).
/// For large concentrations `1 / kappa3 ~ 1 / kappa1 + 1 / kappa2` (variances add). Each
/// prefiltering level of the paper's section 6.2 is such a kernel, `kappa` doubling per level.
///
/// # Panics
/// Debug builds assert `kernel_kappa >= 0`.
pub fn convolve(lobe: &VmfLobe, kernel_kappa: f32) -> VmfLobe {
    debug_assert!(kernel_kappa >= 0.0);
    VmfLobe {
        kappa: convolved_kappa(lobe.kappa as f64, kernel_kappa as f64) as f32,
        ..*lobe
    }
}

/// The concentration of [`convolve`]: `A^{-1}(A(kappa1) A(kappa2))`.
pub fn convolved_kappa(kappa1: f64, kappa2: f64) -> f64 {
    let (q1, q2) = (one_minus_mean_cosine(kappa1), one_minus_mean_cosine(kappa2));
    let q = q1 + q2 - q1 * q2;
    kappa_from_mean_cosine_q(mean_cosine(kappa1) * mean_cosine(kappa2), q)
}

/// The exact value at unit `dir` of the convolution approximated by [`convolve`]:
/// `alpha int c(k1) e^{k1 mu . s} c(k2) e^{k2 s . dir} ds`, an inner product.
pub fn convolution_exact(lobe: &VmfLobe, kernel_kappa: f32, dir: Vec3) -> Vec3 {
    let x = log_unit_inner_product(
        lobe.kappa as f64,
        unit64(lobe.axis),
        kernel_kappa as f64,
        unit64(dir),
    )
    .exp();
    lobe.amplitude * x as f32
}
