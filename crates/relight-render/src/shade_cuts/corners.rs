//! Per-corner cluster lists: how [`super::CutsShader::render`] shades Lambert materials
//! (Cheslack-Postava et al. 2008, Eq. 5 of sec. 4.2 summed corner by corner; the merge of
//! sec. 3.2 done once per light cut instead of once per triangle or pixel).
//!
//! Eq. 5 at a fragment with barycentric weights `b_j` of its triangle's corners sums over the
//! clusters `C'_k` of the merged cut of the light cut and the three vertex cuts:
//! `B = sum_k |C'_k| <L O>_k (sum_j b_j <v_j>_k) f(<w>_k)`. Summed by corner instead,
//!
//! `B ~ sum_j b_j sum_{k in W_j} |C_k| <L O>_k <v_j>_k f(<w>_k)`,
//!
//! where `W_j` is corner `j`'s own cut merged with the light cut (two cuts, not four). `W_j`
//! depends on the vertex and the light cut only, neither on the camera nor on the material,
//! so it is merged once per light cut (per environment and rotation) for every vertex
//! ([`CornerLists::build`], cached by the shader) and a fragment sums its three corners'
//! lists with no merge at all. Nothing of the BRDF is stored: the albedo and the cosine
//! `max(0, n . w)` at the fragment's normal are applied per fragment.
//!
//! **What differs from the merged cut**: `<L O>` and `<v_j>` are constant over a node's
//! sub-clusters, so the terms are the same except that corner `j`'s BRDF is sampled at the
//! clusters of `W_j` instead of at the (finer or equal) clusters of the triangle's merged
//! cut. For Lambert over cuts holding the cosine the BRDF is the same for every cluster and
//! both sums are equal (tested); over binary visibility only the cosine's sampling changes,
//! and the frame is no further from the path tracer than the merged one (tested; on the
//! bunny the two frames differ by 2e-5 to 7e-5 relative RMS). Glossy
//! lobes are not shaded this way: sampled at the corners' coarser clusters they measured up
//! to 8 % further from the path tracer (a GGX conductor at a 64-node light cut).
//!
//! **Layout**: per vertex, groups of [`LANES`] clusters (`[f32; 8]` per channel and axis, which
//! the compiler vectorises), the last padded with zero clusters (no power, direction zero);
//! clusters the vertex does not see (`<v> = 0`) or that hold no light are dropped. An AVX2
//! copy of the sum chosen at run time measured no faster (the frame is not bound by it), so
//! there is none.

use glam::Vec3;
use rayon::prelude::*;
use relight_bake::cuts::cut::{dequantise, VertexCuts};
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::merge::{merge_cuts, CutKeys};

/// Lanes of the per-fragment sums (independent partial sums, one SIMD register each).
pub(crate) const LANES: usize = 8;

/// Vertices merged per parallel task of [`CornerLists::build`] (and per stored part).
const CHUNK: usize = 512;

/// Eight clusters of one vertex list: `|C| <L O> <v>` per colour channel and the direction
/// per axis, lane `l` being cluster `8 i + l` of the list.
#[derive(Clone, Copy, Default)]
struct Group {
    power: [[f32; LANES]; 3],
    dir: [[f32; LANES]; 3],
}

/// Every vertex's cut merged with one light cut (module docs): per cluster `|C| <L O> <v>`
/// (RGB) and the light cut's direction of the cluster's node ([`LightCut::direction`]).
pub(super) struct CornerLists {
    /// The lists of vertices `CHUNK c..CHUNK (c + 1)` in part `c` (built in parallel and
    /// kept apart: no copy into one array).
    parts: Vec<Part>,
}

/// The lists of [`CHUNK`] consecutive vertices.
#[derive(Default)]
struct Part {
    /// First group of each vertex, `vertices + 1` entries.
    start: Vec<u32>,
    /// Clusters of each vertex before padding.
    count: Vec<u32>,
    /// The groups, each vertex's padded with zero clusters.
    groups: Vec<Group>,
    /// `sum_k |C_k| <L O>_k <v>_k` per vertex (Eq. 5 for a constant BRDF).
    sums: Vec<Vec3>,
}

