//! Estimating vMF lobes from weighted directions (paper sections 5.1-5.2, eq. 13-15): the
//! closed-form one-lobe estimate the paper uses per light-path class, and the full iterative
//! expectation-maximisation (EM) for several lobes that it leaves as future work.
//!
//! # Data
//! A transfer slice is known through path samples: unit directions `x_i` that escaped to the
//! environment, each with an RGB weight `w_i` (its radiance contribution; paper eq. 15: the
//! product of the lobe weights `beta` along the path). **Weights are Monte Carlo estimates
//! already divided by the number of paths traced** (escaped or not), so `sum_i w_i` estimates
//! the slice's integral; the paper's eq. 15, `alpha_j = M_j / M sum_i prod_k beta_ijk`, reads
//! the same once its sum is taken as the mean over the `M_j` samples of the class (`M` paths
//! in all). The **shape weight** of a sample is the channel sum `s_i = w_r + w_g + w_b` (as
//! [`crate::sg_fit`] ranks residuals); negative or non-finite channels count as 0 and samples
//! with `s_i = 0` (or a zero direction) are ignored, so no input gives a NaN.
//!
//! # One lobe in closed form (eq. 13-15)
//! With `W = sum s_i`, the mean resultant `n = sum s_i x_i / W`, `r = |n|`, `mu = n / r`
//! (eq. 14), `kappa` from `r` (eq. 13: Banerjee et al.'s `r (3 - r^2) / (1 - r^2)`, or the exact
//! maximum-likelihood `A^{-1}(r)`, [`KappaEstimate`]) and `alpha = sum w_i` (eq. 15; RGB). The
//! paper calls eq. 13-14 unbiased; they are the (approximate) maximum-likelihood estimates,
//! biased towards larger `kappa` for few samples (no correction is applied). `1 - r` is
//! accumulated as `sum s_i (1 - mu . x_i) / W` (the half squared chord), so `kappa` up to
//! [`KAPPA_MAX`] keeps its digits; a single sample, or all samples in one direction, gives
//! `kappa_max`; `n = 0` (e.g. two opposite samples of equal weight) gives `kappa = 0` about the
//! heaviest sample.
//!
//! # Several lobes: EM for a weighted mixture
//! The weighted log-likelihood `l = sum_i s_i ln p(x_i) / W`, `p = sum_j pi_j f_j`, is raised
//! by the soft-assignment EM of Banerjee et al. 2005 (section 4.1, with sample weights):
//! * **E-step**: responsibilities `r_ij = pi_j f_j(x_i) / p(x_i)`, in logs with log-sum-exp
//!   (`ln f = h(kappa) - kappa (1 - mu . x) - ln 2 pi`, no underflow for any `kappa`).
//! * **M-step**: `W_j = sum_i s_i r_ij`, `pi_j = W_j / W`, `mu_j` the direction of
//!   `sum_i s_i r_ij x_i`, `kappa_j = min(A^{-1}(r_j), kappa_max)` (exact maximum likelihood;
//!   `ln c(kappa) + kappa r` is concave in `kappa`, so the clamped value is the constrained
//!   maximiser and every iteration still cannot lower `l`). A class with `W_j = 0` keeps its
//!   axis and concentration and gets `pi_j = 0` (it is "dead": no responsibilities, zero
//!   amplitude).
//! * **Stop** when `l` gains less than [`EmOptions::tolerance`] or after
//!   [`EmOptions::max_iterations`]; the best parameters seen are returned.
//! * **Amplitudes**: `alpha_j = sum_i r_ij w_i` (RGB) from the final responsibilities, so the
//!   lobes' integrals always sum to `sum w_i` exactly (energy kept, also when `kappa` is clamped).
//!
//! # Deterministic, nested initialisation
//! One lobe is the closed-form estimate (one EM step from anything). `K` lobes start from the
//! `K - 1` fit by **splitting** one lobe: its samples' tangent-plane scatter (weighted by
//! `s_i r_ij`) gives a principal direction `e` and spread `sigma`; the two children sit at
//! `normalize(mu +- sigma e)` with half the weight and twice the concentration (at least 2,
//! at most `kappa_max`).
//! If the scatter is zero, one child goes to the sample of the class farthest from `mu`.
//! Every lobe is tried with [`EmOptions::split_trial_iterations`] EM steps and the best
//! continues to convergence. If that ends below the `K - 1` fit's likelihood (possible, since a
//! split does not start at that likelihood), the `K - 1` lobes plus a dead copy are returned,
//! so **more lobes never give a lower likelihood on the same data** ([`fit_em_nested`]).
//!
//! Like every mixture likelihood, `l` is unbounded: a lobe on one sample gains without limit as
//! `kappa` grows. [`EmOptions::kappa_max`] bounds that; with few samples per lobe, lower it to
//! the sharpest lobe the slice can hold (e.g. the material's).

