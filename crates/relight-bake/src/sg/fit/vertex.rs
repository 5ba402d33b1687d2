//! The fit of all views of one vertex (thesis section 2.2.2, eq. 2.2-2.6): two Gauss-Seidel
//! sweeps over the views in breadth-first order on the view icosahedron, each view refined
//! against its data (eq. 2.3), the average of its neighbouring views (eq. 2.4, 2.5) and the
//! arrangement of the already processed neighbouring vertices (eq. 2.6).

use super::target::{group, CubeTables, ViewTarget};
use crate::sg::SgFitSettings;
use glam::Vec3;
use relight_sphere::icosphere::Icosphere;
use relight_sphere::sg::SgLobe;
use relight_sphere::sg_fit::{self, Arrangement, EnergyTarget, FitOptions, PriorWeights};
use relight_sphere::sg_kernel::LobeKernel;

use crate::sg::{FitStart, LobeOrder, LobeShape, SgDomain};
use relight_sphere::half_vector;

/// A warm start whose fit leaves more than this relative L2 error is checked against a greedy
/// fit from scratch (the warm start may sit in another basin, e.g. across a shadow boundary).
const RETRY_ERROR: f64 = 0.8;

/// Weight of `(ln lambda - ln lambda')^2` against `|mu - mu'|^2` in the lobe distance used to
/// match lobes ([`lobe_distance`]).
const WIDTH_MATCH: f32 = 0.1;

/// Everything the fit of one component needs that does not change between vertices.
#[derive(Clone, Debug)]
pub struct ComponentFit {
    /// Texel tables of the component's cube map.
    pub tables: CubeTables,
    /// Lobes per view.
    pub lobes: usize,
    /// Solver options (sharpness bounds from the resolution, iterations from the settings).
    pub opts: FitOptions,
    /// The fit weights.
    pub settings: SgFitSettings,
    /// Neighbouring views of each view (the frequency-3 icosahedron).
    pub view_neighbours: Vec<Vec<usize>>,
    /// The views' directions (the icosahedron's vertices): the half-vector domain's views
    /// where a source does not say which direction its data holds.
    pub view_dirs: Vec<Vec3>,
}

impl ComponentFit {
    /// The fit of a component on an `n x n`-per-face cube map with `lobes` lobes per view.
    ///
    /// The sharpness is bounded by `(n / 2)^2`, the finest lobe the cube map resolves (a
    /// standard deviation of about one texel, `sg_fit::FitOptions::lambda_max`); four times
    /// that in the half-vector domain, where a lobe of sharpness `lambda` is about
    /// `lambda / 4` wide in `w` (`w` turns twice as fast as `h`).
    pub fn new(n: usize, lobes: usize, settings: &SgFitSettings, views: &Icosphere) -> Self {
        debug_assert!(n >= 1 && (1..=10).contains(&lobes));
        let domain_scale = match settings.lobe_domain {
            SgDomain::Light => 1.0,
            SgDomain::HalfVector => 4.0,
        };
        let lambda_max = ((n as f32 / 2.0).powi(2)).max(1.0) * domain_scale;
        ComponentFit {
            tables: CubeTables::new(n),
            lobes,
            opts: FitOptions {
                lambda_min: 0.05f32.min(0.5 * lambda_max),
                lambda_max,
                max_iterations: settings.max_iterations,
                tolerance: 1e-3,
                kernel: settings.lobe_kernel.kernel(),
                ..FitOptions::default()
            },
            settings: *settings,
            view_neighbours: (0..views.vertices().len())
                .map(|v| views.neighbours(v).iter().map(|&u| u as usize).collect())
                .collect(),
            view_dirs: views.vertices().to_vec(),
        }
    }

    /// Groups one view's data ([`group`]) and, in the half-vector domain, moves it to the
    /// half vectors of `view` (the direction the data was computed for).
    pub fn view_target(&self, data: &[Vec3], view: Vec3) -> ViewTarget {
        let mut t = group(&self.tables, data);
        if self.settings.lobe_domain == SgDomain::HalfVector {
            t.to_half_vector(view);
        }
        t
    }

    /// Number of views.
    pub fn views(&self) -> usize {
        self.view_neighbours.len()
    }

    /// Default lobes of a vertex without data and without neighbours: zero amplitude, the
    /// broadest sharpness, axis +Y.
    fn default_lobe(&self) -> SgLobe {
        SgLobe::new(Vec3::Y, self.opts.lambda_min, Vec3::ZERO)
    }
}

