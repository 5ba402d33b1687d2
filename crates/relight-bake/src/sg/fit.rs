//! Fitting spherical Gaussians to the transport of every vertex and view: the flood fill of
//! Green 2005 (thesis section 2.2.2, eq. 2.2-2.6; section 3.1 Algorithm 2; section 3.4).
//!
//! # Conventions
//! Lobes are [`SgLobe`]s `a exp(lambda (mu . w - 1))` (`lambda = 1 / sigma^2`, see
//! `relight_sphere::sg`); the data of a (vertex, view) is its cube map of transport per
//! steradian ([`super::transport::VertexTransport`]); views are the vertices of
//! `Icosphere::new(VIEW_FREQUENCY)` with their icosahedron neighbours as `r(v)` of eq. 2.4.
//!
//! # The objective per (vertex, view) (eq. 2.2)
//! `E = D + beta M + gamma V + delta S`, minimised by `relight_sphere::sg_fit`'s bounded
//! Levenberg-Marquardt with analytic Jacobians:
//! * `D` (eq. 2.3): solid-angle-weighted squared error over the texels, grouped as in
//!   Algorithm 2 ([`target`]: a quadtree per face whose coarse cells cover zero, negligible
//!   or smooth data);
//! * `M`, `V` (eq. 2.4, 2.5): distance of each lobe's axis and log sharpness to the prior,
//!   the average of the neighbouring views' lobes (normalised mean axis, mean log sharpness).
//!   Deviations: the thesis averages raw axes (`|mu - avg|^2 = |avg| |mu - avg/|avg||^2 +
//!   const`, the same up to a weight `|avg| <= 1`) and aligns `sigma` itself rather than
//!   `ln lambda = -2 ln sigma`, which is scale-free (see `sg_fit`);
//! * `S` (eq. 2.6): the arrangement term, exactly as the thesis writes it, against the
//!   processed neighbouring vertices (`sg_fit::Arrangement`).
//!
//! The weights `beta, gamma, delta` ([`SgFitSettings`]) are relative to the view's data
//! energy `sum dA |T|^2`, so that a dim vertex is not all prior and a bright one all data.
//!
//! # Per vertex (eq. 2.2 "concurrently across all views")
//! The thesis optimises all 92 views of a vertex at once. Here the coupled problem is solved
//! by block coordinate descent: two Gauss-Seidel sweeps over the views in breadth-first order
//! on the view icosahedron, starting at the view with the most data energy. Each view is
//! refined with the others fixed; in the first sweep the prior averages only the views
//! already fitted. Warm starts: the same view of the neighbour the vertex was reached from in
//! the flood fill, else the prior (the fitted neighbouring views); the greedy fit of
//! `sg_fit::fit` runs only for the very first view of a region's seed vertex, or when a warm
//! start in the first sweep ends with a relative error above 0.8 or zero amplitude (kept if
//! better). Refinements stop when a step lowers the objective by less than 0.1 %, after at
//! most `max_iterations` steps. After every fit the lobes are permuted to best match the
//! prior and the processed neighbouring vertices together (summed distance
//! `|mu - mu'|^2 + 0.1 (ln lambda - ln lambda')^2`; brute force for `N <= 3`, greedy beyond).
//! Matching against the neighbouring vertices too (not only the views' prior) cut the flips
//! of a 2-lobe glossy sphere bake from 10202 to 4072 (of 30K edge-view pairs).
//!
//! # The flood fill (section 2.2.2) and parallelism
//! The mesh graph (triangle edges) is split into regions (`graph::regions`): about
//! `regions` of them (automatic: `clamp(vertices / 512, 1, 64)`, independent of the thread
//! count so that the result is too), at least one per connected component, seeded by
//! farthest-point sampling and grown by a multi-source breadth-first search. Regions run in
//! parallel; each is flood-filled breadth-first from its seed, and the spatial term of a
//! vertex uses its neighbours *in the same region* that come earlier in that order. Each
//! vertex's transport is computed when it is fitted (`TransportSource::compute`, one
//! reusable buffer per region) and dropped afterwards. Since regions are filled
//! independently, a region may come out with its lobes consistently permuted relative to
//! its neighbour; `flips::align_regions` then permutes whole regions, per view,
//! to match their already aligned neighbours across the boundary.
//!
//! # Flips and relaxation (section 3.4)
//! A flip is an (edge, view) pair where the best permutation of one endpoint's lobes against
//! the other's is not the identity ([`SgFitStats::flips`], counted after the flood fill and
//! the region alignment, summed over components; always 0 for one lobe). Relaxation (the
//! thesis' future work): each of `relax_sweeps` sweeps takes the vertices on a flipped edge,
//! permutes each of their views to the consensus of *all* their neighbours and refits the
//! views in which they have a flipped edge (one Gauss-Seidel sweep over those views, spatial
//! term against all neighbours), in parallel from the
//! previous sweep's lobes (Jacobi, so deterministic); [`SgFitStats::flips_after_relaxation`].
//!
//! Counting every (edge, view) makes the number large for two or more lobes on real glossy
//! data: a second lobe that only mops up a residual has an ill-determined axis, and the count
//! includes it. Relaxation recomputes the transport of a flagged vertex (it is never kept)
//! and refits only its flagged views.
//!
//! # Cost
//! Measured (CPU time, one thread, by this module's former timing tests on synthetic
//! transport): 0.12-0.22 ms per (vertex, view) for one lobe and 0.20-0.48 ms for two on
//! 6x32x32 Blinn-Phong (exponent 20-500) and GGX (alpha 0.05-0.5) transport with half the
//! hemisphere masked; about 170-470 of the 6144 texels remain after grouping. `relight bench`
//! (section "SG bake") measures the fit per (vertex, view, component) on real transport.
//!
//! # Bad input
//! * A view without data (fully occluded): zero amplitude, axis and width of the prior (the
//!   neighbouring views), so interpolation across views stays smooth.
//! * Data sharper than the cube map resolves (a mirror): the sharpness is bounded by
//!   `(res / 2)^2` and the amplitude of a lobe at that bound is rescaled so that the fit
//!   keeps the data's integral (`vertex::preserve_energy`).
//! * A vertex without processed neighbours (a region seed, an isolated vertex, a vertex in
//!   no triangle, one of several coincident but unwelded vertices) is fitted without the
//!   spatial term and without a neighbour's warm start.

