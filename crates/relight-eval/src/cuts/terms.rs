//! Cheslack-Postava et al. 2008 Fig. 8a: terms against approximation error, for visibility
//! cuts and for non-linear Haar wavelets (Ng et al. 2003) on the same visibility functions.
//!
//! For a spread of vertices of a mesh, the visibility function ([`CutFunction`], the bake's)
//! is sampled twice with the same ray caster: at the bake's light samples (a Fibonacci
//! lattice, one leaf of the geometric light tree each) and at the texel centres of a cube map
//! with `n x n` faces. Then for every term count `m`:
//!
//! * **cut, Eq. 6 order**: the cut the bake's [`crate::cuts`] selection would build with no
//!   threshold and a cap of `m` nodes (refine the node of largest `M2 = |C| var`);
//! * **cut, greedy**: refine instead the node whose split lowers the total error most,
//!   `M2 - M2_left - M2_right` (a better selection for a fixed number of terms; the issue's
//!   "greedy on total error");
//! * **Haar**: the `m` largest coefficients of the solid-angle-weighted Haar basis
//!   ([`relight_sphere::haar`], the best `m`-term approximation in the L2 norm on the
//!   sphere).
//!
//! Errors are relative L2: for a cut `sqrt(sum_C M2_C / sum_i x_i^2)` over the leaves
//! (piecewise-constant cluster means; the lattice's cells have equal solid angles to within
//! a few per cent, so the unweighted sum stands for the integral), for Haar
//! `sqrt(dropped energy / total energy)`. Each is averaged over the vertices whose function
//! is not zero. A term of a cut is a node (index, leftmost leaf, mean); a Haar term is an
//! index and a coefficient.

use crate::{EvalError, Result};
use glam::Vec3;
use rayon::prelude::*;
use relight_bake::cuts::cut::NodeStats;
use relight_bake::cuts::samples::EnvSamples;
use relight_bake::cuts::tree::{LightTree, NodeKind};
use relight_bake::cuts::visibility::{CutFunction, Scratch, VisibilitySampler};
use relight_scene::accel::RayCaster;
use relight_scene::mesh::TriMesh;
use relight_sphere::cubemap::{texel_dir, CubeFace};
use relight_sphere::haar::{truncation_errors, HaarBasis};
use std::collections::BinaryHeap;

/// Term counts of the table.
pub const TERMS: [usize; 7] = [8, 16, 32, 64, 128, 256, 512];

/// One term count: the mean relative L2 error of each approximation.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct TermsRow {
    /// Terms.
    pub terms: usize,
    /// Cut refined in Eq. 6's order (largest `M2` first).
    pub cut_eq6: f64,
    /// Cut refined greedily on the total error.
    pub cut_greedy: f64,
    /// Non-linear Haar approximation.
    pub haar: f64,
    /// Terms the Eq. 6 cut needs to reach `haar`'s error, over `terms` (interpolated; `None`
    /// beyond the curve).
    pub cut_eq6_terms_ratio: Option<f64>,
    /// The same for the greedy cut.
    pub cut_greedy_terms_ratio: Option<f64>,
}

/// What to measure.
#[derive(Clone, Copy)]
pub struct TermsInput<'a> {
    /// The mesh.
    pub mesh: &'a TriMesh,
    /// A caster over it.
    pub caster: &'a dyn RayCaster,
    /// Vertices to sample (spread evenly over the vertex order).
    pub vertices: usize,
    /// Light samples (the bake's).
    pub lights: usize,
    /// Cube face size of the Haar functions (a power of two).
    pub face: usize,
    /// The function.
    pub function: CutFunction,
}

