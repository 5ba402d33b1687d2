//! Sampling the vertex visibility function with the ray caster (Cheslack-Postava et al.
//! 2008, sec. 4.1 "we simply loop through each vertex to generate visibility cuts", and the
//! pilot visibility vectors of sec. 3.4).
//!
//! For vertex `p` with unit shading normal `n`, light `i` gets `v_i = V(w_i) max(0, n . w_i)`
//! ([`CutFunction::VisibilityCosine`]) or `V(w_i) [n . w_i > 0]` ([`CutFunction::Visibility`],
//! the paper's binary visibility and the default, the cosine left to the BRDF at render
//! time); see the [`crate::cuts`] conventions. One shadow ray per light above the
//! shading horizon,
//! leaving `p` offset along its area-weighted geometric normal exactly as the SH bake's rays
//! ([`crate::transport::surface_ray`]: a direction above the shading normal but below the
//! surface hits the surface and counts as blocked). A vertex with a degenerate normal sees
//! nothing. The rays of one vertex go to the caster as one stream (`occluded_many`).
//!
//! Vertices are independent: they run on all cores (rayon) in chunks, each chunk's cuts
//! appended in vertex order, so the result does not depend on the thread count; the light
//! directions carry the seed (they are the only random choice).

use super::cut::{select_cut, NodeStats, SelectedCut, VertexCuts};
use super::surface::SurfaceSamples;
use super::tree::{split_groups, LightTree, PilotVectors};
use crate::transport::{
    check_mesh_geometry, progress_bar, surface_ray, vertex_geometric_normals, with_threads,
};
use crate::BakeError;
use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use relight_scene::accel::{Ray, RayCaster};
use relight_scene::mesh::TriMesh;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// The function a vertex cut approximates. A closed set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum CutFunction {
    /// `V(w) max(0, n . w)`: visibility times the clamped cosine of the vertex normal
    /// (cuts 2.3-2.7x shorter, but the cosine of a coarse cluster straddling the horizon
    /// lights a band beyond a sphere's terminator: larger errors).
    VisibilityCosine,
    /// `V(w) [n . w > 0]`: binary visibility above the vertex's horizon (the paper's `V`,
    /// sec. 3.1, with the cosine in the BRDF, so a per-pixel normal can change it). The
    /// default: closer to the path tracer on every scene measured (docs/RESULTS.md, section
    /// cuts).
    #[default]
    Visibility,
}

/// Vertices per parallel work item (and progress tick).
const CHUNK: usize = 16;

/// How to cut each vertex's function (Eq. 6 and the cap).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutParams {
    /// `sigma` of Eq. 6 (`|C| var <= sigma^2`), `>= 0`.
    pub sigma: f32,
    /// Largest cut length; longer cuts stop here and are reported in
    /// [`VertexCuts::capped`].
    pub max_nodes: usize,
    /// Worker threads (`None`: rayon's global pool).
    pub threads: Option<usize>,
    /// Show a progress bar on stderr.
    pub progress: bool,
}