use super::{h, kappa_banerjee, kappa_from_one_minus_mean_cosine, one_minus_dot, unit64};
use super::{VmfLobe, KAPPA_MAX, LN_2PI};
use crate::Vec3;

/// One path sample: an escaped unit direction and its RGB contribution (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WeightedDir {
    /// Unit direction towards the environment.
    pub dir: Vec3,
    /// RGB weight (radiance contribution divided by the number of paths).
    pub weight: Vec3,
}

/// How the one-lobe estimate turns the mean resultant length `r` into `kappa`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KappaEstimate {
    /// The paper's eq. 13 (Banerjee et al. 2005's approximation), `r (3 - r^2) / (1 - r^2)`.
    Banerjee,
    /// The exact maximum-likelihood value `A^{-1}(r)` ([`super::kappa_from_mean_cosine`]).
    MaximumLikelihood,
}

/// Options of the EM ([`fit_em`], [`fit_em_nested`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmOptions {
    /// Iterations of one EM run (to convergence).
    pub max_iterations: usize,
    /// Stop when the mean weighted log-likelihood `l` (nats per unit weight) gains less.
    pub tolerance: f64,
    /// Upper bound of the concentrations (module docs).
    pub kappa_max: f32,
    /// EM iterations spent on each split candidate before the best one is continued.
    pub split_trial_iterations: usize,
}

impl Default for EmOptions {
    fn default() -> Self {
        EmOptions {
            max_iterations: 300,
            tolerance: 1e-8,
            kappa_max: KAPPA_MAX,
            split_trial_iterations: 8,
        }
    }
}

/// Result of an EM fit.
#[derive(Clone, Debug, PartialEq)]
pub struct EmFit {
    /// The lobes (as many as requested; dead ones have zero amplitude). Their amplitudes sum
    /// to the samples' total weight.
    pub lobes: Vec<VmfLobe>,
    /// Mean weighted log-likelihood `sum_i s_i ln p(x_i) / sum_i s_i` of the fitted mixture
    /// (of its f64 parameters, before rounding to the f32 lobes).
    pub log_likelihood: f64,
    /// EM iterations spent on this fit (split trials included; 0 for a fallback).
    pub iterations: usize,
    /// Whether the final run met the tolerance (false: stopped at `max_iterations`).
    pub converged: bool,
}

/// The usable samples in f64: unit directions, shape weights, RGB weights.
struct Data {
    x: Vec<[f64; 3]>,
    s: Vec<f64>,
    rgb: Vec<[f64; 3]>,
    total: f64,
}

impl Data {
    fn new(samples: &[WeightedDir]) -> Option<Data> {
        let clean = |c: f32| {
            if c.is_finite() && c > 0.0 {
                c as f64
            } else {
                0.0
            }
        };
        let mut d = Data {
            x: vec![],
            s: vec![],
            rgb: vec![],
            total: 0.0,
        };
        for p in samples {
            let w = [clean(p.weight.x), clean(p.weight.y), clean(p.weight.z)];
            let s = w[0] + w[1] + w[2];
            let x = unit64(p.dir);
            let unit = x.iter().all(|c| c.is_finite()) && x != [0.0; 3];
            if s > 0.0 && s.is_finite() && unit {
                d.x.push(x);
                d.s.push(s);
                d.rgb.push(w);
                d.total += s;
            }
        }
        (d.total > 0.0 && d.total.is_finite()).then_some(d)
    }

    fn len(&self) -> usize {
        self.x.len()
    }
}

/// One mixture component in f64: axis, concentration, `ln pi` (`-inf` when dead), `h(kappa)`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Comp {
    mu: [f64; 3],
    kappa: f64,
    log_pi: f64,
}

impl Comp {
    fn log_density(&self, h_kappa: f64, x: [f64; 3]) -> f64 {
        self.log_pi + h_kappa - self.kappa * one_minus_dot(self.mu, x) - LN_2PI
    }
}

