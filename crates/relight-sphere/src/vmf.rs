//! von Mises-Fisher (vMF) lobes: the spherical representation of Laurijssen & Dutré 2009
//! ("Adaptive Precomputation of Glossy Interreflections", KU Leuven report CW 548; "the paper"
//! below), built as tested library code: evaluation with a normaliser stable for every `kappa`,
//! the exact and large-`kappa` L2 distance ([`distance`]), sampling ([`sample`]), products and
//! convolutions, and lobe estimation by expectation-maximisation ([`em`]).
//!
//! # Definition and conventions (stated once, here)
//! A vMF lobe with unit axis `mu`, concentration `kappa >= 0` and RGB amplitude `alpha` is
//! (paper eq. 5 and 16)
//!
//! ```text
//! f(w) = alpha c(kappa) exp(kappa mu . w),   c(kappa) = kappa / (4 pi sinh kappa)
//! ```
//!
//! * The **unit lobe** (`alpha = 1`) is a probability density over the sphere per unit solid
//!   angle: it integrates to 1, so **`alpha` is the lobe's integral** (its energy), not its peak.
//!   `kappa = 0` is the uniform density `1 / (4 pi)` (any axis).
//! * Directions are unit [`Vec3`] in any frame (the crate's world frame is +Y up, but nothing here
//!   depends on it); the lobe's own frame ([`crate::warp::Frame::from_normal`] of `mu`) has `mu`
//!   along +Z and is used only by the sampler.
//! * All maths is done in f64 and stored in f32 (as [`SgLobe`]). `c(kappa)` itself underflows
//!   for `kappa > ~700`; nothing here uses it. Every evaluation goes through the **peak form**
//!
//!   ```text
//!   f(w) = alpha p(kappa) exp(-kappa s),   p(kappa) = kappa / (2 pi (1 - exp(-2 kappa))),
//!   s = 1 - mu . w = |mu - w|^2 / 2
//!   ```
//!
//!   where `p(kappa) = c(kappa) e^kappa` is the peak value (`-> 1 / (4 pi)` as `kappa -> 0`,
//!   `~ kappa / (2 pi)` for large `kappa`) and `1 - exp(-2 kappa)` is `-expm1(-2 kappa)`. The
//!   half squared chord `|mu - w|^2 / 2` equals `1 - mu . w` for unit vectors but keeps full
//!   relative precision when `w` is close to `mu`, which is what `kappa = 1e8` (a width of
//!   1e-4 radian) needs; in logs, `ln c(kappa) = h(kappa) - kappa - ln 2 pi` with
//!   `h(kappa) = ln(kappa / (1 - exp(-2 kappa)))` ([`log_normaliser`]).
//! * **Relation to spherical Gaussians**: a vMF is a normalised SG. The SG
//!   `a exp(lambda (mu . w - 1))` of [`crate::sg`] is the vMF with `kappa = lambda` and
//!   `alpha = a / p(lambda) = a 2 pi (1 - exp(-2 lambda)) / lambda` ([`VmfLobe::to_sg`],
//!   [`VmfLobe::from_sg`]).
//! * Estimated concentrations are clamped to `kappa_max` ([`EmOptions::kappa_max`], by default
//!   [`KAPPA_MAX`]): a mirror-like lobe is clamped there, its amplitude (energy) kept.
//!   [`kappa_from_mean_cosine`] itself returns `+inf` for `r >= 1`, for its caller to clamp.
//!
//! # Closed forms (paper section 3, 4.1, appendix A)
//! * Inner product: `int f1 f2 = alpha1 alpha2 c(kappa1) c(kappa2) / c(kappa_c)` with
//!   `kappa_c = |kappa1 mu1 + kappa2 mu2|` (the product of two vMF densities is an unnormalised
//!   vMF), evaluated in logs: `exp(h1 + h2 - h_c - D - ln 2 pi)` with `D = kappa1 + kappa2 -
//!   kappa_c = 2 kappa1 kappa2 (1 - mu1 . mu2) / (kappa1 + kappa2 + kappa_c)` (no
//!   cancellation, no overflow) ([`inner_product`]). The paper's eq. 8 prints
//!   `kappa_c = 1 / |mu0 kappa0 + mu1 kappa1|`; the appendix uses (and the algebra needs) the
//!   norm itself.
//! * Product: `f1 f2` is the vMF of axis `(kappa1 mu1 + kappa2 mu2) / kappa_c`, concentration
//!   `kappa_c` and amplitude `int f1 f2` ([`product`]).
//! * Mean cosine: `E[mu . w] = A(kappa) = coth kappa - 1 / kappa` (the Langevin function,
//!   [`mean_cosine`]), and its inverse ([`kappa_from_mean_cosine`]), the maximum-likelihood
//!   `kappa` of a mean resultant length (Banerjee et al. 2005, "Clustering on the unit
//!   hypersphere using von Mises-Fisher distributions", JMLR 6, section 4).
//! * Convolution (prefiltering, paper section 6.2): the spherical convolution of a lobe with a
//!   normalised vMF kernel is axially symmetric about `mu1`, of integral `alpha1`, but not a
//!   vMF. Its first Legendre moment is the product of theirs (Funk-Hecke), so the vMF with
//!   `A(kappa3) = A(kappa1) A(kappa2)` is the moment-matched approximation ([`convolve`]); its
//!   exact value at a direction is an inner product ([`convolution_exact`]). Measured relative
//!   L2 error of the approximation: about `0.32 / min(kappa1, kappa2)` for comparable
//!   concentrations (3.2 % at 10 and 10, 0.3 % at 100 and 100), far less when one dominates
//!   (test `convolution_is_moment_matched_and_close_for_sharp_lobes`). A normalised SG kernel
//!   is a vMF kernel, so the chain of [`crate::env_prefilter`] (levels store kernel-weighted
//!   averages) is already a vMF-prefiltered chain; what is vMF-specific is choosing the level
//!   by `kappa` and, when a lobe is itself blurred, [`convolved_kappa`].
//!
//! # Example
//! ```
//! use relight_sphere::vmf::{self, em, VmfLobe};
//! use relight_sphere::{Rng, Vec3};
//! // Path samples of a slice: directions drawn from a lobe, each weighing 1/N of its energy.
//! let truth = VmfLobe::new(Vec3::new(0.0, 0.8, 0.6), 50.0, Vec3::new(0.6, 0.4, 0.2));
//! let mut rng = Rng::new(1, 0);
//! let samples: Vec<em::WeightedDir> = (0..4000)
//!     .map(|_| em::WeightedDir {
//!         dir: vmf::sample_vmf(truth.axis, truth.kappa, rng.next_vec2()),
//!         weight: truth.amplitude / 4000.0,
//!     })
//!     .collect();
//! // The paper's closed-form estimate (eq. 13-15) recovers the lobe.
//! let fit = vmf::estimate_one_lobe(&samples, vmf::KappaEstimate::Banerjee, vmf::KAPPA_MAX)
//!     .expect("samples with weight");
//! assert!((fit.kappa / 50.0 - 1.0).abs() < 0.1);
//! assert!((fit.amplitude - truth.amplitude).abs().max_element() < 1e-4);
//! // Their exact L2 distance is small next to the lobe's own norm.
//! let d2 = vmf::l2_distance_squared(&fit, &truth).x;
//! let norm2 = vmf::l2_distance_squared(&truth, &VmfLobe { amplitude: Vec3::ZERO, ..truth }).x;
//! assert!(d2 < 0.01 * norm2);
//! ```
//!
//! # Why a vMF mixture does not implement [`crate::basis::SphericalBasis`]
//! As for SGs ([`crate::sg`]): axes and concentrations enter non-linearly, so a mixture is
//! fitted (by EM, [`em`]), not projected. The trait's verbs are free functions: eval
//! ([`eval_mixture`]), fit ([`em::fit_em`]), rotate ([`VmfLobe::rotated`]), integrate a product
//! ([`inner_product`]).