/// What the light samples are: distant directions or points on the surfaces.
#[derive(Clone, Copy, Debug)]
pub enum LightTargets<'a> {
    /// Unit directions of a distant environment ([`super::samples`]).
    Directions(&'a [Vec3]),
    /// Points on the scene's surfaces with normals and areas ([`super::surface`]).
    Points(&'a SurfaceSamples),
}

impl LightTargets<'_> {
    /// Number of light samples.
    pub fn len(&self) -> usize {
        match self {
            LightTargets::Directions(d) => d.len(),
            LightTargets::Points(p) => p.len(),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Samples the visibility function of the vertices of one mesh towards a set of distant
/// light directions or of surface points ([`LightTargets`]).
pub struct VisibilitySampler<'a> {
    mesh: &'a TriMesh,
    caster: &'a dyn RayCaster,
    targets: LightTargets<'a>,
    ng: Vec<Vec3>,
    function: CutFunction,
}

/// Per-thread buffers of [`VisibilitySampler::sample`].
#[derive(Default)]
pub struct Scratch {
    pub(super) rays: Vec<Ray>,
    pub(super) lights: Vec<u32>,
    pub(super) cosines: Vec<f32>,
    occluded: Vec<bool>,
}

impl<'a> VisibilitySampler<'a> {
    /// A sampler of `function` of the vertices of `mesh` (the caster built over it) towards
    /// unit directions `dirs`.
    ///
    /// # Errors
    /// [`BakeError::Scene`] for an inconsistent mesh.
    pub fn new(
        mesh: &'a TriMesh,
        caster: &'a dyn RayCaster,
        dirs: &'a [Vec3],
        function: CutFunction,
    ) -> Result<Self, BakeError> {
        Self::with_targets(mesh, caster, LightTargets::Directions(dirs), function)
    }

    /// A sampler of `function` of the vertices of `mesh` towards `targets` (for points:
    /// the function times the clamped geometric term, [`super::local`]).
    ///
    /// # Errors
    /// [`BakeError::Scene`] for an inconsistent mesh.
    pub fn with_targets(
        mesh: &'a TriMesh,
        caster: &'a dyn RayCaster,
        targets: LightTargets<'a>,
        function: CutFunction,
    ) -> Result<Self, BakeError> {
        check_mesh_geometry(mesh)?;
        Ok(VisibilitySampler {
            mesh,
            caster,
            targets,
            ng: vertex_geometric_normals(mesh),
            function,
        })
    }

    /// Fill `out[i]` (one per direction) with vertex `v`'s function towards `w_i`
    /// ([`CutFunction`]).
    ///
    /// # Panics
    /// If `out.len()` differs from the number of directions or `v` is out of range.
    pub fn sample(&self, v: usize, out: &mut [f32], s: &mut Scratch) {
        assert_eq!(out.len(), self.targets.len());
        out.fill(0.0);
        let n = self.mesh.normals[v].normalize_or_zero();
        if n == Vec3::ZERO {
            return;
        }
        let p = self.mesh.positions[v];
        s.rays.clear();
        s.lights.clear();
        s.cosines.clear();
        let dirs = match self.targets {
            LightTargets::Directions(d) => d,
            LightTargets::Points(points) => {
                super::local::point_rays(p, n, self.ng[v], points, self.function, s);
                &[]
            }
        };
        for (i, &w) in dirs.iter().enumerate() {
            let c = n.dot(w);
            if c > 0.0 {
                s.rays.push(surface_ray(p, self.ng[v], w));
                s.lights.push(i as u32);
                s.cosines.push(match self.function {
                    CutFunction::VisibilityCosine => c.min(1.0),
                    CutFunction::Visibility => 1.0,
                });
            }
        }
        s.occluded.clear();
        s.occluded.resize(s.rays.len(), false);
        self.caster.occluded_many(&s.rays, &mut s.occluded);
        for k in 0..s.rays.len() {
            if !s.occluded[k] {
                out[s.lights[k] as usize] = s.cosines[k];
            }
        }
    }

    /// The visibility cuts of the vertices `range` over `tree` (whose lights are this
    /// sampler's directions), in vertex order.
    ///
    /// # Errors
    /// [`BakeError::Settings`] for a range outside the mesh, a tree of another light count,
    /// `max_nodes == 0` or a bad `sigma`; [`BakeError::Threads`].
    pub fn cuts(
        &self,
        tree: &LightTree,
        range: Range<usize>,
        params: &CutParams,
    ) -> Result<VertexCuts, BakeError> {
        self.check_range(&range)?;
        if tree.light_count() != self.targets.len() {
            return Err(BakeError::Settings(format!(
                "light tree of {} lights for {} directions",
                tree.light_count(),
                self.targets.len()
            )));
        }
        if params.max_nodes == 0 || !(params.sigma >= 0.0 && params.sigma.is_finite()) {
            return Err(BakeError::Settings(format!(
                "cut sigma {} and cap {} (need sigma >= 0, cap >= 1)",
                params.sigma, params.max_nodes
            )));
        }
        let pb = progress_bar(params.progress, range.len() as u64, "cuts bake");
        let sigma2 = params.sigma * params.sigma;
        let starts: Vec<usize> = range.clone().step_by(CHUNK).collect();
        let parts: Vec<VertexCuts> = with_threads(params.threads, || {
            starts
                .par_iter()
                .map_init(
                    || {
                        let values = vec![0.0f32; self.targets.len()];
                        (Scratch::default(), values, NodeStats::default(), Vec::new())
                    },
                    |(scratch, values, stats, heap), &start| {
                        let mut part = VertexCuts::default();
                        for v in start..(start + CHUNK).min(range.end) {
                            self.sample(v, values, scratch);
                            stats.compute(tree, values);
                            let cut: SelectedCut = select_cut(
                                tree,
                                stats,
                                self.threshold(sigma2, stats, tree),
                                params.max_nodes,
                                heap,
                            );
                            part.push(tree, &cut, stats);
                        }
                        self.progress(&pb, part.vertex_count());
                        part
                    },
                )
                .collect()
        })?;
        pb.finish_and_clear();
        Ok(concat(parts))
    }

    /// The threshold of Eq. 6 for one vertex: `sigma^2` for directions (a function in
    /// `[0, 1]` of order 1); for surface points `sigma^2 <g>^2`, `<g>` the vertex's mean over
    /// all samples, i.e. Eq. 6 on `g / <g>` (the geometric term is of order `A_s / d^2`,
    /// ~1e-3 and less, so an absolute `sigma` would leave every cut at the root).
    fn threshold(&self, sigma2: f32, stats: &NodeStats, tree: &LightTree) -> f32 {
        match self.targets {
            LightTargets::Directions(_) => sigma2,
            LightTargets::Points(_) => {
                let m = stats.mean[tree.root() as usize];
                sigma2 * m * m
            }
        }
    }

    fn progress(&self, pb: &ProgressBar, n: usize) {
        pb.inc(n as u64);
    }

    fn check_range(&self, range: &Range<usize>) -> Result<(), BakeError> {
        if range.start > range.end || range.end > self.mesh.vertex_count() {
            return Err(BakeError::Settings(format!(
                "vertex range {}..{} is not inside the mesh's {} vertices",
                range.start,
                range.end,
                self.mesh.vertex_count()
            )));
        }
        Ok(())
    }

    /// Pilot visibility vectors (sec. 3.4): the mesh's vertices clustered into `clusters`
    /// groups with the geometric metric (Eq. 11 on vertex positions and normals, `k`), and
    /// every light's mean visibility function over each group. Costs one full pass of rays
    /// over all vertices (the paper's "twice the precomputation time").
    ///
    /// # Errors
    /// [`BakeError::Settings`] for `clusters == 0`, `k <= 0` or a mesh without vertices;
    /// [`BakeError::Threads`].
    pub fn pilot_vectors(
        &self,
        clusters: usize,
        k: f32,
        threads: Option<usize>,
        progress: bool,
    ) -> Result<PilotVectors, BakeError> {
        let nv = self.mesh.vertex_count();
        if clusters == 0 || nv == 0 || !(k > 0.0 && k.is_finite()) {
            return Err(BakeError::Settings(format!(
                "pilot vectors need >= 1 cluster, >= 1 vertex and K > 0 (got {clusters}, \
                 {nv}, {k})"
            )));
        }
        let groups = self.vertex_groups(clusters.min(nv), k);
        let m = groups.len();
        let n = self.targets.len();
        let mut data = vec![0.0f32; n * m];
        let pb = progress_bar(progress, nv as u64, "cuts pilot");
        // Clusters in batches: a batch's columns are computed in parallel, then scattered
        // into the light-major matrix (bounded extra memory).
        let batch = 64;
        with_threads(threads, || {
            for b0 in (0..m).step_by(batch) {
                let cols: Vec<Vec<f32>> = groups[b0..(b0 + batch).min(m)]
                    .par_iter()
                    .map_init(
                        || (Scratch::default(), vec![0.0f32; n]),
                        |(scratch, values), members| {
                            let mut col = vec![0.0f64; n];
                            for &v in members {
                                self.sample(v as usize, values, scratch);
                                col.iter_mut().zip(values.iter()).for_each(|(c, &x)| {
                                    *c += x as f64;
                                });
                            }
                            pb.inc(members.len() as u64);
                            let w = 1.0 / members.len() as f64;
                            col.iter().map(|&c| (c * w) as f32).collect()
                        },
                    )
                    .collect();
                for (jj, col) in cols.iter().enumerate() {
                    let j = b0 + jj;
                    for (i, &x) in col.iter().enumerate() {
                        data[i * m + j] = x;
                    }
                }
            }
        })?;
        pb.finish_and_clear();
        Ok(PilotVectors {
            lights: n,
            clusters: m,
            data,
        })
    }

    /// The vertices split top-down into `clusters` groups by the geometric metric.
    fn vertex_groups(&self, clusters: usize, k: f32) -> Vec<Vec<u32>> {
        let (lo, hi) = self.mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let diag = (hi - lo).length();
        let wx = if diag > 0.0 { k / diag } else { 0.0 };
        let mut f = Vec::with_capacity(6 * self.mesh.vertex_count());
        for (p, n) in self.mesh.positions.iter().zip(&self.mesh.normals) {
            f.extend_from_slice(&(*p * wx).to_array());
            f.extend_from_slice(&n.normalize_or_zero().to_array());
        }
        let mut ids: Vec<u32> = (0..self.mesh.vertex_count() as u32).collect();
        let mut sizes = Vec::new();
        split_groups(&f, 6, &mut ids, clusters, &mut sizes);
        let mut out = Vec::with_capacity(sizes.len());
        let mut at = 0;
        for s in sizes {
            out.push(ids[at..at + s].to_vec());
            at += s;
        }
        out
    }
}

/// Concatenate per-chunk cuts in order.
fn concat(parts: Vec<VertexCuts>) -> VertexCuts {
    let mut out = VertexCuts {
        offsets: vec![0],
        ..Default::default()
    };
    for p in parts {
        out.append(p);
    }
    out
}

#[cfg(test)]
mod tests;