/// The result of fitting one vertex: `views * lobes` lobes (view-major) and error statistics.
#[derive(Clone, Debug, Default)]
pub struct VertexFit {
    /// Lobes, `lobes[v * n + k]`.
    pub lobes: Vec<SgLobe>,
    /// Relative L2 error per view (negative: no data, or not refitted in a relaxation).
    pub errors: Vec<f64>,
    /// Levenberg-Marquardt iterations spent.
    pub iterations: u64,
}

/// Distance of two lobes for matching: `|mu - mu'|^2 + 0.1 (ln lambda - ln lambda')^2`.
pub fn lobe_distance(a: &SgLobe, b: &SgLobe) -> f32 {
    let dl = a.sharpness.ln() - b.sharpness.ln();
    (a.axis - b.axis).length_squared() + WIDTH_MATCH * dl * dl
}

/// The assignment `perm` minimising `sum_k cost[k * n + perm[k]]` (lobe `perm[k]` takes slot
/// `k`): brute force for `n <= 3` (the identity wins ties), greedy (slot by slot, the
/// cheapest free lobe) beyond.
pub fn best_assignment(cost: &[f32], n: usize) -> Vec<usize> {
    debug_assert_eq!(cost.len(), n * n);
    let total = |p: &[usize]| {
        p.iter()
            .enumerate()
            .map(|(k, &j)| cost[k * n + j])
            .sum::<f32>()
    };
    let perms: &[&[usize]] = match n {
        2 => &[&[0, 1], &[1, 0]],
        3 => &[
            &[0, 1, 2],
            &[0, 2, 1],
            &[1, 0, 2],
            &[1, 2, 0],
            &[2, 0, 1],
            &[2, 1, 0],
        ],
        _ => &[],
    };
    if n <= 1 {
        return (0..n).collect();
    }
    if !perms.is_empty() {
        let mut best = (total(perms[0]), perms[0]);
        for p in &perms[1..] {
            let c = total(p);
            if c < best.0 {
                best = (c, p);
            }
        }
        return best.1.to_vec();
    }
    let mut used = vec![false; n];
    (0..n)
        .map(|k| {
            let j = (0..n)
                .filter(|&j| !used[j])
                .min_by(|&a, &b| cost[k * n + a].total_cmp(&cost[k * n + b]))
                .unwrap_or(0);
            used[j] = true;
            j
        })
        .collect()
}

/// The permutation of `lobes` that best matches `reference` (slot `k` gets `lobes[perm[k]]`).
pub fn match_to(lobes: &[SgLobe], reference: &[SgLobe]) -> Vec<usize> {
    match_to_all(lobes, &[reference])
}

/// The permutation of `lobes` that best matches all `references` at once (summed distance).
pub fn match_to_all(lobes: &[SgLobe], references: &[&[SgLobe]]) -> Vec<usize> {
    let n = lobes.len();
    let cost: Vec<f32> = (0..n * n)
        .map(|i| {
            references
                .iter()
                .map(|r| lobe_distance(&lobes[i % n], &r[i / n]))
                .sum()
        })
        .collect();
    best_assignment(&cost, n)
}

fn permuted(lobes: &[SgLobe], perm: &[usize]) -> Vec<SgLobe> {
    perm.iter().map(|&j| lobes[j]).collect()
}

/// The average of several lobe sets (slot by slot): normalised mean axis, mean log
/// sharpness, mean amplitude. This is the prior of eq. 2.4 and 2.5 (module docs of
/// [`super`] on why the axis is normalised and the width averaged in log space).
pub fn average(sets: &[&[SgLobe]], n: usize) -> Vec<SgLobe> {
    debug_assert!(!sets.is_empty());
    (0..n)
        .map(|k| {
            let (mut axis, mut ll, mut amp) = (Vec3::ZERO, 0.0, Vec3::ZERO);
            for s in sets {
                axis += s[k].axis;
                ll += s[k].sharpness.ln();
                amp += s[k].amplitude;
            }
            let m = sets.len() as f32;
            SgLobe {
                axis: axis.try_normalize().unwrap_or(sets[0][k].axis),
                sharpness: (ll / m).exp(),
                amplitude: amp / m,
            }
        })
        .collect()
}