pub mod distance;
pub mod em;
pub mod moments;
pub mod sample;

use crate::sg::SgLobe;
use crate::{Mat3, Vec3};
use std::f64::consts::{LN_2, PI};

pub use distance::{
    l2_distance_squared, l2_distance_squared_large_kappa, mixture_l2_distance_squared,
};
pub use em::{
    estimate_one_lobe, fit_em, fit_em_nested, log_likelihood, EmFit, EmOptions, KappaEstimate,
    WeightedDir,
};
#[cfg(test)]
pub(crate) use moments::mean_cosine_derivative;
pub use moments::{
    convolution_exact, convolve, convolved_kappa, kappa_banerjee, kappa_from_mean_cosine,
    kappa_from_one_minus_mean_cosine, mean_cosine, one_minus_mean_cosine,
};
pub use sample::{invert_vmf_sample, sample_vmf, vmf_pdf};

/// Largest concentration produced by estimation (fits, [`kappa_from_mean_cosine`] callers):
/// a lobe about 1e-4 radian wide, still resolved by f32 unit vectors (spacing ~6e-8).
pub const KAPPA_MAX: f32 = 1.0e8;

/// `ln(2 pi)`.
const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// One vMF lobe `alpha c(kappa) exp(kappa mu . w)` (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VmfLobe {
    /// Unit mean direction `mu`.
    pub axis: Vec3,
    /// Concentration `kappa >= 0` (0: uniform).
    pub kappa: f32,
    /// RGB amplitude `alpha`: the lobe's integral over the sphere.
    pub amplitude: Vec3,
}

