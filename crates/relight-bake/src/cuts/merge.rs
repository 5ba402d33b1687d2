//! Merging cuts in one linear traversal (Cheslack-Postava et al. 2008, sec. 3.2, the
//! pseudo-code of "Algorithm for merging cuts"; sec. 4.2 for its per-pixel use).
//!
//! Every cut lists its nodes in increasing post-order index (left to right). The traversal
//! keeps one current node per cut; at each step the smallest current index is the deepest
//! candidate cluster, and the current nodes all overlap exactly when the largest current
//! leftmost leaf is at most that index (a node covers `[leftleaf, index]`). When they do,
//! that deepest node is a cluster `C'_k` of the **merged cut** (the union of the cuts: the
//! deepest nodes of all of them), of size `|C'_k| = (index - leftleaf) / 2 + 1`, and each cut
//! contributes its current node's mean. Then every cut whose current index is the smallest
//! advances; the traversal ends when one cut runs out (they all end together). Cost:
//! `O(N m)` for `N` cuts of length `m` at worst, `O(m)` for identical cuts (sec. 3.3).
//!
//! [`merge_cuts`] is that traversal for a compile-time number of cuts, calling a visitor with
//! the merged cluster and each cut's current position; sums ([`interpolate`]) and products
//! ([`product`], [`shade`], Eq. 4-5) are visitors. The slow references of the tests expand
//! every cut to the leaves.

use super::cut::{dequantise, CutRef};
use super::light_cut::LightCut;
use glam::Vec3;

/// The part of a cut the traversal reads: post-order indices (increasing) and leftmost
/// leaves, same length, non-empty.
#[derive(Clone, Copy, Debug)]
pub struct CutKeys<'a> {
    /// Node indices, increasing.
    pub index: &'a [u32],
    /// Leftmost leaf of each node.
    pub leftleaf: &'a [u32],
}

impl<'a> From<CutRef<'a>> for CutKeys<'a> {
    fn from(c: CutRef<'a>) -> Self {
        CutKeys {
            index: c.index,
            leftleaf: c.leftleaf,
        }
    }
}

impl<'a> From<&'a LightCut> for CutKeys<'a> {
    fn from(c: &'a LightCut) -> Self {
        CutKeys {
            index: &c.index,
            leftleaf: &c.leftleaf,
        }
    }
}

/// A cluster of the merged cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MergedNode {
    /// Post-order index of the cluster's node (the deepest current node).
    pub index: u32,
    /// Its leftmost leaf.
    pub leftleaf: u32,
}

impl MergedNode {
    /// Number of lights in the cluster, `|C'_k|` (a complete binary subtree of `s` nodes has
    /// `(s + 1) / 2` leaves).
    #[inline]
    pub fn leaves(&self) -> u32 {
        (self.index - self.leftleaf) / 2 + 1
    }
}

/// Visit every cluster of the merged cut of `cuts` in left-to-right order, with the
/// position in each cut of the node containing it (the pseudo-code of sec. 3.2).
///
/// # Panics
/// Debug builds: a cut empty or its arrays of different lengths.
#[inline]
pub fn merge_cuts<const N: usize>(
    cuts: [CutKeys<'_>; N],
    mut visit: impl FnMut(MergedNode, [usize; N]),
) {
    if N == 0 {
        return;
    }
    for c in &cuts {
        debug_assert!(!c.index.is_empty() && c.index.len() == c.leftleaf.len());
    }
    let mut pos = [0usize; N];
    // Each cut's current node, reloaded only when the cut advances.
    let mut index = cuts.map(|c| c.index[0]);
    let mut leftleaf = cuts.map(|c| c.leftleaf[0]);
    loop {
        let mut min_index = u32::MAX;
        let mut max_leftleaf = 0u32;
        for j in 0..N {
            min_index = min_index.min(index[j]);
            max_leftleaf = max_leftleaf.max(leftleaf[j]);
        }
        if max_leftleaf <= min_index {
            // All current nodes overlap: the deepest one is a merged cluster.
            visit(
                MergedNode {
                    index: min_index,
                    leftleaf: max_leftleaf,
                },
                pos,
            );
        }
        let mut done = false;
        for j in 0..N {
            // Branch-free advance; a cut that ran out ends the traversal (all end together).
            pos[j] += (index[j] == min_index) as usize;
            let p = pos[j].min(cuts[j].index.len() - 1);
            done |= pos[j] == cuts[j].index.len();
            index[j] = cuts[j].index[p];
            leftleaf[j] = cuts[j].leftleaf[p];
        }
        if done {
            return;
        }
    }
}

/// `sum_k |C'_k| prod_j values_j[pos_j]`: the multi-product integral of `N` cuts whose node
/// means are `values[j]` (parallel to the cut's nodes), accumulated in f64.
pub fn product<const N: usize>(cuts: [CutKeys<'_>; N], values: [&[f32]; N]) -> f64 {
    let mut sum = 0.0f64;
    merge_cuts(cuts, |node, pos| {
        let mut p = node.leaves() as f64;
        for j in 0..N {
            p *= values[j][pos[j]] as f64;
        }
        sum += p;
    });
    sum
}

/// Linear interpolation `sum_j w_j cut_j` of `N` quantised cuts as a new cut: the merged
/// clusters (indices, leftmost leaves) and their interpolated means.
pub fn interpolate<const N: usize>(
    cuts: [CutRef<'_>; N],
    weights: [f32; N],
) -> (Vec<MergedNode>, Vec<f32>) {
    let (mut nodes, mut means) = (Vec::new(), Vec::new());
    merge_cuts(cuts.map(CutKeys::from), |node, pos| {
        nodes.push(node);
        means.push(
            (0..N)
                .map(|j| weights[j] * dequantise(cuts[j].value[pos[j]]))
                .sum(),
        );
    });
    (nodes, means)
}

/// One pixel of Eq. 5 with per-pixel interpolation (sec. 4.2): the light cut, three vertex
/// visibility cuts interpolated with barycentric weights `bary`, and the BRDF `brdf(w)`
/// (without the cosine, which the visibility holds) sampled at each merged cluster's
/// direction ([`LightCut::direction`]: its lights' luminance-weighted mean direction), all in
/// one traversal: `B = sum_k |C'_k| <l>_k (sum_j bary_j <v_j>_k) f_r(<w>_k)`. `brdf` gives
/// `f_r` as its `[glossy, diffuse]` lobes; with `spread`, the glossy lobe is averaged over
/// each cluster ([`LightCut::spread_lobes`]).
pub fn shade(
    light: &LightCut,
    vertices: [CutRef<'_>; 3],
    bary: [f32; 3],
    spread: bool,
    mut brdf: impl FnMut(Vec3) -> [Vec3; 2],
) -> Vec3 {
    let keys = [
        CutKeys::from(light),
        vertices[0].into(),
        vertices[1].into(),
        vertices[2].into(),
    ];
    let mut sum = Vec3::ZERO;
    merge_cuts(keys, |node, pos| {
        let v = bary[0] * dequantise(vertices[0].value[pos[1]])
            + bary[1] * dequantise(vertices[1].value[pos[2]])
            + bary[2] * dequantise(vertices[2].value[pos[3]]);
        if v > 0.0 {
            let l = light.value[pos[0]] * node.leaves() as f32;
            let f = if spread {
                light.spread_lobes(node.index, &mut brdf)
            } else {
                let [glossy, diffuse] = brdf(light.direction(node.index));
                glossy + diffuse
            };
            sum += l * v * f;
        }
    });
    sum
}

#[cfg(test)]
mod tests;