/// E-step: responsibilities into `resp` (`n x k`, row-major) and the mean weighted
/// log-likelihood.
fn e_step(data: &Data, comps: &[Comp], resp: &mut Vec<f64>) -> f64 {
    let k = comps.len();
    resp.resize(data.len() * k, 0.0);
    let hs: Vec<f64> = comps.iter().map(|c| h(c.kappa)).collect();
    let mut ll = 0.0;
    for (i, &x) in data.x.iter().enumerate() {
        let row = &mut resp[i * k..(i + 1) * k];
        let mut m = f64::NEG_INFINITY;
        for (j, c) in comps.iter().enumerate() {
            row[j] = c.log_density(hs[j], x);
            m = m.max(row[j]);
        }
        // At least one component is alive (the weights sum to 1), so m is finite.
        let sum: f64 = row.iter().map(|l| (l - m).exp()).sum();
        let lse = m + sum.ln();
        for r in row.iter_mut() {
            *r = (*r - lse).exp();
        }
        ll += data.s[i] * lse;
    }
    ll / data.total
}

/// Tangent frame `(e1, e2)` of a unit f64 axis (any right-handed one).
fn tangent_frame(mu: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let a = if mu[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let d = dot(a, mu);
    let e1 = normalize([a[0] - d * mu[0], a[1] - d * mu[1], a[2] - d * mu[2]]);
    let e2 = [
        mu[1] * e1[2] - mu[2] * e1[1],
        mu[2] * e1[0] - mu[0] * e1[2],
        mu[0] * e1[1] - mu[1] * e1[0],
    ];
    (e1, e2)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// The maximum-likelihood (or Banerjee) lobe shape of samples weighted by `s_i q_i`, where
/// `q_i` is column `j` of `resp` (or 1): `(mu, kappa, W)`, `None` when `W = 0`.
fn weighted_shape(
    data: &Data,
    col: Option<(&[f64], usize, usize)>,
    estimate: KappaEstimate,
    kappa_max: f64,
) -> Option<([f64; 3], f64, f64)> {
    let q = |i: usize| col.map_or(1.0, |(r, k, j)| r[i * k + j]);
    let (mut n, mut w) = ([0.0f64; 3], 0.0);
    for (i, x) in data.x.iter().enumerate() {
        let sw = data.s[i] * q(i);
        w += sw;
        for c in 0..3 {
            n[c] += sw * x[c];
        }
    }
    if w.is_nan() || w <= 0.0 {
        return None;
    }
    let len = dot(n, n).sqrt();
    let mu = if len > 0.0 {
        [n[0] / len, n[1] / len, n[2] / len]
    } else {
        // No mean direction (e.g. opposite samples of equal weight): the heaviest sample's.
        let (mut best, mut bw) = (data.x[0], -1.0);
        for (i, x) in data.x.iter().enumerate() {
            if data.s[i] * q(i) > bw {
                bw = data.s[i] * q(i);
                best = *x;
            }
        }
        best
    };
    // 1 - r accumulated as the weighted mean of 1 - mu . x (exactly 1 - |n| / W for the mean
    // direction, without cancellation).
    let mut one_minus_r = 0.0;
    for (i, &x) in data.x.iter().enumerate() {
        one_minus_r += data.s[i] * q(i) * one_minus_dot(mu, x);
    }
    let one_minus_r = (one_minus_r / w).clamp(0.0, 1.0);
    let kappa = match estimate {
        KappaEstimate::Banerjee => kappa_banerjee(1.0 - one_minus_r, one_minus_r),
        KappaEstimate::MaximumLikelihood => kappa_from_one_minus_mean_cosine(one_minus_r),
    };
    Some((mu, kappa.clamp(0.0, kappa_max), w))
}

/// M-step (module docs).
fn m_step(data: &Data, resp: &[f64], comps: &mut [Comp], kappa_max: f64) {
    let k = comps.len();
    for (j, c) in comps.iter_mut().enumerate() {
        match weighted_shape(
            data,
            Some((resp, k, j)),
            KappaEstimate::MaximumLikelihood,
            kappa_max,
        ) {
            Some((mu, kappa, w)) => {
                c.mu = mu;
                c.kappa = kappa;
                c.log_pi = (w / data.total).ln();
            }
            None => c.log_pi = f64::NEG_INFINITY,
        }
    }
}

/// An EM run from `comps`: the best parameters seen, their log-likelihood, iterations spent,
/// and whether the tolerance was met.
fn run_em(
    data: &Data,
    mut comps: Vec<Comp>,
    iterations: usize,
    opts: &EmOptions,
    resp: &mut Vec<f64>,
) -> (Vec<Comp>, f64, usize, bool) {
    let kappa_max = opts.kappa_max as f64;
    let mut ll = e_step(data, &comps, resp);
    let mut best = (comps.clone(), ll);
    let (mut it, mut converged) = (0, false);
    while it < iterations {
        m_step(data, resp, &mut comps, kappa_max);
        let next = e_step(data, &comps, resp);
        it += 1;
        if next > best.1 {
            best = (comps.clone(), next);
        }
        if (next - ll).abs() <= opts.tolerance {
            converged = true;
            break;
        }
        ll = next;
    }
    (best.0, best.1, it, converged)
}

/// The f32 lobes of components, with amplitudes `sum_i r_ij w_i` from their responsibilities.
fn to_fit(data: &Data, comps: &[Comp], iterations: usize, converged: bool) -> EmFit {
    let mut resp = vec![];
    let ll = e_step(data, comps, &mut resp);
    let k = comps.len();
    let lobes = comps
        .iter()
        .enumerate()
        .map(|(j, c)| {
            let mut a = [0.0f64; 3];
            for (i, w) in data.rgb.iter().enumerate() {
                for ch in 0..3 {
                    a[ch] += resp[i * k + j] * w[ch];
                }
            }
            VmfLobe {
                axis: Vec3::new(c.mu[0] as f32, c.mu[1] as f32, c.mu[2] as f32).normalize(),
                kappa: c.kappa as f32,
                amplitude: Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32),
            }
        })
        .collect();
    EmFit {
        lobes,
        log_likelihood: ll,
        iterations,
        converged,
    }
}

/// The closed-form one-lobe estimate of the paper (eq. 13-15, module docs): `None` when no
/// sample has a positive weight (a slice with no escaping samples).
///
/// # Panics
/// Debug builds assert `kappa_max > 0`.
pub fn estimate_one_lobe(
    samples: &[WeightedDir],
    estimate: KappaEstimate,
    kappa_max: f32,
) -> Option<VmfLobe> {
    debug_assert!(kappa_max > 0.0);
    let data = Data::new(samples)?;
    let (mu, kappa, _) = weighted_shape(&data, None, estimate, kappa_max as f64)?;
    let mut a = [0.0f64; 3];
    for w in &data.rgb {
        for c in 0..3 {
            a[c] += w[c];
        }
    }
    Some(VmfLobe {
        axis: Vec3::new(mu[0] as f32, mu[1] as f32, mu[2] as f32).normalize(),
        kappa: kappa as f32,
        amplitude: Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32),
    })
}

