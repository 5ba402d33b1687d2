//! Moment matching of fitted lobes (the shape of one Gaussian standing for a GGX lobe).
//!
//! The least-squares fit (thesis eq. 3.1) spends its one Gaussian on the core of a GGX lobe
//! and misses its long tails; rescaling its amplitude to the data's integral afterwards puts
//! the tails' energy into the core. What a relit pixel sees is the inner product
//! `int T(w) L(w) dw` with the lighting, so the parts of `T` that low-frequency lighting sees
//! (its integral and its first moment: its SH bands 0 and 1) matter more than its peak.
//!
//! [`match_moments`] is one M-step of an expectation-maximisation fit of the lobes to the data
//! read as a density (the closed form of von Mises-Fisher maximum likelihood, Banerjee et al.
//! 2005; `crate::vmf` has the same estimator for samples). With responsibilities
//! `r_k(w) = s_k(w) / sum_j s_j(w)`, `s_k` the channel sum of lobe `k`, and `t(w)` the
//! channel sum of the data:
//!
//! ```text
//! m_k = sum_i dA_i r_k(w_i) t_i w_i,    s_k = sum_i dA_i r_k(w_i) t_i
//! mu_k = m_k / |m_k|,                   lambda_k = A^{-1}(|m_k| / s_k)
//! a_kc = sum_i dA_i r_k(w_i) T_ic / I(lambda_k)
//! ```
//! with `A(lambda) = coth lambda - 1 / lambda` the mean cosine of the normalised lobe
//! ([`crate::vmf::mean_cosine`]) and `I` its integral ([`crate::sg::unit_integral`]). A lobe
//! `a exp(lambda (mu . w - 1))` has the first moment `a I(lambda) A(lambda) mu`, so each lobe
//! carries exactly its share of the data's integral (per channel) and of its first moment,
//! and so does the mixture: **with `N` lobes the mixture's SH bands 0 and 1 are the data's**
//! (of the channel sum; per channel when the channels are proportional), whatever `N`.
//! Sharpness clamped to `[lambda_min, lambda_max]` keeps the energy, not the first moment.

use super::FitTarget;
use crate::sg::{unit_integral, SgLobe};
use crate::vmf::kappa_from_one_minus_mean_cosine;
use crate::Vec3;