mod flips;
mod graph;
mod parts;
pub mod target;
mod vertex;

pub use parts::{PartFit, RegionPlan};
pub use vertex::{fit_alone, ComponentFit, VertexFit};

use super::transport::{TransportSource, VertexTransport};
use super::{SgFitSettings, SgFitStats, SgLobes, VIEW_FREQUENCY};
use flips::LobeField;
use graph::{Adjacency, Regions};
use indicatif::ProgressBar;
use rayon::prelude::*;
use relight_sphere::icosphere::Icosphere;
use relight_sphere::sg::SgLobe;
use std::ops::Range;
use vertex::{fit_vertex, VertexInput};

/// What to fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitConfig {
    /// Lobes of the direct glossy component (`1..=10`).
    pub direct_lobes: usize,
    /// Lobes of the indirect glossy component (`0..=10`; 0 or an indirect resolution of 0:
    /// no indirect component).
    pub indirect_lobes: usize,
    /// Weights, iterations, relaxation and regions.
    pub fit: SgFitSettings,
}

/// The fitted mesh.
#[derive(Clone, Debug)]
pub struct MeshFit {
    /// Direct glossy lobes.
    pub direct: SgLobes,
    /// Indirect glossy lobes, if fitted.
    pub indirect: Option<SgLobes>,
    /// Diffuse SH per vertex, copied from the transport (`diffuse_stride` floats each).
    pub diffuse_sh: Vec<f32>,
    /// Floats of diffuse SH per vertex.
    pub diffuse_stride: usize,
    /// Statistics.
    pub stats: SgFitStats,
}

/// The automatic region count for `vertices` vertices (module docs).
pub fn auto_regions(vertices: usize) -> usize {
    (vertices / 512).clamp(1, 64)
}

/// One component's fit over the whole mesh.
struct Component {
    fit: ComponentFit,
    lobes: Vec<SgLobe>,
    /// Relative L2 error per (vertex, view); negative where the view has no data. Kept in
    /// `f32` so that a part bundle carries it exactly (a merge recomputes the same mean).
    error: Vec<f32>,
}

