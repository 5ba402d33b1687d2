//! Cuts through the light tree: cluster statistics, cut selection, sparse storage
//! (Cheslack-Postava et al. 2008, sec. 3.2 "Algorithm for selecting a cut", Eq. 3 and 6).
//!
//! A function `x` sampled at every leaf is summarised at every node by its cluster mean
//! `<x>` (Eq. 3) and `M2 = sum (x_i - <x>)^2 = |C| var(x)` ([`NodeStats`]), propagated up the
//! post-order array in one forward pass with Chan et al.'s pairwise update (children precede
//! their parent): `M2 = M2_a + M2_b + delta^2 n_a n_b / n`, which never cancels the way
//! `sum x^2 - n <x>^2` does.
//!
//! [`select_cut`] starts from the root and repeatedly replaces the cut node of largest error
//! by its two children until every node satisfies Eq. 6, `|C| var <= sigma^2`, i.e.
//! `M2 <= sigma^2`, or the cut reaches its cap (1000 nodes by default, as in the paper after
//! Walter et al. 2005): such a cut is flagged, never silently truncated. Leaves have `M2 = 0`,
//! so refinement always terminates. Ties in error go to the lower node index (deterministic).
//!
//! [`VertexCuts`] stores the cuts of many vertices sparse, as the paper's GPU textures do:
//! per cut node its post-order index, its leftmost leaf and its mean quantised to 16 bits.

use super::tree::{LightTree, NodeKind};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// The paper's cap on a cut's length (after Walter et al. 2005).
pub const DEFAULT_MAX_CUT: usize = 1000;
/// Default `sigma` of Eq. 6 (the paper: "typically 1.5~3.0").
pub const DEFAULT_SIGMA: f32 = 2.0;
/// Quantisation scale of stored means: `q = round(QUANT v)` for `v` in `[0, 1]`.
pub const QUANT: f32 = 65535.0;

/// Cluster mean and `M2 = |C| var` of a leaf function at every node (post-order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeStats {
    /// `<x>` per node.
    pub mean: Vec<f32>,
    /// `sum (x_i - <x>)^2` per node (`|C| var(x)`, the left side of Eq. 6).
    pub m2: Vec<f32>,
}

impl NodeStats {
    /// Statistics of `values[light]` (one per light) over `tree`, reusing `self`'s storage.
    ///
    /// # Panics
    /// If `values` is shorter than the tree's light count.
    pub fn compute(&mut self, tree: &LightTree, values: &[f32]) {
        let nodes = tree.nodes();
        self.mean.clear();
        self.m2.clear();
        for node in nodes {
            let (mean, m2) = match node.kind {
                NodeKind::Leaf { light } => (values[light as usize], 0.0),
                NodeKind::Inner { left, right } => {
                    let (a, b) = (left as usize, right as usize);
                    let (na, nb) = (nodes[a].leaves as f32, nodes[b].leaves as f32);
                    let n = na + nb;
                    let delta = self.mean[b] - self.mean[a];
                    let mean = self.mean[a] + delta * (nb / n);
                    let m2 = self.m2[a] + self.m2[b] + delta * delta * (na * nb / n);
                    (mean, m2)
                }
            };
            self.mean.push(mean);
            self.m2.push(m2);
        }
    }
}

/// A refinement-queue entry (scratch of [`select_cut`]): ordered by larger key first, then
/// lower node index, so refinement is deterministic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyed {
    /// The priority (a node's error or intensity).
    pub key: f32,
    /// Post-order node index.
    pub node: u32,
}

impl Eq for Keyed {}

impl Ord for Keyed {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key
            .total_cmp(&other.key)
            .then(other.node.cmp(&self.node))
    }
}

impl PartialOrd for Keyed {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// A selected cut: node indices in increasing order, and whether refinement stopped at the
/// cap with a node still above the threshold.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SelectedCut {
    /// Post-order indices, increasing (= left to right).
    pub nodes: Vec<u32>,
    /// The cap was reached before every node satisfied Eq. 6.
    pub capped: bool,
}