/// How a vertex is fitted.
pub struct VertexInput<'a> {
    /// The component's data, `views * 6 n^2` texels.
    pub data: &'a [Vec3],
    /// A warm start for every view (`views * lobes`): the lobes of the processed neighbour
    /// the vertex was reached from, or during relaxation the vertex's own lobes.
    pub warm: Option<&'a [SgLobe]>,
    /// The lobes (`views * lobes` each) of the neighbouring vertices of the spatial term.
    pub spatial: &'a [&'a [SgLobe]],
    /// The direction each view's data was computed for (the half-vector domain's views).
    pub views: &'a [Vec3],
    /// Relaxation: `warm` already holds a complete, matched fit; refit only the views whose
    /// bit is set in this mask (view `v` is bit `v`), in one sweep.
    pub relax: Option<u128>,
}

/// Fits every view of one vertex (module docs). Deterministic.
pub fn fit_vertex(c: &ComponentFit, input: &VertexInput) -> VertexFit {
    let (nv, n) = (c.views(), c.lobes);
    let texels = c.tables.texels();
    debug_assert_eq!(input.data.len(), nv * texels);
    debug_assert!(nv <= 128);
    let active = |v: usize| input.relax.is_none_or(|m| m >> v & 1 == 1);
    // Only the views being fitted are grouped (a relaxation refits few).
    let targets: Vec<Option<ViewTarget>> = (0..nv)
        .map(|v| {
            active(v)
                .then(|| c.view_target(&input.data[v * texels..(v + 1) * texels], input.views[v]))
        })
        .collect();
    let order: Vec<usize> = view_order(c, &targets)
        .into_iter()
        .filter(|&v| active(v))
        .collect();
    let mut out = VertexFit {
        lobes: vec![c.default_lobe(); nv * n],
        errors: vec![-1.0; nv],
        iterations: 0,
    };
    let mut assigned = vec![false; nv];
    let relax = input.relax.is_some();
    if relax {
        if let Some(w) = input.warm {
            out.lobes.copy_from_slice(w);
            assigned.fill(true);
        }
    }
    let sweeps = if relax { 1 } else { 2 };
    for sweep in 0..sweeps {
        for &v in &order {
            let first = sweep == 0 && !relax;
            let Some(target) = &targets[v] else {
                continue;
            };
            let nb: Vec<&[SgLobe]> = c.view_neighbours[v]
                .iter()
                .filter(|&&u| assigned[u])
                .map(|&u| &out.lobes[u * n..(u + 1) * n])
                .collect();
            let prior = (!nb.is_empty()).then(|| average(&nb, n));
            let warm: Option<Vec<SgLobe>> = if first && c.settings.fit_start == FitStart::Greedy {
                None
            } else if first {
                input
                    .warm
                    .map(|w| w[v * n..(v + 1) * n].to_vec())
                    .or_else(|| prior.clone())
            } else {
                Some(out.lobes[v * n..(v + 1) * n].to_vec())
            };
            let spatial: Vec<SgLobe> = input
                .spatial
                .iter()
                .flat_map(|s| s[v * n..(v + 1) * n].iter().copied())
                .collect();
            let (lobes, err, it) = fit_view(c, target, warm, prior, &spatial, first);
            out.lobes[v * n..(v + 1) * n].copy_from_slice(&lobes);
            out.errors[v] = if target.norm2 > 0.0 { err } else { -1.0 };
            out.iterations += it as u64;
            assigned[v] = true;
        }
    }
    out
}

/// Views in breadth-first order on the view icosahedron from the view with the most data
/// energy (ties: lowest index), so that every view after the first has a fitted neighbour.
fn view_order(c: &ComponentFit, targets: &[Option<ViewTarget>]) -> Vec<usize> {
    let energy = |v: usize| targets[v].as_ref().map_or(-1.0, |t| t.norm2);
    let start = (0..targets.len()).fold(0, |b, v| if energy(v) > energy(b) { v } else { b });
    let mut seen = vec![false; targets.len()];
    let mut order = vec![start];
    seen[start] = true;
    let mut i = 0;
    while i < order.len() {
        for &u in &c.view_neighbours[order[i]] {
            if !seen[u] {
                seen[u] = true;
                order.push(u);
            }
        }
        i += 1;
    }
    order
}

