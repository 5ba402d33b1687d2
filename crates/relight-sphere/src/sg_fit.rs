//! Fitting `N` isotropic spherical Gaussians ([`SgLobe`]) to a tabulated spherical function:
//! the data term of Green 2005 (thesis eq. 2.3 / 3.1) minimised by a bounded
//! Levenberg-Marquardt with analytic Jacobians, greedy initialisation, optional coherence
//! priors (eq. 2.4, 2.5) and skipping of empty texels (the idea of Algorithm 2, section 3.1).
//!
//! # Objective
//! With texel directions `w_i`, quadrature weights `dA_i` (exact solid angles of the map,
//! so the sum approximates the continuous L2 norm; Green sums texels unweighted) and data `T_i`:
//!
//! ```text
//! E = sum_i dA_i sum_rgb (sum_k a_k exp(lambda_k (mu_k . w_i - 1)) - T_i)^2         (data, eq. 3.1)
//!   + w_mean  sum_k |mu_k - mu'_k|^2                                                 (eq. 2.4)
//!   + w_width sum_k (ln lambda_k - ln lambda'_k)^2                                   (eq. 2.5)
//!   + delta sum_s sum_{k1<k2} max(-<mu_k1 - mu_k2, mu^s_k1 - mu^s_k2>, 0)^3           (eq. 2.6)
//!   + w_E sum_rgb (sum_k a_k I(lambda_k) - E)^2                                       (energy)
//! ```
//! where `mu'_k, lambda'_k` are the lobes of an optional prior (e.g. the already fitted
//! neighbour of a flood fill, or the average of neighbouring views). Green aligns the width
//! `sigma`; since `ln lambda = -2 ln sigma` the log-sharpness alignment is the same term on a
//! relative scale, which is what makes it meaningful for both sharp and broad lobes.
//!
//! The last line is Green's spatial *arrangement* term (optional, [`Arrangement`]): for every
//! already fitted neighbouring vertex `s` (its lobes `mu^s` for the same view) and pair of
//! lobes, it penalises a difference vector `mu_k1 - mu_k2` pointing against the neighbour's,
//! i.e. a swapped ("flipped") pair. It enters the least squares as the residual
//! `sqrt(delta) m^(3/2)`, `m = max(-<mu_k1 - mu_k2, d_s>, 0)`, which is C1 (its derivative
//! `1.5 sqrt(delta) m^(1/2) dm/dp` vanishes where the term switches on), with
//! `dm/dalpha_k1 = -<s_k1, d_s>`, `dm/dalpha_k2 = <s_k2, d_s>` (same with `t` for `beta`).
//!
//! The last line is our addition ([`EnergyTarget`], optional): it holds the mixture's
//! integral `sum_k a_k I(lambda_k)`, `I(lambda) = 2 pi (1 - exp(-2 lambda)) / lambda`, near
//! the data's `E = sum_i dA_i T_i`, so that the fitted shape is the best one *of the right
//! energy* rather than the least-squares one rescaled afterwards (a least-squares Gaussian
//! misses a GGX lobe's long tails; rescaling it puts their energy into its core). Its rows
//! are `sqrt(w_E) (sum_k a_kc I_k - E_c)` with `d/da_kc = sqrt(w_E) I_k` and
//! `d/d ln lambda_k = sqrt(w_E) a_kc lambda_k I'(lambda_k)`,
//! `lambda I'(lambda) = 4 pi exp(-2 lambda) - I(lambda)`.
//!
//! # Parameters and bounds (6 per lobe)
//! RGB amplitude `a >= 0`; axis `mu` moved in its tangent plane,
//! `mu <- normalize(mu + alpha s + beta t)` with `(s, t)` the tangent frame of
//! [`crate::warp::Frame`] (same construction, in f64) re-built after every accepted step (so
//! the Jacobian is always taken at `alpha = beta = 0`, no pole singularity); log
//! sharpness `ln lambda` in `[ln lambda_min, ln lambda_max]`. Bounds are handled by
//! projection: parameters at a bound whose gradient points outward are frozen for the step,
//! the others are clamped after it (a projected Levenberg-Marquardt).
//!
//! # Solver
//! Levenberg (1944, "A method for the solution of certain non-linear problems in least
//! squares"), Marquardt (1963, "An algorithm for least-squares estimation of nonlinear
//! parameters") with Marquardt's diagonal scaling `(J^T J + mu diag(J^T J)) d = -J^T r`, the
//! damping update of Nocedal & Wright (2006, "Numerical Optimization", section 10.3), f64
//! normal equations solved by Cholesky. Analytic Jacobian of the residual
//! `r_ic = sqrt(dA_i) (F_c(w_i) - T_ic)`, with `g_k = exp(lambda_k (mu_k . w_i - 1))`:
//! `dr/da_kc = sqrt(dA_i) g_k`, `dr/dalpha_k = sqrt(dA_i) a_kc g_k lambda_k (s_k . w_i)`
//! (same with `t_k` for `beta`), `dr/d ln lambda_k = sqrt(dA_i) a_kc g_k lambda_k (mu_k . w_i - 1)`.
//!
//! # Initialisation (greedy)
//! Lobes are added one at a time: the new axis is the texel with the largest positive residual
//! (channel sum), the sharpness comes from the second moment `m = E[1 - mu . w]` of the residual
//! over the texels above 5 % of that peak (for an SG truncated at `exp(-3)` this is
//! `0.842 / lambda`); among sharpnesses `2^(j/2)` times that estimate (`j = -2..8`) the one
//! whose non-negative least-squares amplitude removes the most residual energy is kept (a
//! small matching pursuit: the moment alone is too wide when the residual has several bumps).
//! Then all lobes so far are refined jointly. The new lobe starts with a non-negative gain and
//! the solver accepts only decreasing steps, so the error is non-increasing in `N`.
//!
//! # Skipping empty texels
//! A texel whose data is exactly zero (e.g. masked by visibility: Green's `S_0`) and where every
//! unit lobe is below `zero_epsilon` contributes less than `(zero_epsilon sum_k |a_k|)^2 dA_i`
//! to `E` and about as little to the gradient, so it is skipped when evaluating the cost and the
//! normal equations (the spirit of Algorithm 2: spend work only where data or model live).