impl CornerLists {
    /// Merge every cut of `cuts` with `light` (in parallel over vertices), in the arrays of
    /// `reuse` if given (the previous light cut's lists: no new pages to fault in and clear,
    /// no reallocation once they are large enough).
    ///
    /// # Panics
    /// Debug builds: a cut of another light tree than `light`'s.
    pub(super) fn build(cuts: &VertexCuts, light: &LightCut, reuse: Option<Self>) -> Self {
        let n = cuts.vertex_count();
        let mut parts = reuse.map_or_else(Vec::new, |r| r.parts);
        parts.resize_with(n.div_ceil(CHUNK), Part::default);
        parts.par_iter_mut().enumerate().for_each(|(c, p)| {
            p.fill(cuts, light, c * CHUNK..((c + 1) * CHUNK).min(n));
        });
        CornerLists { parts }
    }

    /// Bytes held (what the shader's cache costs).
    pub(super) fn bytes(&self) -> usize {
        let part = |p: &Part| {
            4 * (p.start.len() + p.count.len())
                + std::mem::size_of::<Group>() * p.groups.len()
                + 12 * p.sums.len()
        };
        self.parts.iter().map(part).sum()
    }

    /// Mean clusters per vertex before padding.
    pub(super) fn mean_len(&self) -> f64 {
        let (c, n) = self.parts.iter().fold((0u64, 0usize), |(c, n), p| {
            (
                c + p.count.iter().map(|&x| x as u64).sum::<u64>(),
                n + p.count.len(),
            )
        });
        c as f64 / n.max(1) as f64
    }

    /// `sum_k |C_k| <L O>_k <v>_k` of vertex `v`.
    #[inline]
    pub(super) fn sum(&self, v: u32) -> Vec3 {
        let v = v as usize;
        self.parts[v / CHUNK].sums[v % CHUNK]
    }

    /// `sum_k |C_k| <L O>_k <v>_k max(0, n . w_k)` over vertex `v`'s list: Eq. 5 for a
    /// Lambert BRDF over binary visibility cuts, without its `albedo / pi`, over [`LANES`]
    /// partial sums.
    #[inline]
    pub(super) fn lambert(&self, v: u32, n: Vec3) -> Vec3 {
        let v = v as usize;
        let p = &self.parts[v / CHUNK];
        let (a, b) = (p.start[v % CHUNK] as usize, p.start[v % CHUNK + 1] as usize);
        let mut acc = [[0.0f32; LANES]; 3];
        for g in &p.groups[a..b] {
            let d = &g.dir;
            for l in 0..LANES {
                let c = (n.x * d[0][l] + n.y * d[1][l] + n.z * d[2][l]).max(0.0);
                for (a, p) in acc.iter_mut().zip(&g.power) {
                    a[l] += p[l] * c;
                }
            }
        }
        Vec3::from_array(acc.map(|a| a.iter().sum()))
    }
}

impl Part {
    /// Replace the lists by those of vertices `range`.
    fn fill(&mut self, cuts: &VertexCuts, light: &LightCut, range: std::ops::Range<usize>) {
        let out = self;
        out.start.clear();
        out.start.push(0);
        out.count.clear();
        out.groups.clear();
        out.sums.clear();
        for v in range {
            let cut = cuts.cut(v);
            debug_assert!(
                cut.index
                    .last()
                    .is_some_and(|&i| (i as usize) < light.dirs.len()),
                "vertex {v}: a cut of another tree than the light cut's"
            );
            let mut sum = Vec3::ZERO;
            let mut k = 0;
            let first = out.groups.len();
            merge_cuts([CutKeys::from(light), cut.into()], |node, pos| {
                let q = cut.value[pos[1]];
                let power = light.value[pos[0]] * node.leaves() as f32;
                if q == 0 || power == Vec3::ZERO {
                    return; // adds nothing
                }
                let p = power * dequantise(q);
                let d = light.direction(node.index);
                if k % LANES == 0 {
                    out.groups.push(Group::default());
                }
                let g = out.groups.last_mut().expect("pushed");
                for ch in 0..3 {
                    g.power[ch][k % LANES] = p[ch];
                    g.dir[ch][k % LANES] = d[ch];
                }
                sum += p;
                k += 1;
            });
            debug_assert_eq!(out.groups.len() - first, k.div_ceil(LANES));
            out.start.push(out.groups.len() as u32);
            out.count.push(k as u32);
            out.sums.push(sum);
        }
    }
}