/// Fits one view: returns its lobes (matched to the prior, or else to the warm start), the
/// relative L2 error and the iterations spent. Only in the `first` sweep of a flood fill is
/// a poor warm start checked against a greedy fit. The lobe order ([`LobeOrder`]) decides
/// how `N >= 2` lobes are found in that sweep.
pub(super) fn fit_view(
    c: &ComponentFit,
    t: &ViewTarget,
    warm: Option<Vec<SgLobe>>,
    prior: Option<Vec<SgLobe>>,
    spatial: &[SgLobe],
    first: bool,
) -> (Vec<SgLobe>, f64, usize) {
    let n = c.lobes;
    let nested = c.settings.lobe_order == LobeOrder::Nested && n > 1;
    let additive = c.settings.lobe_order == LobeOrder::Additive && n > 1;
    let (mut lobes, err, it) = if additive {
        fit_slots(c, t, (warm, prior), spatial, first, LobeOrder::Additive)
    } else if nested && first {
        fit_slots(c, t, (warm, prior), spatial, true, LobeOrder::Nested)
    } else if nested {
        // Later sweeps refine all lobes together and keep the order of the warm start (the
        // vertex's own nested fit, or the consensus of its neighbours in a relaxation).
        let reference = warm.clone();
        let (l, e, it) = solve_view(c, n, t, warm, prior, spatial, false);
        match reference {
            Some(r) if t.norm2 > 0.0 => (permuted(&l, &match_to(&l, &r)), e, it),
            _ => (l, e, it),
        }
    } else {
        solve_view(c, n, t, warm, prior, spatial, first)
    };
    if t.norm2 > 0.0 {
        shape(c, &mut lobes, t);
    }
    (lobes, err, it)
}

/// The first `k` lobes of each `n`-lobe set in `sets` (consecutive).
fn first_of(sets: &[SgLobe], n: usize, k: usize) -> Vec<SgLobe> {
    sets.chunks_exact(n)
        .flat_map(|s| s[..k].iter().copied())
        .collect()
}

/// The lobes slot by slot: slot 1 as [`solve_view`] fits one lobe (warm start, prior and
/// neighbours of slot 1), then for `k = 2..N` by `order`:
///
/// - [`LobeOrder::Nested`] (the flood fill's first sweep only): a lobe on the residual of the
///   `k - 1` ([`sg_fit::residual_lobe`]) and a joint refinement of the `k` with the
///   coherence terms of the first `k` slots; after each step the first `k - 1` slots are
///   matched to the previous step's lobes, so slot `k` is always the `k`-th lobe found.
/// - [`LobeOrder::Additive`] (every sweep): slot `k` alone refined on the signed residual
///   of slots `1..k-1` (`FitTarget::residual`, of the lobes with their peaks bounded as
///   [`shape`] bounds them), which stay as they are, from the warm start's slot `k` after
///   the first sweep, else from a lobe on the residual, with the prior and neighbours of
///   slot `k` and no energy term (the residual's integral is not the data's; the set is
///   rescaled after, [`shape`]). A lobe that leaves the residual no smaller gets zero
///   amplitude: its view's fit is never worse than with `k - 1` lobes.
///
/// Returns the lobes, the relative L2 error of the whole set and the iterations.
fn fit_slots(
    c: &ComponentFit,
    t: &ViewTarget,
    (warm, prior): (Option<Vec<SgLobe>>, Option<Vec<SgLobe>>),
    spatial: &[SgLobe],
    first: bool,
    order: LobeOrder,
) -> (Vec<SgLobe>, f64, usize) {
    let n = c.lobes;
    let additive = order == LobeOrder::Additive;
    let head = |l: &Option<Vec<SgLobe>>, k: usize| l.as_ref().map(|v| v[..k].to_vec());
    let (mut cur, mut err, mut iterations) = solve_view(
        c,
        1,
        t,
        head(&warm, 1),
        head(&prior, 1),
        &first_of(spatial, n, 1),
        first,
    );
    if t.norm2 <= 0.0 {
        // No data: every slot takes the prior's (or the warm start's) shape, zero amplitude.
        return solve_view(c, n, t, warm, prior, spatial, true);
    }
    let mut opts = weighted_options(c, t);
    // Additive residuals are of the earlier lobes as they will be stored: a half-vector lobe's
    // peak is bounded after the fit ([`clamp_peak`]), and an unbounded one (its axis beyond
    // the view's reachable half vectors, fitting the data with its tail) would leave a
    // residual thousands of times the data's norm. Each lobe is bounded once, as it is added.
    let bound = additive && t.view.is_some();
    if additive {
        opts.energy = None;
    }
    if bound {
        clamp_peak(&mut cur, t);
    }
    for k in 2..=n {
        // The neighbours' slot `k` (additive) or first `k` slots (nested).
        let sp: Vec<SgLobe> = if additive {
            spatial.chunks_exact(n).map(|s| s[k - 1]).collect()
        } else {
            first_of(spatial, n, k)
        };
        let arr = Arrangement {
            weight: c.settings.spatial_weight * t.norm2,
            neighbours: &sp,
        };
        let arr = (!sp.is_empty() && c.settings.spatial_weight > 0.0).then_some(&arr);
        if additive {
            let resid = t.target.residual(&cur, &opts);
            // From the residual itself: the earlier lobes are already subtracted.
            let start = match &warm {
                Some(w) if !first && w.len() == n => w[k - 1],
                _ => sg_fit::residual_lobe(&resid, &[], &opts),
            };
            let start = clamp_sharpness(&[start], &opts);
            let p = prior.as_ref().map(|p| p[k - 1..k].to_vec());
            let f = sg_fit::refine_arranged(&resid, &start, &opts, p.as_deref(), arr);
            iterations += f.iterations;
            // The solver's error is relative to the residual's norm. A lobe that leaves the
            // residual no smaller (its coherence terms pulled it off the data) is not kept.
            let left = (resid.norm2() / t.target.norm2()).sqrt();
            let mut lobe = f.lobes[0];
            if f.relative_error < 1.0 {
                err = f.relative_error * left;
            } else {
                lobe.amplitude = Vec3::ZERO;
                err = left;
            }
            if bound {
                clamp_peak(std::slice::from_mut(&mut lobe), t);
            }
            cur.push(lobe);
            continue;
        }
        let mut start = cur.clone();
        start.push(sg_fit::residual_lobe(&t.target, &cur, &opts));
        let start = clamp_sharpness(&start, &opts);
        let f = sg_fit::refine_arranged(&t.target, &start, &opts, head(&prior, k).as_deref(), arr);
        iterations += f.iterations;
        err = f.relative_error;
        // Slots 1..k-1 keep the previous step's lobes (best assignment), slot k the new one.
        let mut cost = vec![0f32; k * k];
        for (slot, p) in cur.iter().enumerate() {
            for (j, l) in f.lobes.iter().enumerate() {
                cost[slot * k + j] = lobe_distance(p, l);
            }
        }
        cur = permuted(&f.lobes, &best_assignment(&cost, k));
    }
    (cur, err, iterations)
}