// Index loops over RGB channels and lobes mirror the formulas above.
#![allow(clippy::needless_range_loop)]

mod lm;
mod moments;
pub use moments::match_moments;

use crate::envmap::EnvMap;
use crate::sg::SgLobe;
use crate::sg_kernel::LobeKernel;
use crate::Vec3;
use lm::{dot, finish, levenberg_marquardt, objective, unit64, Arr64, Lobe64};

/// A spherical function tabulated at quadrature points (directions, weights, RGB values).
#[derive(Clone, Debug)]
pub struct FitTarget {
    dirs: Vec<[f64; 3]>,
    sqrt_w: Vec<f64>,
    values: Vec<[f64; 3]>,
    weights: Vec<f64>,
}

impl FitTarget {
    /// A target from unit directions, quadrature weights (steradians) and values.
    ///
    /// # Panics
    /// Panics if the slices differ in length; debug builds assert non-negative weights.
    pub fn new(dirs: &[Vec3], weights: &[f32], values: &[Vec3]) -> FitTarget {
        assert!(dirs.len() == weights.len() && dirs.len() == values.len());
        debug_assert!(weights.iter().all(|&w| w >= 0.0));
        let f = |v: Vec3| [v.x as f64, v.y as f64, v.z as f64];
        FitTarget {
            dirs: dirs.iter().map(|&d| f(d)).collect(),
            sqrt_w: weights.iter().map(|&w| (w as f64).sqrt()).collect(),
            weights: weights.iter().map(|&w| w as f64).collect(),
            values: values.iter().map(|&v| f(v)).collect(),
        }
    }

    /// The texels of an environment map (any layout) with their exact quadrature weights.
    pub fn from_env(map: &EnvMap) -> FitTarget {
        let (mut d, mut w, mut v) = (vec![], vec![], vec![]);
        for t in map.texel_iter() {
            d.push(t.dir);
            w.push(t.solid_angle);
            v.push(t.value);
        }
        FitTarget::new(&d, &w, &v)
    }