/// The components to fit: per component, its cube-map resolution and lobe count.
fn component_fits(res: [usize; 2], config: &FitConfig, views: &Icosphere) -> Vec<ComponentFit> {
    let mut fits = vec![ComponentFit::new(
        res[0],
        config.direct_lobes,
        &config.fit,
        views,
    )];
    if config.indirect_lobes > 0 && res[1] > 0 {
        fits.push(ComponentFit::new(
            res[1],
            config.indirect_lobes,
            &config.fit,
            views,
        ));
    }
    fits
}

/// Fits every vertex and view of `source` (module docs) on the current rayon pool, counting
/// one `progress` step per vertex fitted (relaxation extends its length).
///
/// `triangles` define the neighbourhoods (indices `< source.vertex_count()`). The result
/// depends on the source, the triangles and `config` only, not on the thread count.
///
/// # Panics
/// Debug builds assert lobe counts in range and triangle indices in range.
pub fn fit_mesh<S: TransportSource + ?Sized>(
    source: &S,
    triangles: &[[u32; 3]],
    config: &FitConfig,
    progress: &ProgressBar,
) -> MeshFit {
    let plan = RegionPlan::new(source.vertex_count(), triangles, &config.fit);
    let all = fit_regions(source, &plan, config, 0..plan.region_count(), progress);
    let res = [source.direct_res(), source.indirect_res()];
    finish(&plan, config, res, all, Some(source), progress)
}

/// Flood-fills the regions `range` of `plan` (module docs) in parallel: the first half of
/// [`fit_mesh`], and what one part of a sharded bake runs.
pub fn fit_regions<S: TransportSource + ?Sized>(
    source: &S,
    plan: &RegionPlan,
    config: &FitConfig,
    range: Range<usize>,
    progress: &ProgressBar,
) -> PartFit {
    debug_assert!((1..=10).contains(&config.direct_lobes) && config.indirect_lobes <= 10);
    let views = Icosphere::new(VIEW_FREQUENCY);
    let nview = views.vertices().len();
    let fits = component_fits([source.direct_res(), source.indirect_res()], config, &views);
    let filled: Vec<RegionFit> = range
        .clone()
        .into_par_iter()
        .map(|r| fill_region(source, &fits, &plan.adj, &plan.regions, r, progress))
        .collect();
    // Rows in ascending vertex order.
    let mut at: Vec<(u32, usize, usize)> = filled
        .iter()
        .zip(&plan.regions.orders[range])
        .enumerate()
        .flat_map(|(ri, (_, order))| order.iter().enumerate().map(move |(i, &x)| (x, ri, i)))
        .collect();
    at.sort_unstable();
    let stride = filled
        .iter()
        .find_map(|rf| rf.diffuse.first().map(Vec::len))
        .unwrap_or(0);
    let mut out = PartFit {
        vertices: at.iter().map(|a| a.0).collect(),
        lobes: fits
            .iter()
            .map(|f| Vec::with_capacity(at.len() * nview * f.lobes))
            .collect(),
        errors: vec![Vec::with_capacity(at.len() * nview); fits.len()],
        diffuse_sh: Vec::with_capacity(at.len() * stride),
        diffuse_stride: stride,
        iterations: 0,
    };
    for &(_, ri, i) in &at {
        let rf = &filled[ri];
        for (c, f) in rf.fits.iter().enumerate() {
            out.lobes[c].extend_from_slice(&f[i].lobes);
            out.errors[c].extend(f[i].errors.iter().map(|&e| e as f32));
            out.iterations += f[i].iterations;
        }
        debug_assert_eq!(rf.diffuse[i].len(), stride);
        out.diffuse_sh.extend_from_slice(&rf.diffuse[i]);
    }
    out
}