/// Refine from the root until every node has `M2 <= sigma2` (Eq. 6) or the cut has
/// `max_nodes` nodes (then `capped`). `heap` is scratch.
///
/// # Panics
/// Debug builds: `max_nodes == 0` or a negative `sigma2`.
pub fn select_cut(
    tree: &LightTree,
    stats: &NodeStats,
    sigma2: f32,
    max_nodes: usize,
    heap: &mut Vec<Keyed>,
) -> SelectedCut {
    debug_assert!(max_nodes >= 1 && sigma2 >= 0.0);
    let mut h = BinaryHeap::from(std::mem::take(heap));
    h.clear();
    let root = tree.root();
    h.push(Keyed {
        key: stats.m2[root as usize],
        node: root,
    });
    let mut capped = false;
    while let Some(&top) = h.peek() {
        if top.key <= sigma2 {
            break;
        }
        if h.len() >= max_nodes {
            capped = true;
            break;
        }
        h.pop();
        let NodeKind::Inner { left, right } = tree.node(top.node).kind else {
            unreachable!("a leaf has M2 = 0 <= sigma^2")
        };
        for c in [left, right] {
            h.push(Keyed {
                key: stats.m2[c as usize],
                node: c,
            });
        }
    }
    let mut nodes: Vec<u32> = h.iter().map(|k| k.node).collect();
    nodes.sort_unstable();
    *heap = h.into_vec();
    SelectedCut { nodes, capped }
}

/// Quantise a mean in `[0, 1]` to 16 bits (values a rounding error outside are clamped).
///
/// # Panics
/// Debug builds: `v` outside `[-1e-4, 1 + 1e-4]` or NaN.
#[inline]
pub fn quantise(v: f32) -> u16 {
    debug_assert!((-1e-4..=1.0 + 1e-4).contains(&v), "mean {v} outside [0, 1]");
    (v.clamp(0.0, 1.0) * QUANT).round() as u16
}

/// The value of a quantised mean.
#[inline]
pub fn dequantise(q: u16) -> f32 {
    q as f32 * (1.0 / QUANT)
}

/// The cuts of many vertices, sparse (CSR): vertex `v`'s cut is entries
/// `offsets[v]..offsets[v + 1]` of the three parallel arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexCuts {
    /// `vertex_count + 1` offsets, from 0, non-decreasing.
    pub offsets: Vec<u64>,
    /// Post-order node index of each entry.
    pub index: Vec<u32>,
    /// Leftmost leaf of each entry's node (the paper stores it beside the index).
    pub leftleaf: Vec<u32>,
    /// Cluster mean of each entry, quantised ([`quantise`]).
    pub value: Vec<u16>,
    /// Vertices whose cut hit the cap with a node still above the threshold.
    pub capped: Vec<u32>,
}

/// One vertex's cut as borrowed slices.
#[derive(Clone, Copy, Debug)]
pub struct CutRef<'a> {
    /// Post-order indices, increasing.
    pub index: &'a [u32],
    /// Leftmost leaves.
    pub leftleaf: &'a [u32],
    /// Quantised means.
    pub value: &'a [u16],
}

/// Why a [`VertexCuts`] is inconsistent with its tree.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CutError {
    /// The CSR arrays disagree in length or offsets are not monotone from 0.
    #[error("cut arrays are inconsistent: {0}")]
    Layout(String),
    /// A vertex's cut is not a cut of the tree (the message says why).
    #[error("vertex {vertex}: {problem}")]
    Vertex {
        /// The vertex.
        vertex: usize,
        /// The broken invariant.
        problem: &'static str,
    },
}

impl VertexCuts {
    /// Append `other`'s vertices after this one's (offsets and capped vertices rebased): the
    /// cuts of consecutive vertex ranges put together.
    pub fn append(&mut self, other: VertexCuts) {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        let (base_v, base_e) = (self.vertex_count() as u32, self.index.len() as u64);
        self.offsets
            .extend(other.offsets.iter().skip(1).map(|&o| o + base_e));
        self.index.extend(other.index);
        self.leftleaf.extend(other.leftleaf);
        self.value.extend(other.value);
        self.capped.extend(other.capped.iter().map(|&v| v + base_v));
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Vertex `v`'s cut.
    pub fn cut(&self, v: usize) -> CutRef<'_> {
        let r = self.offsets[v] as usize..self.offsets[v + 1] as usize;
        CutRef {
            index: &self.index[r.clone()],
            leftleaf: &self.leftleaf[r.clone()],
            value: &self.value[r],
        }
    }