    /// Replaces every direction `d` by `f(d)` (a unit vector), keeping weights and values:
    /// the same L2 objective over the original directions, with the model evaluated at the
    /// mapped ones (lobes in the half-vector domain, [`crate::half_vector`]).
    pub fn map_dirs(&mut self, f: impl Fn(Vec3) -> Vec3) {
        for d in &mut self.dirs {
            let m = f(Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32)).normalize();
            *d = [m.x as f64, m.y as f64, m.z as f64];
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.dirs.len()
    }

    /// The same samples with `lobes` (evaluated with `opts.kernel`) subtracted from the
    /// values: the target of a lobe fitted to what `lobes` leave (signed).
    pub fn residual(&self, lobes: &[SgLobe], opts: &FitOptions) -> FitTarget {
        let l: Vec<Lobe64> = lobes.iter().map(Lobe64::from_lobe).collect();
        let mut model = vec![[0.0f64; 3]; self.len()];
        model_of(self, &l, &mut model, opts);
        let mut r = self.clone();
        for (v, m) in r.values.iter_mut().zip(&model) {
            for c in 0..3 {
                v[c] -= m[c];
            }
        }
        r
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.dirs.is_empty()
    }

    /// `sum_i dA_i |T_i|^2`, the squared L2 norm of the data.
    pub fn norm2(&self) -> f64 {
        self.values
            .iter()
            .zip(&self.weights)
            .map(|(v, w)| w * dot(*v, *v))
            .sum()
    }
}

/// Weights of the coherence terms against a prior (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PriorWeights {
    /// `w_mean` of the mean alignment `|mu_k - mu'_k|^2` (Green eq. 2.4).
    pub mean: f64,
    /// `w_width` of the width alignment `(ln lambda_k - ln lambda'_k)^2` (Green eq. 2.5).
    pub width: f64,
}

/// Green's spatial arrangement term (eq. 2.6, module docs) against already fitted
/// neighbouring vertices.
#[derive(Clone, Copy, Debug)]
pub struct Arrangement<'a> {
    /// Weight `delta`.
    pub weight: f64,
    /// The neighbours' lobes for the same view, `n` consecutive lobes per neighbour in the
    /// order of the lobes being fitted.
    pub neighbours: &'a [SgLobe],
}

/// Options of [`fit`] and [`refine`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Lower bound of the sharpness.
    pub lambda_min: f32,
    /// Upper bound of the sharpness. Keep it below about `(n / 2)^2` for an `n x n`-per-face
    /// cube map (`sigma` of at least one texel): sharper lobes can fit single texels, a
    /// degenerate optimum.
    pub lambda_max: f32,
    /// Maximum number of Levenberg-Marquardt iterations per refinement.
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the objective by less than this fraction.
    pub tolerance: f64,
    /// Unit-lobe level below which zero-data texels are skipped (0 disables skipping).
    pub zero_epsilon: f64,
    /// Weights of the prior terms (used only when a prior is passed).
    pub prior_weights: PriorWeights,
    /// The energy term (module docs), if any.
    pub energy: Option<EnergyTarget>,
    /// The lobes' radial shape ([`crate::sg_kernel`]): the model is `sum_k a_k K(1 - mu_k .
    /// w; lambda_k)`, the Gaussian of the formulas above by default.
    pub kernel: LobeKernel,
}

/// The energy term `w_E sum_c (sum_k a_kc I(lambda_k) - E_c)^2` (module docs): the mixture's
/// integral held near the data's while the shape is fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnergyTarget {
    /// Weight `w_E`.
    pub weight: f64,
    /// The data's integral per channel, `E_c = sum_i dA_i T_ic`.
    pub integral: [f64; 3],
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            lambda_min: 0.05,
            lambda_max: 1.0e4,
            max_iterations: 100,
            tolerance: 1e-6,
            zero_epsilon: 1e-5,
            prior_weights: PriorWeights {
                mean: 0.0,
                width: 0.0,
            },
            energy: None,
            kernel: LobeKernel::Gaussian,
        }
    }
}

/// Result of a fit.
#[derive(Clone, Debug)]
pub struct SgFit {
    /// The fitted lobes (same count as requested; unused lobes have zero amplitude).
    pub lobes: Vec<SgLobe>,
    /// Final objective `E` (data plus prior terms).
    pub cost: f64,
    /// Relative L2 error of the data term, `sqrt(data term / sum dA |T|^2)` (0 for zero data).
    pub relative_error: f64,
    /// Levenberg-Marquardt iterations spent (all refinements).
    pub iterations: usize,
}