/// The second half of [`fit_mesh`]: aligns the regions of `whole` (every vertex of the
/// plan), counts flips, relaxes (`relax` is the transport, needed only when
/// `config.fit.relax_sweeps > 0`) and computes the statistics. `res` is the direct and
/// indirect cube-map resolution of the transport (what [`TransportSource`] reports).
///
/// # Panics
/// If `whole` does not hold every vertex of `plan`, or relaxation is asked without `relax`.
pub fn finish<S: TransportSource + ?Sized>(
    plan: &RegionPlan,
    config: &FitConfig,
    res: [usize; 2],
    whole: PartFit,
    relax_source: Option<&S>,
    progress: &ProgressBar,
) -> MeshFit {
    let views = Icosphere::new(VIEW_FREQUENCY);
    let nv = plan.adj.len();
    assert!(
        whole.vertices.len() == nv
            && whole
                .vertices
                .iter()
                .enumerate()
                .all(|(i, &x)| x as usize == i),
        "finish needs every vertex"
    );
    let mut comps: Vec<Component> = component_fits(res, config, &views)
        .into_iter()
        .zip(whole.lobes)
        .zip(whole.errors)
        .map(|((fit, lobes), error)| Component { fit, lobes, error })
        .collect();
    let mut stats = SgFitStats {
        iterations: whole.iterations,
        ..SgFitStats::default()
    };
    let nview = views.vertices().len();
    for c in &mut comps {
        flips::align_regions(&mut c.lobes, nview, c.fit.lobes, &plan.adj, &plan.regions);
    }
    let sweeps = config.fit.relax_sweeps;
    (stats.flips, stats.flips_after_relaxation) = match relax_source {
        Some(source) => relax(
            source,
            &mut comps,
            &plan.adj,
            sweeps,
            progress,
            &mut stats.iterations,
        ),
        None => {
            assert!(sweeps == 0, "relaxation needs the transport");
            let flips = count_flips(&comps, &plan.adj).0;
            (flips, flips)
        }
    };
    for (i, c) in comps.iter().enumerate() {
        let (s, n) = c
            .error
            .iter()
            .filter(|&&e| e >= 0.0)
            .fold((0.0, 0), |(s, n), &e| (s + e as f64, n + 1));
        stats.mean_relative_error[i] = if n > 0 { s / n as f64 } else { 0.0 };
    }
    let mut comps = comps.into_iter().map(|c| SgLobes {
        lobe_count: c.fit.lobes,
        view_count: nview,
        lobes: c.lobes,
    });
    MeshFit {
        direct: comps.next().expect("the direct component"),
        indirect: comps.next(),
        diffuse_sh: whole.diffuse_sh,
        diffuse_stride: whole.diffuse_stride,
        stats,
    }
}

/// Flips over all components, and the vertices on a flipped edge (sorted) with the views
/// (bit `v`) in which they are.
fn count_flips(comps: &[Component], adj: &Adjacency) -> (u64, Vec<(u32, u128)>) {
    let mut all = vec![0u128; adj.len()];
    let mut n = 0;
    for c in comps {
        let field = LobeField {
            views: c.fit.views(),
            n: c.fit.lobes,
            lobes: &c.lobes,
        };
        let (k, f) = field.flips(adj);
        n += k;
        for (a, m) in all.iter_mut().zip(f) {
            *a |= m;
        }
    }
    let flagged = (0..adj.len() as u32)
        .zip(all)
        .filter(|&(_, m)| m != 0)
        .collect();
    (n, flagged)
}

/// Counts flips, runs up to `sweeps` relaxation sweeps (module docs) and counts them again:
/// returns (flips before, flips after).
fn relax<S: TransportSource + ?Sized>(
    source: &S,
    comps: &mut [Component],
    adj: &Adjacency,
    sweeps: usize,
    progress: &ProgressBar,
    iterations: &mut u64,
) -> (u64, u64) {
    let (before, mut flagged) = count_flips(comps, adj);
    let mut flips = before;
    for _ in 0..sweeps {
        if flagged.is_empty() {
            break;
        }
        progress.inc_length(flagged.len() as u64);
        let shared: &[Component] = comps;
        let refits: Vec<Vec<VertexFit>> = flagged
            .par_iter()
            .map_init(VertexTransport::default, |buf, &(x, mask)| {
                source.compute(x as usize, buf);
                let r = shared
                    .iter()
                    .enumerate()
                    .map(|(ci, c)| {
                        let views = data_views(buf, &c.fit);
                        relax_vertex(c, adj, x as usize, component_data(buf, ci), views, mask)
                    })
                    .collect();
                progress.inc(1);
                r
            })
            .collect();
        for (&(x, mask), r) in flagged.iter().zip(refits) {
            let x = x as usize;
            for (c, f) in comps.iter_mut().zip(r) {
                let nview = c.fit.views();
                let s = nview * c.fit.lobes;
                c.lobes[x * s..(x + 1) * s].copy_from_slice(&f.lobes);
                for v in (0..nview).filter(|&v| mask >> v & 1 == 1) {
                    c.error[x * nview + v] = f.errors[v] as f32;
                }
                *iterations += f.iterations;
            }
        }
        (flips, flagged) = count_flips(comps, adj);
    }
    (before, flips)
}