    /// Append a vertex's cut: the selected nodes with their means from `stats`.
    pub fn push(&mut self, tree: &LightTree, cut: &SelectedCut, stats: &NodeStats) {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        if cut.capped {
            self.capped.push(self.vertex_count() as u32);
        }
        for &p in &cut.nodes {
            self.index.push(p);
            self.leftleaf.push(tree.node(p).leftleaf);
            self.value.push(quantise(stats.mean[p as usize]));
        }
        self.offsets.push(self.index.len() as u64);
    }

    /// Mean cut length over the vertices (0 for none).
    pub fn mean_len(&self) -> f64 {
        self.index.len() as f64 / self.vertex_count().max(1) as f64
    }

    /// Check every invariant against `tree`: CSR layout; every cut non-empty, indices
    /// increasing and inside the tree, stored leftmost leaves equal the tree's, nodes tiling
    /// the leaves left to right exactly once; capped vertices increasing and in range.
    ///
    /// # Errors
    /// The first broken invariant.
    pub fn validate(&self, tree: &LightTree) -> Result<(), CutError> {
        let layout = |m: String| Err(CutError::Layout(m));
        if self.offsets.first() != Some(&0) {
            return layout("offsets must start at 0".into());
        }
        if self.offsets.windows(2).any(|w| w[0] > w[1]) {
            return layout("offsets decrease".into());
        }
        let n = self.index.len();
        if self.offsets.last() != Some(&(n as u64))
            || self.leftleaf.len() != n
            || self.value.len() != n
        {
            return layout(format!(
                "{} indices, {} leftleaves, {} values, last offset {:?}",
                n,
                self.leftleaf.len(),
                self.value.len(),
                self.offsets.last()
            ));
        }
        let vc = self.vertex_count();
        if self.capped.windows(2).any(|w| w[0] >= w[1])
            || self.capped.iter().any(|&v| v as usize >= vc)
        {
            return layout("capped vertices not increasing or out of range".into());
        }
        let nodes = tree.nodes();
        for v in 0..vc {
            let bad = |problem| Err(CutError::Vertex { vertex: v, problem });
            let cut = self.cut(v);
            if cut.index.is_empty() {
                return bad("empty cut");
            }
            let mut next_rank = 0u32;
            let mut prev: Option<u32> = None;
            for (&p, &ll) in cut.index.iter().zip(cut.leftleaf) {
                if p as usize >= nodes.len() {
                    return bad("node index outside the tree");
                }
                if prev.is_some_and(|q| q >= p) {
                    return bad("node indices not increasing");
                }
                prev = Some(p);
                let node = &nodes[p as usize];
                if node.leftleaf != ll {
                    return bad("stored leftleaf differs from the tree's");
                }
                if node.first != next_rank {
                    return bad("nodes do not tile the leaves (gap or overlap)");
                }
                next_rank += node.leaves;
            }
            if next_rank as usize != tree.light_count() {
                return bad("nodes do not cover every leaf");
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cuts::samples::fibonacci_point;
    use glam::Vec3;
    use relight_sphere::warp::Rng;

    fn tree(n: usize) -> LightTree {
        let d: Vec<Vec3> = (0..n).map(|i| fibonacci_point(i, n)).collect();
        LightTree::environment(&d).unwrap()
    }

    /// Mean and M2 of a node straight from its leaves (the slow reference).
    fn stats_slow(t: &LightTree, values: &[f32], p: u32) -> (f64, f64) {
        let order = t.lights_in_order();
        let node = t.node(p);
        let xs: Vec<f64> = order[node.first as usize..(node.first + node.leaves) as usize]
            .iter()
            .map(|&l| values[l as usize] as f64)
            .collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        (mean, xs.iter().map(|x| (x - mean) * (x - mean)).sum())
    }

    #[test]
    fn propagated_stats_match_leaves() {
        let t = tree(777);
        let mut rng = Rng::new(4, 4);
        let values: Vec<f32> = (0..777).map(|_| rng.next_f32()).collect();
        let mut s = NodeStats::default();
        s.compute(&t, &values);
        for p in 0..t.nodes().len() as u32 {
            let (m, m2) = stats_slow(&t, &values, p);
            // f32 pairwise updates: relative 1e-5 of the sums involved.
            assert!((s.mean[p as usize] as f64 - m).abs() < 1e-5, "node {p}");
            assert!(
                (s.m2[p as usize] as f64 - m2).abs() < 1e-4 * (1.0 + m2),
                "node {p}"
            );
        }
    }

    #[test]
    fn cut_satisfies_eq6_and_is_minimal_along_its_path() {
        let t = tree(2048);
        // A function with a hard edge and a smooth ramp: visibility-like.
        let d: Vec<Vec3> = (0..2048).map(|i| fibonacci_point(i, 2048)).collect();
        let values: Vec<f32> = d
            .iter()
            .map(|w| if w.x > 0.3 { 0.0 } else { w.y.max(0.0) })
            .collect();
        let mut s = NodeStats::default();
        s.compute(&t, &values);
        for sigma in [0.5f32, 1.5, 3.0] {
            let cut = select_cut(&t, &s, sigma * sigma, 100_000, &mut Vec::new());
            assert!(!cut.capped);
            let mut vc = VertexCuts::default();
            vc.push(&t, &cut, &s);
            vc.validate(&t).unwrap();
            for &p in &cut.nodes {
                assert!(s.m2[p as usize] <= sigma * sigma);
            }
            // Every cut node's parent needed splitting (the cut is no finer than needed).
            for &p in &cut.nodes {
                if p == t.root() {
                    continue;
                }
                let parent = (p + 1..t.nodes().len() as u32)
                    .find(|&q| match t.node(q).kind {
                        NodeKind::Inner { left, right } => left == p || right == p,
                        NodeKind::Leaf { .. } => false,
                    })
                    .unwrap();
                assert!(s.m2[parent as usize] > sigma * sigma);
            }
        }
    }

    #[test]
    fn cap_is_reported_and_zero_gives_one_node() {
        let t = tree(4096);
        let mut rng = Rng::new(8, 8);
        // Pure noise: needs nearly every leaf at sigma 0.1.
        let noise: Vec<f32> = (0..4096).map(|_| rng.next_f32()).collect();
        let mut s = NodeStats::default();
        s.compute(&t, &noise);
        let cut = select_cut(&t, &s, 0.01, DEFAULT_MAX_CUT, &mut Vec::new());
        assert!(cut.capped);
        assert_eq!(cut.nodes.len(), DEFAULT_MAX_CUT);
        let mut vc = VertexCuts::default();
        vc.push(&t, &cut, &s);
        // A vertex that sees nothing: one zero node, the root.
        s.compute(&t, &vec![0.0; 4096]);
        let zero = select_cut(&t, &s, 0.0, DEFAULT_MAX_CUT, &mut Vec::new());
        assert_eq!(zero.nodes, vec![t.root()]);
        assert!(!zero.capped);
        vc.push(&t, &zero, &s);
        vc.validate(&t).unwrap();
        assert_eq!(vc.capped, vec![0]);
        assert_eq!(vc.cut(1).value, &[0]);
        assert_eq!(vc.vertex_count(), 2);
    }

    #[test]
    fn quantisation_round_trip() {
        for k in 0..=1000 {
            let v = k as f32 / 1000.0;
            // Half a quantisation step.
            assert!((dequantise(quantise(v)) - v).abs() <= 0.5 / QUANT + 1e-7);
        }
        assert_eq!(quantise(1.0), u16::MAX);
        assert_eq!(quantise(0.0), 0);
    }

    #[test]
    fn validate_catches_breakage() {
        let t = tree(64);
        let mut s = NodeStats::default();
        let values: Vec<f32> = (0..64).map(|i| (i % 3) as f32 / 2.0).collect();
        s.compute(&t, &values);
        let cut = select_cut(&t, &s, 0.1, 1000, &mut Vec::new());
        assert!(cut.nodes.len() > 3);
        let mut vc = VertexCuts::default();
        vc.push(&t, &cut, &s);
        vc.validate(&t).unwrap();
        let mut b = vc.clone();
        b.index.swap(0, 1);
        assert!(b.validate(&t).is_err());
        let mut b = vc.clone();
        b.leftleaf[1] += 1;
        assert!(b.validate(&t).is_err());
        let mut b = vc.clone();
        // Dropping a node leaves a gap.
        b.index.remove(1);
        b.leftleaf.remove(1);
        b.value.remove(1);
        *b.offsets.last_mut().unwrap() -= 1;
        assert!(b.validate(&t).is_err());
        let mut b = vc.clone();
        b.value.pop();
        assert!(b.validate(&t).is_err());
        let mut b = vc;
        b.capped = vec![3];
        assert!(b.validate(&t).is_err());
    }
}