/// The solver options of a view: coherence weights relative to its data energy.
fn weighted_options(c: &ComponentFit, t: &ViewTarget) -> FitOptions {
    let s = &c.settings;
    FitOptions {
        prior_weights: PriorWeights {
            mean: s.mean_weight * t.norm2,
            width: s.width_weight * t.norm2,
        },
        energy: energy_target(c, t),
        ..c.opts
    }
}

/// The energy term of a view (`SgFitSettings::energy_weight`, relative to its data energy
/// and integral), if on, the view has a non-zero integral and it is in the light domain.
fn energy_target(c: &ComponentFit, t: &ViewTarget) -> Option<EnergyTarget> {
    let e2 = t.integral.length_squared() as f64;
    // The solver's energy term integrates lobes in the light domain; a half-vector fit keeps
    // its energy by the rescaling after the fit only ([`conserve_energy`]).
    let light = t.view.is_none();
    (light && c.settings.energy_weight > 0.0 && e2 > 0.0 && t.norm2 > 0.0).then(|| EnergyTarget {
        weight: c.settings.energy_weight * t.norm2 / e2,
        integral: [
            t.integral.x as f64,
            t.integral.y as f64,
            t.integral.z as f64,
        ],
    })
}

/// `l` with every sharpness clamped to the solver's bounds.
fn clamp_sharpness(l: &[SgLobe], opts: &FitOptions) -> Vec<SgLobe> {
    l.iter()
        .map(|g| SgLobe {
            sharpness: g.sharpness.clamp(opts.lambda_min, opts.lambda_max),
            ..*g
        })
        .collect()
}