/// The direction each view's data was computed for: the transport's own (clamped above the
/// horizon; what the half-vector domain moves the data by), else the icosahedron's.
fn data_views<'a>(buf: &'a VertexTransport, c: &'a ComponentFit) -> &'a [glam::Vec3] {
    if buf.view_dirs.len() == c.views() {
        &buf.view_dirs
    } else {
        &c.view_dirs
    }
}

fn component_data(buf: &VertexTransport, component: usize) -> &[glam::Vec3] {
    if component == 0 {
        &buf.direct
    } else {
        &buf.indirect
    }
}

/// The fits of one region, in its flood-fill order.
struct RegionFit {
    /// Per component, per vertex of the order.
    fits: Vec<Vec<VertexFit>>,
    diffuse: Vec<Vec<f32>>,
}

/// Flood-fills region `r` breadth-first from its seed (module docs).
fn fill_region<S: TransportSource + ?Sized>(
    source: &S,
    fits: &[ComponentFit],
    adj: &Adjacency,
    regions: &Regions,
    r: usize,
    progress: &ProgressBar,
) -> RegionFit {
    let order = &regions.orders[r];
    let mut buf = VertexTransport::default();
    let mut out = RegionFit {
        fits: vec![Vec::with_capacity(order.len()); fits.len()],
        diffuse: Vec::with_capacity(order.len()),
    };
    for (i, &x) in order.iter().enumerate() {
        let x = x as usize;
        source.compute(x, &mut buf);
        // Processed neighbours: same region, earlier in the order; the earliest one is the
        // breadth-first parent, whose lobes warm-start this vertex.
        let processed: Vec<usize> = adj
            .neighbours(x)
            .iter()
            .filter(|&&y| {
                regions.region_of[y as usize] as usize == r
                    && (regions.rank[y as usize] as usize) < i
            })
            .map(|&y| regions.rank[y as usize] as usize)
            .collect();
        let parent = processed.iter().copied().min();
        for (ci, c) in fits.iter().enumerate() {
            let done = &out.fits[ci];
            let spatial: Vec<&[SgLobe]> = processed.iter().map(|&j| &done[j].lobes[..]).collect();
            let f = fit_vertex(
                c,
                &VertexInput {
                    data: component_data(&buf, ci),
                    warm: parent.map(|j| &done[j].lobes[..]),
                    spatial: &spatial,
                    views: data_views(&buf, c),
                    relax: None,
                },
            );
            out.fits[ci].push(f);
        }
        out.diffuse.push(buf.diffuse_sh.clone());
        progress.inc(1);
    }
    out
}

/// Refits vertex `x` of a component against all its neighbours (relaxation, module docs).
fn relax_vertex(
    c: &Component,
    adj: &Adjacency,
    x: usize,
    data: &[glam::Vec3],
    views: &[glam::Vec3],
    mask: u128,
) -> VertexFit {
    let nview = c.fit.views();
    let s = nview * c.fit.lobes;
    let lobes_of = |y: usize| &c.lobes[y * s..(y + 1) * s];
    let warm = if c.fit.lobes > 1 {
        let field = LobeField {
            views: nview,
            n: c.fit.lobes,
            lobes: &c.lobes,
        };
        field.consensus(adj, x)
    } else {
        lobes_of(x).to_vec()
    };
    let spatial: Vec<&[SgLobe]> = adj
        .neighbours(x)
        .iter()
        .map(|&y| lobes_of(y as usize))
        .collect();
    fit_vertex(
        &c.fit,
        &VertexInput {
            data,
            warm: Some(&warm),
            spatial: &spatial,
            views,
            relax: Some(mask),
        },
    )
}

#[cfg(test)]
mod tests;