/// Mean weighted log-likelihood `sum_i s_i ln p(x_i) / sum_i s_i` of `samples` under the
/// mixture of `lobes` normalised to a density (mixture weights proportional to the channel
/// sums of the amplitudes). `None` when no sample has weight or no lobe has amplitude.
pub fn log_likelihood(samples: &[WeightedDir], lobes: &[VmfLobe]) -> Option<f64> {
    let data = Data::new(samples)?;
    let amp = |l: &VmfLobe| (l.amplitude.x + l.amplitude.y + l.amplitude.z).max(0.0) as f64;
    let total: f64 = lobes.iter().map(amp).sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let comps: Vec<Comp> = lobes
        .iter()
        .map(|l| Comp {
            mu: unit64(l.axis),
            kappa: l.kappa as f64,
            log_pi: (amp(l) / total).ln(),
        })
        .collect();
    Some(e_step(&data, &comps, &mut vec![]))
}

/// Splits component `j` of `comps` (module docs) given the responsibilities `resp` of `comps`.
fn split(data: &Data, comps: &[Comp], resp: &[f64], j: usize, kappa_max: f64) -> Vec<Comp> {
    let k = comps.len();
    let c = comps[j];
    let (e1, e2) = tangent_frame(c.mu);
    // Weighted tangent-plane scatter of the class.
    let (mut a, mut b, mut d, mut w) = (0.0, 0.0, 0.0, 0.0);
    let mut far = (0.0, c.mu);
    for (i, &x) in data.x.iter().enumerate() {
        let q = data.s[i] * resp[i * k + j];
        let (t1, t2) = (dot(x, e1), dot(x, e2));
        a += q * t1 * t1;
        b += q * t1 * t2;
        d += q * t2 * t2;
        w += q;
        let f = q * one_minus_dot(c.mu, x);
        if f > far.0 {
            far = (f, x);
        }
    }
    let (a, b, d) = if w > 0.0 {
        (a / w, b / w, d / w)
    } else {
        (0.0, 0.0, 0.0)
    };
    // Largest eigenvalue and its eigenvector of [[a, b], [b, d]].
    let lambda = 0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (v1, v2) = if (lambda - d).abs() + b.abs() > (lambda - a).abs() + b.abs() {
        (lambda - d, b)
    } else {
        (b, lambda - a)
    };
    let vn = (v1 * v1 + v2 * v2).sqrt();
    let sigma = lambda.max(0.0).sqrt();
    let child = |mu: [f64; 3]| Comp {
        mu,
        kappa: (2.0 * c.kappa).max(2.0).min(kappa_max),
        log_pi: c.log_pi - std::f64::consts::LN_2,
    };
    let (m1, m2) = if sigma > 1e-12 && vn > 0.0 {
        let e = [
            (v1 * e1[0] + v2 * e2[0]) / vn,
            (v1 * e1[1] + v2 * e2[1]) / vn,
            (v1 * e1[2] + v2 * e2[2]) / vn,
        ];
        let p = |sg: f64| {
            normalize([
                c.mu[0] + sg * e[0],
                c.mu[1] + sg * e[1],
                c.mu[2] + sg * e[2],
            ])
        };
        (p(sigma), p(-sigma))
    } else {
        (c.mu, far.1)
    };
    let mut out = comps.to_vec();
    out[j] = child(m1);
    out.push(child(m2));
    out
}