/// Objective `E` of `lobes` (data term plus the prior terms when `prior` is given).
///
/// # Panics
/// Debug builds assert that a prior has as many lobes as `lobes`.
pub fn objective_of(
    target: &FitTarget,
    lobes: &[SgLobe],
    opts: &FitOptions,
    prior: Option<&[SgLobe]>,
) -> f64 {
    let l: Vec<_> = lobes.iter().map(Lobe64::from_lobe).collect();
    let p: Option<Vec<_>> = prior.map(|p| p.iter().map(Lobe64::from_lobe).collect());
    debug_assert!(p.as_ref().is_none_or(|p| p.len() == l.len()));
    objective(target, &l, opts, p.as_deref(), None)
}

/// Refines `initial` lobes by bounded Levenberg-Marquardt (no greedy initialisation).
///
/// # Panics
/// Debug builds assert `lambda_min <= sharpness <= lambda_max`, unit axes, and a prior (if
/// any) with as many lobes as `initial`.
pub fn refine(
    target: &FitTarget,
    initial: &[SgLobe],
    opts: &FitOptions,
    prior: Option<&[SgLobe]>,
) -> SgFit {
    refine_arranged(target, initial, opts, prior, None)
}

/// [`refine`] with Green's spatial arrangement term (eq. 2.6) against the lobes of already
/// fitted neighbouring vertices (module docs). The returned `cost` includes the term.
///
/// # Panics
/// As [`refine`]; debug builds also assert `arrangement.neighbours.len()` is a multiple of
/// the lobe count.
pub fn refine_arranged(
    target: &FitTarget,
    initial: &[SgLobe],
    opts: &FitOptions,
    prior: Option<&[SgLobe]>,
    arrangement: Option<&Arrangement>,
) -> SgFit {
    debug_assert!(initial
        .iter()
        .all(|g| g.sharpness >= opts.lambda_min * 0.999
            && g.sharpness <= opts.lambda_max * 1.001
            && (g.axis.length() - 1.0).abs() < 1e-3));
    let l: Vec<_> = initial.iter().map(Lobe64::from_lobe).collect();
    let p: Option<Vec<_>> = prior.map(|p| p.iter().map(Lobe64::from_lobe).collect());
    debug_assert!(p.as_ref().is_none_or(|p| p.len() == l.len()));
    let a = arrangement.and_then(|a| Arr64::new(a, l.len()));
    let (l, c, it) = levenberg_marquardt(target, l, opts, p.as_deref(), a.as_ref());
    finish(target, l, c, it, opts)
}

/// Fits `n` lobes (1..=10) to `target`. With a `prior` (the flood-fill case) the prior lobes
/// are both the starting point and the reference of the coherence terms (weights in
/// `opts.prior_weights`); without one the lobes are added greedily (module docs) and refined
/// jointly after each addition.
///
/// # Panics
/// Debug builds assert `1 <= n <= 10`, `0 < lambda_min < lambda_max` and a prior of `n` lobes.
pub fn fit(target: &FitTarget, n: usize, opts: &FitOptions, prior: Option<&[SgLobe]>) -> SgFit {
    debug_assert!((1..=10).contains(&n));
    debug_assert!(opts.lambda_min > 0.0 && opts.lambda_min < opts.lambda_max);
    debug_assert!(prior.is_none_or(|p| p.len() == n));
    let p: Option<Vec<Lobe64>> = prior.map(|p| p.iter().map(Lobe64::from_lobe).collect());
    if let Some(p) = &p {
        let (l, c, it) = levenberg_marquardt(target, p.clone(), opts, Some(p), None);
        return finish(target, l, c, it, opts);
    }
    let mut lobes: Vec<Lobe64> = Vec::with_capacity(n);
    let (mut cost, mut iterations) = (0.0, 0);
    let mut model = vec![[0.0f64; 3]; target.len()];
    for _ in 0..n {
        lobes.push(residual_lobe64(target, &model, opts));
        let (l2, c, it) = levenberg_marquardt(target, lobes, opts, None, None);
        lobes = l2;
        cost = c;
        iterations += it;
        model_of(target, &lobes, &mut model, opts);
    }
    finish(target, lobes, cost, iterations, opts)
}