/// Total `M2` of the cut after each refinement, `out[k - 1]` for a cut of `k` nodes,
/// `k = 1..=m_max`; `key(parent, left, right)` orders the refinements (largest first; ties
/// to the lower node).
fn refinement_curve(
    tree: &LightTree,
    stats: &NodeStats,
    m_max: usize,
    key: impl Fn(f32, f32, f32) -> f32,
) -> Vec<f64> {
    let split_key = |i: u32| match tree.node(i).kind {
        NodeKind::Leaf { .. } => f32::NEG_INFINITY,
        NodeKind::Inner { left, right } => key(
            stats.m2[i as usize],
            stats.m2[left as usize],
            stats.m2[right as usize],
        ),
    };
    let mut heap = BinaryHeap::new();
    let root = tree.root();
    heap.push(relight_bake::cuts::cut::Keyed {
        key: split_key(root),
        node: root,
    });
    let mut total = stats.m2[root as usize] as f64;
    let mut out = vec![total];
    while out.len() < m_max {
        let Some(top) = heap.pop() else { break };
        let NodeKind::Inner { left, right } = tree.node(top.node).kind else {
            // Only leaves left: the cut is exact.
            heap.push(top);
            out.push(total);
            continue;
        };
        total += stats.m2[left as usize] as f64 + stats.m2[right as usize] as f64
            - stats.m2[top.node as usize] as f64;
        for c in [left, right] {
            heap.push(relight_bake::cuts::cut::Keyed {
                key: split_key(c),
                node: c,
            });
        }
        out.push(total.max(0.0));
    }
    out
}

/// Terms the decreasing `curve` (error at `k = 1, 2, ..`) needs to reach `target`,
/// interpolated linearly between term counts; `None` if it never does.
fn terms_to_reach(curve: &[f64], target: f64) -> Option<f64> {
    let k = curve.iter().position(|&e| e <= target)?;
    if k == 0 {
        return Some(1.0);
    }
    let (a, b) = (curve[k - 1], curve[k]);
    let t = if a > b { (a - target) / (a - b) } else { 1.0 };
    Some(k as f64 + t)
}