/// Fits `n` lobes to one view from the warm start (all `n` refined together, the paper's
/// fit), with the coherence terms; returns the least-squares lobes (matched to the prior, or
/// else to the warm start, and to the spatial neighbours), the relative L2 error and the
/// iterations. Only in the `first` sweep of a flood fill is a poor warm start checked
/// against a greedy fit.
fn solve_view(
    c: &ComponentFit,
    n: usize,
    t: &ViewTarget,
    warm: Option<Vec<SgLobe>>,
    prior: Option<Vec<SgLobe>>,
    spatial: &[SgLobe],
    first: bool,
) -> (Vec<SgLobe>, f64, usize) {
    let reference = prior.clone().or_else(|| warm.clone());
    // Lobes are matched to the prior (or warm start) and to every spatial neighbour at once.
    let references: Vec<&[SgLobe]> = reference
        .as_deref()
        .into_iter()
        .chain(spatial.chunks_exact(n))
        .collect();
    // No data (fully occluded view): zero amplitude, mean and width from the alignment prior
    // (or the warm start), so that interpolation across views stays smooth (section 2.2.2).
    if t.norm2 <= 0.0 {
        let mut l = reference.unwrap_or_else(|| vec![c.default_lobe(); n]);
        for g in &mut l {
            g.amplitude = Vec3::ZERO;
        }
        return (l, 0.0, 0);
    }
    // Weights relative to the view's data energy, so they do not depend on its brightness.
    let s = &c.settings;
    let opts = weighted_options(c, t);
    let arr = Arrangement {
        weight: s.spatial_weight * t.norm2,
        neighbours: spatial,
    };
    let arr = (!spatial.is_empty() && s.spatial_weight > 0.0).then_some(&arr);
    let mut iterations = 0;
    let mut best = None;
    if let Some(w) = &warm {
        let f = sg_fit::refine_arranged(
            &t.target,
            &clamp_sharpness(w, &opts),
            &opts,
            prior.as_deref(),
            arr,
        );
        iterations += f.iterations;
        best = Some(f);
    }
    let retry = best.as_ref().is_none_or(|f| {
        first
            && (f.relative_error > RETRY_ERROR || f.lobes.iter().all(|g| g.amplitude == Vec3::ZERO))
    });
    if retry {
        let g = sg_fit::fit(&t.target, n, &opts, None);
        iterations += g.iterations;
        let g = match &reference {
            // Match the fresh fit to the neighbours, then let the coherence terms act.
            Some(_) => {
                let l = permuted(&g.lobes, &match_to_all(&g.lobes, &references));
                let f = sg_fit::refine_arranged(&t.target, &l, &opts, prior.as_deref(), arr);
                iterations += f.iterations;
                f
            }
            None => g,
        };
        if best
            .as_ref()
            .is_none_or(|b| g.relative_error < b.relative_error)
        {
            best = Some(g);
        }
    }
    let f = best.expect("a warm start or a greedy fit");
    let lobes = if references.is_empty() {
        f.lobes
    } else {
        permuted(&f.lobes, &match_to_all(&f.lobes, &references))
    };
    (lobes, f.relative_error, iterations)
}

/// Fits one view's data (`6 n^2` texels) on its own: the greedy fit of `sg_fit::fit` with no
/// coherence term, then the same energy handling as the flood fill. Returns the lobes and
/// the relative L2 error. The reference the flood fill is measured against in the error
/// budget (its per-pixel and exact-view rows, in `relight_eval::sg::budget`). `view` is the
/// direction the data was computed for (used in the half-vector domain).
pub fn fit_alone(c: &ComponentFit, data: &[Vec3], view: Vec3) -> (Vec<SgLobe>, f64) {
    let t = c.view_target(data, view);
    if t.norm2 <= 0.0 {
        return (vec![c.default_lobe(); c.lobes], 0.0);
    }
    let opts = FitOptions {
        energy: energy_target(c, &t),
        ..c.opts
    };
    let f = sg_fit::fit(&t.target, c.lobes, &opts, None);
    let mut lobes = f.lobes;
    shape(c, &mut lobes, &t);
    (lobes, f.relative_error)
}

/// The lobes' final shape ([`LobeShape`]): the least-squares lobes with their energy
/// restored, or moved to the moments of their share of the data.
fn shape(c: &ComponentFit, lobes: &mut Vec<SgLobe>, t: &ViewTarget) {
    match c.settings.lobe_shape {
        LobeShape::LeastSquares => {
            if t.view.is_some() {
                clamp_peak(lobes, t);
            }
            preserve_energy(lobes, t, c.opts.lambda_max, c.opts.kernel);
            if c.settings.energy {
                conserve_energy(lobes, t, c.opts.kernel);
            }
        }
        LobeShape::Moments => {
            *lobes = sg_fit::match_moments(&t.target, lobes, c.opts.lambda_min, c.opts.lambda_max);
        }
    }
}