#[cfg(test)]
mod tests;

/// The mixture of `lobes` at every sample of `target`, into `model`.
fn model_of(target: &FitTarget, lobes: &[Lobe64], model: &mut [[f64; 3]], opts: &FitOptions) {
    for (i, m) in model.iter_mut().enumerate() {
        *m = [0.0; 3];
        for l in lobes {
            let g = unit64(opts.kernel, l.log_l.exp(), dot(l.mu, target.dirs[i]));
            for c in 0..3 {
                m[c] += l.a[c] * g;
            }
        }
    }
}

/// The greedy step (module docs): a new lobe on the residual `target - model`, at the
/// texel of the largest positive residual (channel sum), with the sharpness among
/// `2^(j/2)` times the second-moment estimate whose non-negative least-squares amplitude
/// removes the most residual energy. A zero-amplitude lobe if nothing is left.
fn residual_lobe64(target: &FitTarget, model: &[[f64; 3]], opts: &FitOptions) -> Lobe64 {
    let (lo, hi) = (opts.lambda_min as f64, opts.lambda_max as f64);
    // Residual (channel sum) and its peak.
    let res: Vec<f64> = (0..target.len())
        .map(|i| (0..3).map(|c| target.values[i][c] - model[i][c]).sum())
        .collect();
    let (peak_i, peak) = res
        .iter()
        .enumerate()
        .fold((0, 0.0), |b, (i, &r)| if r > b.1 { (i, r) } else { b });
    let mut l = Lobe64::from_lobe(&SgLobe::new(Vec3::Y, 1.0, Vec3::ZERO));
    if peak <= 0.0 {
        return l;
    }
    let mu = target.dirs[peak_i];
    // Truncated second moment of the residual about the peak -> sharpness.
    let (mut m1, mut m0) = (0.0, 0.0);
    for (i, &r) in res.iter().enumerate() {
        let c = dot(mu, target.dirs[i]);
        if r >= 0.05 * peak && c > 0.0 {
            m0 += target.weights[i] * r;
            m1 += target.weights[i] * r * (1.0 - c);
        }
    }
    let lambda = if m1 > 0.0 { 0.842 * m0 / m1 } else { hi };
    l.set_axis(mu);
    // Matching pursuit over a few sharpnesses around the moment estimate: keep the one
    // whose non-negative least-squares amplitude removes the most residual energy
    // (the moment alone overestimates the width when the residual has several bumps).
    let mut best = (0.0, lambda.clamp(lo, hi), [0.0; 3]);
    for j in -2..=8 {
        let lam = (lambda * 2f64.powf(0.5 * j as f64)).clamp(lo, hi);
        let (mut num, mut den) = ([0.0; 3], 0.0);
        for i in 0..target.len() {
            let g = unit64(opts.kernel, lam, dot(mu, target.dirs[i]));
            den += target.weights[i] * g * g;
            for c in 0..3 {
                num[c] += target.weights[i] * g * (target.values[i][c] - model[i][c]);
            }
        }
        if den <= 0.0 {
            continue;
        }
        let a = num.map(|x| (x / den).max(0.0));
        let gain: f64 = (0..3).map(|c| a[c] * a[c] * den).sum();
        if gain > best.0 {
            best = (gain, lam, a);
        }
    }
    l.log_l = best.1.ln();
    l.a = best.2;
    l
}

/// The lobe the greedy initialisation would add to `lobes` (module docs): on the residual of
/// their mixture, at its largest positive texel. A zero-amplitude lobe if the mixture already
/// covers the data everywhere. The first step of a nested fit, where `N` lobes start from the
/// `N - 1` of a previous fit.
///
/// # Panics
/// Debug builds assert `0 < lambda_min < lambda_max`.
pub fn residual_lobe(target: &FitTarget, lobes: &[SgLobe], opts: &FitOptions) -> SgLobe {
    debug_assert!(opts.lambda_min > 0.0 && opts.lambda_min < opts.lambda_max);
    let l: Vec<Lobe64> = lobes.iter().map(Lobe64::from_lobe).collect();
    let mut model = vec![[0.0f64; 3]; target.len()];
    model_of(target, &l, &mut model, opts);
    residual_lobe64(target, &model, opts).to_lobe()
}