/// `h(kappa) = ln(kappa / (1 - exp(-2 kappa)))`, the non-exponential part of the log
/// normaliser (module docs); `-ln 2` at `kappa = 0`.
#[inline]
pub(crate) fn h(kappa: f64) -> f64 {
    debug_assert!(kappa >= 0.0);
    if kappa < 1e-12 {
        // kappa / (1 - e^{-2 kappa}) = 1/2 (1 + kappa + kappa^2 / 3 + ...): ln = -ln 2 + kappa
        // + O(kappa^2).
        -LN_2 + kappa
    } else {
        (kappa / -(-2.0 * kappa).exp_m1()).ln()
    }
}

/// `ln c(kappa) = ln(kappa / (4 pi sinh kappa))` for every `kappa >= 0` (`-ln 4 pi` at 0,
/// `~ ln(kappa / 2 pi) - kappa` for large `kappa`); never overflows.
///
/// # Panics
/// Debug builds assert `kappa >= 0`.
#[inline]
pub fn log_normaliser(kappa: f64) -> f64 {
    h(kappa) - kappa - LN_2PI
}

/// The peak value `p(kappa) = c(kappa) e^kappa = kappa / (2 pi (1 - exp(-2 kappa)))` of the
/// unit lobe: `1 / (4 pi)` at `kappa = 0`, `~ kappa / (2 pi)` for large `kappa`.
///
/// # Panics
/// Debug builds assert `kappa >= 0`.
#[inline]
pub fn peak_value(kappa: f64) -> f64 {
    h(kappa).exp() / (2.0 * PI)
}

/// The normaliser `c(kappa) = kappa / (4 pi sinh kappa)` itself (paper eq. 16): exact to a few
/// ulps for every `kappa` but **underflows to 0 beyond `kappa ~ 745`**; prefer
/// [`log_normaliser`] or the peak form of [`VmfLobe::eval_unit`].
///
/// # Panics
/// Debug builds assert `kappa >= 0`.
#[inline]
pub fn normaliser(kappa: f64) -> f64 {
    log_normaliser(kappa).exp()
}

/// `1 - mu . w` as the half squared chord `|mu - w|^2 / 2` in f64 (accurate near `mu`).
#[inline]
pub(crate) fn one_minus_dot(mu: [f64; 3], w: [f64; 3]) -> f64 {
    let d = [mu[0] - w[0], mu[1] - w[1], mu[2] - w[2]];
    0.5 * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
}

/// A [`Vec3`] as f64, normalised in f64 (zero stays zero).
#[inline]
pub(crate) fn unit64(v: Vec3) -> [f64; 3] {
    let v = [v.x as f64, v.y as f64, v.z as f64];
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 0.0 {
        [v[0] / n, v[1] / n, v[2] / n]
    } else {
        v
    }
}

impl VmfLobe {
    /// A lobe; `axis` is normalised.
    ///
    /// # Panics
    /// Debug builds assert a non-zero axis and a finite `kappa >= 0`.
    pub fn new(axis: Vec3, kappa: f32, amplitude: Vec3) -> VmfLobe {
        debug_assert!(axis.length_squared() > 0.0 && kappa >= 0.0 && kappa.is_finite());
        VmfLobe {
            axis: axis.normalize(),
            kappa,
            amplitude,
        }
    }

    /// Density of the unit lobe, `c(kappa) exp(kappa mu . w)`, at unit `dir`, in f64 (the peak
    /// form of the module docs).
    ///
    /// # Panics
    /// Debug builds assert that `dir` is unit length.
    #[inline]
    pub fn eval_unit64(&self, dir: Vec3) -> f64 {
        debug_assert!(
            (dir.length_squared() - 1.0).abs() < 1e-3,
            "dir must be unit"
        );
        let k = self.kappa as f64;
        let s = one_minus_dot(unit64(self.axis), unit64(dir));
        (h(k) - k * s).exp() / (2.0 * PI)
    }

    /// Density of the unit lobe at unit `dir` (f32 of [`VmfLobe::eval_unit64`]).
    #[inline]
    pub fn eval_unit(&self, dir: Vec3) -> f32 {
        self.eval_unit64(dir) as f32
    }