/// EM fits of 1, 2, ..., `max_lobes` lobes, each started from the previous one (module docs):
/// `fits[k - 1]` has `k` lobes and `fits[k].log_likelihood >= fits[k - 1].log_likelihood`.
/// Empty when no sample has a positive weight or `max_lobes` is 0.
pub fn fit_em_nested(samples: &[WeightedDir], max_lobes: usize, opts: &EmOptions) -> Vec<EmFit> {
    debug_assert!(opts.kappa_max > 0.0);
    let Some(data) = Data::new(samples) else {
        return vec![];
    };
    let mut fits = Vec::with_capacity(max_lobes);
    if max_lobes == 0 {
        return fits;
    }
    let kappa_max = opts.kappa_max as f64;
    let mut resp = vec![];
    let Some((mu, kappa, _)) =
        weighted_shape(&data, None, KappaEstimate::MaximumLikelihood, kappa_max)
    else {
        return fits;
    };
    let first = vec![Comp {
        mu,
        kappa,
        log_pi: 0.0,
    }];
    let (mut comps, mut ll, it, conv) = run_em(&data, first, opts.max_iterations, opts, &mut resp);
    fits.push(to_fit(&data, &comps, it, conv));
    for _ in 1..max_lobes {
        e_step(&data, &comps, &mut resp);
        // Try splitting every live lobe for a few iterations; continue the best.
        let mut best: Option<(Vec<Comp>, f64)> = None;
        let mut trials = 0;
        for j in 0..comps.len() {
            if comps[j].log_pi == f64::NEG_INFINITY {
                continue;
            }
            let start = split(&data, &comps, &resp, j, kappa_max);
            let mut r = vec![];
            let (c, l, it, _) = run_em(&data, start, opts.split_trial_iterations, opts, &mut r);
            trials += it;
            if best.as_ref().is_none_or(|b| l > b.1) {
                best = Some((c, l));
            }
        }
        let (next, next_ll, it, conv) = match best {
            Some((start, _)) => run_em(&data, start, opts.max_iterations, opts, &mut resp),
            None => (comps.clone(), f64::NEG_INFINITY, 0, true),
        };
        let it = it + trials;
        if next_ll >= ll {
            comps = next;
            ll = next_ll;
            fits.push(to_fit(&data, &comps, it, conv));
        } else {
            // The split ended lower: keep the previous lobes and add a dead copy.
            let mut dead = comps[0];
            dead.log_pi = f64::NEG_INFINITY;
            comps.push(dead);
            fits.push(to_fit(&data, &comps, 0, true));
        }
    }
    fits
}

/// EM fit of `n_lobes` lobes: the last of [`fit_em_nested`]. `None` when no sample has a
/// positive weight or `n_lobes` is 0.
pub fn fit_em(samples: &[WeightedDir], n_lobes: usize, opts: &EmOptions) -> Option<EmFit> {
    fit_em_nested(samples, n_lobes, opts).pop()
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod vs_lm;