/// Rescale the amplitudes, per channel, so that the mixture's integral over the sphere equals
/// the data's, `sum_k a_k int G_k = sum_w T(w) dA(w)` (our addition to the paper, on by
/// default, [`SgFitSettings::energy`]): a least-squares Gaussian misses the long tails of a
/// GGX or Blinn-Phong lobe (about 20 % of the energy for a GGX conductor at alpha 0.15, one
/// lobe), which shows as a uniformly too-dark render; with the integral matched a constant
/// environment is rendered exactly and smooth lighting nearly so. The factor is bounded to
/// `[1/4, 4]` so that a failed fit is not blown up.
fn conserve_energy(lobes: &mut [SgLobe], t: &ViewTarget, kernel: LobeKernel) {
    let have = lobes
        .iter()
        .fold(Vec3::ZERO, |e, g| e + lobe_integral(kernel, t, g));
    let ok = have.cmpgt(Vec3::splat(f32::MIN_POSITIVE)) & t.integral.cmpgt(Vec3::ZERO);
    let scale = Vec3::select(
        ok,
        (t.integral / have).clamp(Vec3::splat(0.25), Vec3::splat(4.0)),
        Vec3::ONE,
    );
    for g in lobes.iter_mut() {
        g.amplitude *= scale;
    }
}

/// Half-vector domain: a lobe's peak `a` (reached at `h = m`) bounded by twice the data's
/// peak. A lobe whose axis lies beyond the view's reachable half vectors (`v . m <= 0`:
/// `h(w)` always has `v . h >= 0`) can fit the data with its tail and an unbounded peak,
/// which a nearby view at render time then reaches (measured on the GGX plastic of Fig.
/// 3-4: pixels up to 200 times the reference, 146 % error).
fn clamp_peak(lobes: &mut [SgLobe], t: &ViewTarget) {
    let cap = 2.0 * t.peak;
    for g in lobes.iter_mut() {
        g.amplitude = g.amplitude.min(Vec3::splat(cap));
    }
}

/// `int g(w) dw` of a fitted lobe over the light directions: `a unit_integral(lambda)` in the
/// light domain; in the half-vector domain of view `v`, the integral of each Gaussian term
/// `exp(s (m . h(w) - 1))` over `w` ([`half_vector::lobe_mass`]).
fn lobe_integral(kernel: LobeKernel, t: &ViewTarget, g: &SgLobe) -> Vec3 {
    match t.view {
        None => g.amplitude * kernel.unit_integral(g.sharpness),
        Some(v) => half_vector::lobe_mass(kernel, g, v),
    }
}

/// Lobes at the sharpness bound (data sharper than the cube map resolves, e.g. a mirror) get
/// their amplitude rescaled so that the mixture's integral matches the data's, per channel:
/// the least-squares amplitude of a too-broad lobe under-spreads a peak's energy (for a
/// single-texel spike it is twice the energy-preserving one). A clamped lobe with a negligible
/// share of the energy keeps its amplitude; the factor is capped at 4.
fn preserve_energy(lobes: &mut [SgLobe], t: &ViewTarget, lambda_max: f32, kernel: LobeKernel) {
    let at_bound = |g: &SgLobe| g.sharpness >= 0.999 * lambda_max;
    if !lobes.iter().any(at_bound) {
        return;
    }
    let (mut free, mut bound) = (Vec3::ZERO, Vec3::ZERO);
    for g in lobes.iter() {
        let e = lobe_integral(kernel, t, g);
        if at_bound(g) {
            bound += e;
        } else {
            free += e;
        }
    }
    // Only a lobe that carries a real share of the energy is rescaled, by at most 4x (the
    // least-squares amplitude of a spike is half the energy-preserving one).
    let want = (t.integral - free).max(Vec3::ZERO);
    let meaningful = bound.cmpgt(want * 1e-3) & bound.cmpgt(Vec3::splat(f32::MIN_POSITIVE));
    let scale = Vec3::select(meaningful, (want / bound).min(Vec3::splat(4.0)), Vec3::ONE);
    for g in lobes.iter_mut().filter(|g| at_bound(g)) {
        g.amplitude *= scale;
    }
}