    /// Value `alpha c(kappa) exp(kappa mu . w)` at unit `dir`.
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        self.amplitude * self.eval_unit(dir)
    }

    /// Integral over the sphere: the amplitude.
    #[inline]
    pub fn integral(&self) -> Vec3 {
        self.amplitude
    }

    /// The lobe of `w -> f(R^T w)`, i.e. rotated by `world_from_lobe` (axis `R mu`).
    #[inline]
    pub fn rotated(&self, world_from_lobe: Mat3) -> VmfLobe {
        VmfLobe {
            axis: (world_from_lobe * self.axis).normalize(),
            ..*self
        }
    }

    /// The same function as a spherical Gaussian `a exp(lambda (mu . w - 1))`:
    /// `lambda = kappa`, `a = alpha p(kappa)`. A `kappa = 0` lobe gives an SG of sharpness 0
    /// (a constant), which [`SgLobe::new`] would refuse but which evaluates correctly.
    pub fn to_sg(&self) -> SgLobe {
        SgLobe {
            axis: self.axis,
            sharpness: self.kappa,
            amplitude: self.amplitude * peak_value(self.kappa as f64) as f32,
        }
    }

    /// The vMF equal to the SG `g`: `kappa = lambda`, `alpha = a / p(lambda)`.
    ///
    /// # Panics
    /// Debug builds assert `g.sharpness >= 0` and a non-zero axis.
    pub fn from_sg(g: &SgLobe) -> VmfLobe {
        debug_assert!(g.sharpness >= 0.0);
        VmfLobe::new(
            g.axis,
            g.sharpness,
            g.amplitude / peak_value(g.sharpness as f64) as f32,
        )
    }
}

/// Value of the mixture `sum_k f_k(dir)`.
#[inline]
pub fn eval_mixture(lobes: &[VmfLobe], dir: Vec3) -> Vec3 {
    lobes.iter().fold(Vec3::ZERO, |acc, g| acc + g.eval(dir))
}

/// `|kappa1 mu1 + kappa2 mu2|` and `D = kappa1 + kappa2 - kappa_c >= 0`, both without
/// cancellation (module docs), from unit f64 axes.
pub(crate) fn combined_kappa(k1: f64, m1: [f64; 3], k2: f64, m2: [f64; 3]) -> (f64, f64) {
    // kappa_c^2 = (k1 - k2)^2 + k1 k2 |m1 + m2|^2: exact for unit axes and free of
    // cancellation both for parallel and for opposite axes.
    let p = [m1[0] + m2[0], m1[1] + m2[1], m1[2] + m2[2]];
    let kc = ((k1 - k2) * (k1 - k2) + k1 * k2 * (p[0] * p[0] + p[1] * p[1] + p[2] * p[2])).sqrt();
    let sum = k1 + k2 + kc;
    let d = if sum > 0.0 {
        2.0 * k1 * k2 * one_minus_dot(m1, m2) / sum
    } else {
        0.0
    };
    (kc, d)
}

/// `ln int c1 e^{k1 m1 . w} c2 e^{k2 m2 . w} dw = ln c(k1) + ln c(k2) - ln c(k_c)` (f64).
pub(crate) fn log_unit_inner_product(k1: f64, m1: [f64; 3], k2: f64, m2: [f64; 3]) -> f64 {
    let (kc, d) = combined_kappa(k1, m1, k2, m2);
    h(k1) + h(k2) - h(kc) - d - LN_2PI
}

/// `int f1(w) f2(w) dw` in closed form (module docs), per RGB channel; exact for all
/// concentrations (computed in logs in f64).
pub fn inner_product(a: &VmfLobe, b: &VmfLobe) -> Vec3 {
    let x = log_unit_inner_product(
        a.kappa as f64,
        unit64(a.axis),
        b.kappa as f64,
        unit64(b.axis),
    )
    .exp();
    a.amplitude * b.amplitude * x as f32
}

/// The product `f1 f2`, a vMF (module docs): axis `(k1 mu1 + k2 mu2) / k_c`, concentration
/// `k_c = |k1 mu1 + k2 mu2|`, amplitude `int f1 f2` (component-wise RGB). When `k_c` is 0
/// (equal concentrations, opposite axes) the product is a constant, returned as a `kappa = 0`
/// lobe about `mu1` of the same integral.
pub fn product(a: &VmfLobe, b: &VmfLobe) -> VmfLobe {
    let (k1, k2) = (a.kappa as f64, b.kappa as f64);
    let (m1, m2) = (unit64(a.axis), unit64(b.axis));
    let (kc, _) = combined_kappa(k1, m1, k2, m2);
    let u = Vec3::new(
        (k1 * m1[0] + k2 * m2[0]) as f32,
        (k1 * m1[1] + k2 * m2[1]) as f32,
        (k1 * m1[2] + k2 * m2[2]) as f32,
    );
    VmfLobe {
        axis: u.try_normalize().unwrap_or(a.axis),
        kappa: kc as f32,
        amplitude: inner_product(a, b),
    }
}

#[cfg(test)]
pub(crate) mod tests;