/// Fig. 8a's table for `input` at [`TERMS`].
///
/// # Errors
/// [`EvalError::Options`] for no vertices, a face size that is not a power of two, or a
/// sampler that cannot be built.
pub fn terms_vs_error(input: &TermsInput<'_>) -> Result<Vec<TermsRow>> {
    let bad = |m: String| EvalError::Options(format!("cuts terms: {m}"));
    if input.vertices == 0 || !input.face.is_power_of_two() {
        return Err(bad(format!(
            "{} vertices, face {} (need >= 1 and a power of two)",
            input.vertices, input.face
        )));
    }
    let samples = EnvSamples::fibonacci(input.lights, 0).map_err(|e| bad(e.to_string()))?;
    let tree = LightTree::environment(&samples.dirs).map_err(|e| bad(e.to_string()))?;
    let n = input.face;
    let texels: Vec<Vec3> = CubeFace::ALL
        .iter()
        .flat_map(|&f| (0..n * n).map(move |i| texel_dir(n, f, i / n, i % n)))
        .collect();
    let on_lights = VisibilitySampler::new(input.mesh, input.caster, &samples.dirs, input.function)
        .map_err(|e| bad(e.to_string()))?;
    let on_texels = VisibilitySampler::new(input.mesh, input.caster, &texels, input.function)
        .map_err(|e| bad(e.to_string()))?;
    let haar = HaarBasis::new(n);
    let nv = input.mesh.vertex_count();
    let count = input.vertices.min(nv);
    let m_max = *TERMS.last().expect("terms");
    // Per vertex: the three curves of relative errors at k = 1..=m_max, or None (zero).
    let curves: Vec<[Vec<f64>; 3]> = (0..count)
        .into_par_iter()
        .filter_map(|j| {
            let v = j * nv / count;
            let mut s = Scratch::default();
            let mut x = vec![0.0f32; samples.dirs.len()];
            on_lights.sample(v, &mut x, &mut s);
            let energy: f64 = x.iter().map(|&a| (a as f64) * (a as f64)).sum();
            let mut t = vec![0.0f32; texels.len()];
            on_texels.sample(v, &mut t, &mut s);
            if energy == 0.0 || t.iter().all(|&a| a == 0.0) {
                return None;
            }
            let mut stats = NodeStats::default();
            stats.compute(&tree, &x);
            let rel = |c: Vec<f64>| c.into_iter().map(|m2| (m2 / energy).sqrt()).collect();
            let eq6 = rel(refinement_curve(&tree, &stats, m_max, |p, _, _| p));
            let greedy = rel(refinement_curve(&tree, &stats, m_max, |p, l, r| p - l - r));
            let coeffs = haar.project_values(&t.iter().map(|&a| a as f64).collect::<Vec<_>>());
            let h = truncation_errors(&coeffs, m_max)[1..].to_vec();
            Some([eq6, greedy, h])
        })
        .collect();
    if curves.is_empty() {
        return Err(bad("every sampled vertex sees nothing".into()));
    }
    let mean = |which: usize| -> Vec<f64> {
        (0..m_max)
            .map(|k| {
                curves
                    .iter()
                    .map(|c| c[which][k.min(c[which].len() - 1)])
                    .sum::<f64>()
                    / curves.len() as f64
            })
            .collect()
    };
    let (eq6, greedy, h) = (mean(0), mean(1), mean(2));
    Ok(TERMS
        .iter()
        .map(|&m| TermsRow {
            terms: m,
            cut_eq6: eq6[m - 1],
            cut_greedy: greedy[m - 1],
            haar: h[m - 1],
            cut_eq6_terms_ratio: terms_to_reach(&eq6, h[m - 1]).map(|t| t / m as f64),
            cut_greedy_terms_ratio: terms_to_reach(&greedy, h[m - 1]).map(|t| t / m as f64),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::accel::{build, Backend};

    /// Closed form: the refinement curve's last value equals the cut's M2 summed directly,
    /// and a complete refinement reaches 0.
    #[test]
    fn refinement_curve_tracks_the_cut_error() {
        let samples = EnvSamples::fibonacci(256, 0).unwrap();
        let tree = LightTree::environment(&samples.dirs).unwrap();
        let x: Vec<f32> = samples
            .dirs
            .iter()
            .map(|d| (d.y > 0.3) as u8 as f32 * d.y)
            .collect();
        let mut stats = NodeStats::default();
        stats.compute(&tree, &x);
        let mut heap = vec![];
        for m in [1, 5, 40] {
            let cut = relight_bake::cuts::cut::select_cut(&tree, &stats, 0.0, m, &mut heap);
            let direct: f64 = cut.nodes.iter().map(|&i| stats.m2[i as usize] as f64).sum();
            let curve = refinement_curve(&tree, &stats, m, |p, _, _| p);
            assert_eq!(curve.len(), m);
            let last = curve[m - 1];
            assert!(
                (last - direct).abs() <= 1e-4 * stats.m2[tree.root() as usize] as f64,
                "{m}: {last} vs {direct}"
            );
        }
        // Refined to every leaf, both orders are exact.
        for key in [
            |p: f32, _: f32, _: f32| p,
            |p: f32, l: f32, r: f32| p - l - r,
        ] {
            let full = refinement_curve(&tree, &stats, 256, key);
            assert!(full[255].abs() < 1e-3, "{}", full[255]);
        }
    }

    #[test]
    fn terms_to_reach_interpolates() {
        let c = [1.0, 0.5, 0.25, 0.125];
        assert_eq!(terms_to_reach(&c, 2.0), Some(1.0));
        assert_eq!(terms_to_reach(&c, 0.375), Some(2.5));
        assert_eq!(terms_to_reach(&c, 0.01), None);
    }

    /// On a sphere over a plane: every approximation improves with terms, and the error
    /// tables are consistent (ratios where Haar's error is reached).
    #[test]
    fn errors_fall_with_terms() {
        let mut mesh = relight_scene::shapes::ground_plane(Vec3::ZERO, 4.0, 6);
        mesh.append(
            &relight_scene::shapes::uv_sphere(Vec3::new(0.0, 0.6, 0.0), 0.5, 8, 16),
            0,
        );
        let caster = build(&mesh, Backend::Bvh).unwrap();
        let rows = terms_vs_error(&TermsInput {
            mesh: &mesh,
            caster: caster.as_ref(),
            vertices: 24,
            lights: 2048,
            face: 16,
            function: CutFunction::Visibility,
        })
        .unwrap();
        for w in rows.windows(2) {
            assert!(w[1].cut_eq6 <= w[0].cut_eq6 + 1e-9);
            assert!(w[1].cut_greedy <= w[0].cut_greedy + 1e-9);
            assert!(w[1].haar <= w[0].haar + 1e-9);
        }
        for r in &rows {
            for e in [r.cut_eq6, r.cut_greedy, r.haar] {
                assert!((0.0..=1.0).contains(&e), "{r:?}");
            }
        }
        // 512 terms of 2048 leaves and of 1536 texels: both well below their 8-term error.
        assert!(rows[6].cut_eq6 < 0.5 * rows[0].cut_eq6 && rows[6].haar < 0.5 * rows[0].haar);
    }
}