/// The lobes with the same slots as `lobes`, each moved to the moments of its share of
/// `target` (module docs). A lobe with no share of the data (no responsibility where the data
/// is non-zero) is returned unchanged; so are all lobes when every one has zero amplitude.
///
/// # Panics
/// Debug builds assert `0 < lambda_min <= lambda_max`.
pub fn match_moments(
    target: &FitTarget,
    lobes: &[SgLobe],
    lambda_min: f32,
    lambda_max: f32,
) -> Vec<SgLobe> {
    debug_assert!(lambda_min > 0.0 && lambda_min <= lambda_max);
    let n = lobes.len();
    let weight_of = |g: &SgLobe| (g.amplitude.x + g.amplitude.y + g.amplitude.z) as f64;
    if n == 0 || lobes.iter().all(|g| weight_of(g) <= 0.0) {
        return lobes.to_vec();
    }
    let axes: Vec<[f64; 3]> = lobes
        .iter()
        .map(|g| [g.axis.x as f64, g.axis.y as f64, g.axis.z as f64])
        .collect();
    let ln_a: Vec<f64> = lobes
        .iter()
        .map(|g| match weight_of(g) {
            w if w > 0.0 => w.ln(),
            _ => f64::NEG_INFINITY,
        })
        .collect();
    // E-step (responsibilities in log space: far from every axis the lobes underflow) and the
    // sufficient statistics of each lobe's share.
    let mut energy = vec![[0f64; 3]; n];
    let mut first = vec![[0f64; 3]; n];
    let mut mass = vec![0f64; n];
    let mut log_s = vec![0f64; n];
    for ((d, &w), v) in target.dirs.iter().zip(&target.weights).zip(&target.values) {
        let t = v[0] + v[1] + v[2];
        if t <= 0.0 || w <= 0.0 {
            continue;
        }
        let mut top = f64::NEG_INFINITY;
        for k in 0..n {
            let c = d[0] * axes[k][0] + d[1] * axes[k][1] + d[2] * axes[k][2];
            log_s[k] = ln_a[k] + lobes[k].sharpness as f64 * (c - 1.0);
            top = top.max(log_s[k]);
        }
        let total: f64 = log_s.iter().map(|&l| (l - top).exp()).sum();
        for k in 0..n {
            let r = (log_s[k] - top).exp() / total;
            if r == 0.0 {
                continue;
            }
            for c in 0..3 {
                energy[k][c] += r * w * v[c];
                first[k][c] += r * w * t * d[c];
            }
            mass[k] += r * w * t;
        }
    }
    // M-step: the closed-form lobe of each share.
    (0..n)
        .map(|k| {
            let m = first[k];
            let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            if mass[k] <= 0.0 {
                return lobes[k];
            }
            // No first moment (e.g. a constant): the broadest lobe, about the old axis.
            let axis = match len > 0.0 {
                true => Vec3::new(m[0] as f32, m[1] as f32, m[2] as f32),
                false => lobes[k].axis,
            };
            let q = (1.0 - len / mass[k]).max(0.0);
            let lambda = (kappa_from_one_minus_mean_cosine(q) as f32).clamp(lambda_min, lambda_max);
            let i = unit_integral(lambda) as f64;
            let e = energy[k];
            SgLobe::new(
                axis,
                lambda,
                Vec3::new(
                    (e[0].max(0.0) / i) as f32,
                    (e[1].max(0.0) / i) as f32,
                    (e[2].max(0.0) / i) as f32,
                ),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::EnvMap;
    use crate::sg::eval_mixture;
    use crate::vmf::mean_cosine;

    fn target_of(n: usize, f: impl Fn(Vec3) -> Vec3) -> FitTarget {
        FitTarget::from_env(&EnvMap::cube_from_fn(n, f))
    }

    /// Quadrature integral and first moment (of the channel sum) of a target.
    fn data_moments(t: &FitTarget) -> (Vec3, Vec3) {
        let (mut e, mut m) = (Vec3::ZERO, Vec3::ZERO);
        for ((d, &w), v) in t.dirs.iter().zip(&t.weights).zip(&t.values) {
            let v = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
            let d = Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
            e += v * w as f32;
            m += d * (v.x + v.y + v.z) * w as f32;
        }
        (e, m)
    }

    /// Closed-form integral and first moment (channel sum) of a mixture.
    fn mixture_moments(lobes: &[SgLobe]) -> (Vec3, Vec3) {
        lobes.iter().fold((Vec3::ZERO, Vec3::ZERO), |(e, m), g| {
            let i = unit_integral(g.sharpness);
            let a = mean_cosine(g.sharpness as f64) as f32;
            let s = g.amplitude.x + g.amplitude.y + g.amplitude.z;
            (e + g.amplitude * i, m + g.axis * (s * i * a))
        })
    }

    #[test]
    fn a_tabulated_gaussian_is_recovered_from_a_wrong_start() {
        let truth = SgLobe::new(Vec3::new(0.3, 0.8, -0.2), 30.0, Vec3::new(1.0, 0.6, 0.3));
        let t = target_of(64, |d| truth.eval(d));
        let start = SgLobe::new(Vec3::new(0.1, 0.9, 0.1), 120.0, Vec3::splat(0.2));
        let g = match_moments(&t, &[start], 0.05, 1e4)[0];
        // The cube-map quadrature of a 64-texel face (sigma = 0.18 rad over ~6 texels)
        // integrates the lobe's moments to about 1e-3 relative; 1 % leaves room for it.
        assert!(g.axis.dot(truth.axis) > 1.0 - 1e-5, "{g:?}");
        assert!((g.sharpness / truth.sharpness - 1.0).abs() < 0.01, "{g:?}");
        assert!(
            ((g.amplitude - truth.amplitude) / truth.amplitude)
                .abs()
                .max_element()
                < 0.01
        );
    }

    #[test]
    fn the_mixture_keeps_the_datas_integral_and_first_moment() {
        // A clipped, cosine-weighted heavy-tailed lobe (GGX-like, alpha 0.2) cut by a
        // horizon: not a Gaussian, so the check is of the invariant, not of a recovery.
        let n = Vec3::new(0.0, 0.0, 1.0);
        let r = Vec3::new(0.6, 0.0, 0.8);
        let f = |d: Vec3| {
            let c = d.dot(n);
            if c <= 0.0 || d.x < -0.3 {
                return Vec3::ZERO;
            }
            let h = d.dot(r.normalize());
            let a2 = 0.04f32;
            let den = h * h * (a2 - 1.0) + 1.0;
            Vec3::new(1.0, 0.7, 0.4) * (a2 / (std::f32::consts::PI * den * den) * c)
        };
        let t = target_of(48, f);
        let (e, m) = data_moments(&t);
        for start in [
            vec![SgLobe::new(r, 20.0, Vec3::ONE)],
            vec![
                SgLobe::new(r, 60.0, Vec3::ONE),
                SgLobe::new(Vec3::new(0.3, 0.2, 0.9), 5.0, Vec3::splat(0.1)),
            ],
        ] {
            let lobes = match_moments(&t, &start, 0.05, 1e4);
            let (e2, m2) = mixture_moments(&lobes);
            // f32 accumulation of ~14k texels in the test's sums: 1e-4 relative.
            assert!(((e2 - e) / e).abs().max_element() < 1e-4, "{e2} vs {e}");
            assert!((m2 - m).length() < 1e-4 * m.length(), "{m2} vs {m}");
            assert!(lobes.iter().all(|g| g.amplitude.min_element() >= 0.0));
        }
    }

    #[test]
    fn two_separated_gaussians_are_both_recovered() {
        let truth = [
            SgLobe::new(Vec3::new(1.0, 0.0, 0.2), 40.0, Vec3::new(1.0, 0.5, 0.2)),
            SgLobe::new(Vec3::new(-0.2, 0.1, 1.0), 15.0, Vec3::new(0.2, 0.3, 0.9)),
        ];
        let t = target_of(64, |d| eval_mixture(&truth, d));
        // Start swapped in sharpness and a little off: slots follow the axes.
        let start = [
            SgLobe::new(Vec3::new(0.9, 0.2, 0.2), 15.0, Vec3::ONE),
            SgLobe::new(Vec3::new(0.0, 0.0, 1.0), 40.0, Vec3::ONE),
        ];
        let mut lobes = start.to_vec();
        for _ in 0..20 {
            lobes = match_moments(&t, &lobes, 0.05, 1e4);
        }
        // The lobes are 80 degrees apart (overlap ~e^-10 of the peaks): EM converges to the
        // truth up to the quadrature's ~1e-3.
        for (g, tr) in lobes.iter().zip(&truth) {
            assert!(g.axis.dot(tr.axis.normalize()) > 1.0 - 1e-4, "{g:?}");
            assert!((g.sharpness / tr.sharpness - 1.0).abs() < 0.02, "{g:?}");
        }
    }

    #[test]
    fn zero_lobes_and_zero_data_are_left_alone() {
        let t = target_of(8, |_| Vec3::ZERO);
        let g = [SgLobe::new(Vec3::Z, 10.0, Vec3::ONE)];
        assert_eq!(match_moments(&t, &g, 0.05, 1e4), g.to_vec());
        let t = target_of(8, |_| Vec3::ONE);
        let z = [SgLobe::new(Vec3::Z, 10.0, Vec3::ZERO)];
        assert_eq!(match_moments(&t, &z, 0.05, 1e4), z.to_vec());
        // A constant: the broadest lobe allowed, carrying the whole integral.
        let g = match_moments(&t, &[SgLobe::new(Vec3::Z, 10.0, Vec3::ONE)], 0.05, 1e4)[0];
        assert_eq!(g.sharpness, 0.05);
        let e = g.amplitude * unit_integral(g.sharpness);
        assert!(
            (e - Vec3::splat(4.0 * std::f32::consts::PI))
                .abs()
                .max_element()
                < 1e-3
        );
    }
}
