//! The light tree (Cheslack-Postava et al. 2008, sec. 3.1, 3.2, 3.4).
//!
//! A complete binary tree over `N >= 2` lights, built top-down: every cluster of `n` lights
//! splits into a left child of `ceil(n / 2)` lights and a right child of `floor(n / 2)`. The
//! split is a balanced 2-means: two centres (the light farthest from the cluster's mean, then
//! the light farthest from it), the lights sorted by `d(s, c1) - d(s, c2)` and cut in the
//! middle, centres moved to the halves' means, repeated until the halves stop changing (at
//! most [`SPLIT_ITERATIONS`] times). Ties are broken by light index: the tree depends on its
//! input only.
//!
//! Distances (all squared Euclidean in a weighted feature space, so a cluster's centre is the
//! mean of its members' features):
//! * geometric, Eq. 11: `d_g(s, c) = K^2 / d^2 |x_s - <x_c>|^2 + |n_s - <n_c>|^2`, with `d` the
//!   diagonal of the lights' bounding box and `K` = [`DEFAULT_K`] = 30;
//! * data-driven, Eq. 12: `d_v(s, c) = (K + 1)^2 / M |l_s - <l_c>|^2`, `l_s` the light's pilot
//!   visibility vector over `M` vertex clusters ([`PilotVectors`]);
//! * mixed, Eq. 13: `d = (1 - beta) d_v + beta d_g`, `beta` = [`DEFAULT_BETA`].
//!
//! **Deviation from Eq. 12**: the paper also multiplies `d_v` by `A^2`, `A = 4 pi / N` the
//! solid angle of a light, to "normalise it to `d_g`". With `l` the mean visibility in `[0, 1]`
//! (as here) and 32K lights, that factor makes `d_v` about 1e-7 of `d_g` and `beta` would have
//! no effect; without it, both distances range over the same few hundreds (`d_g` up to
//! `4 K^2 / d^2 + 4`, `d_v` up to `(K + 1)^2`), which is the normalisation the paper intends.
//!
//! Environment lights are points on the unit sphere with normal `-w` (facing the scene), so
//! their normal term repeats the position term.
//!
//! Storage is linear in post-order ([`LightTree::nodes`]; see the conventions of
//! [`crate::cuts`]). [`LightTree::validate`] checks every invariant.

use super::CutsError;
use glam::Vec3;

/// `K` of Eq. 11-12 (the paper: "a default value of 30 always gives good results").
pub const DEFAULT_K: f32 = 30.0;
/// `beta` of Eq. 13: the paper's 0.4-0.5 balances compression and light-cut length.
pub const DEFAULT_BETA: f32 = 0.5;
/// Vertex clusters `M` of the pilot visibility vectors (the paper's 1024).
pub const DEFAULT_VERTEX_CLUSTERS: usize = 1024;
/// Largest number of 2-means iterations per split.
pub const SPLIT_ITERATIONS: usize = 8;

/// What a node is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeKind {
    /// A leaf: one light.
    Leaf {
        /// Index of the light (into the arrays the tree was built from).
        light: u32,
    },
    /// A cluster with two children (post-order indices, both below the node's).
    Inner {
        /// Left child.
        left: u32,
        /// Right child (always the node's index minus one).
        right: u32,
    },
}

/// One node of the post-order array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TreeNode {
    /// Post-order index of the node's leftmost leaf: the node covers `[leftleaf, index]`.
    pub leftleaf: u32,
    /// Number of lights in the cluster, `|C|`.
    pub leaves: u32,
    /// Rank (left to right, from 0) of the node's leftmost leaf among all leaves: the node's
    /// lights are the leaves of ranks `first..first + leaves`.
    pub first: u32,
    /// Leaf or inner node.
    pub kind: NodeKind,
}

/// Why a [`LightTree`] breaks an invariant ([`LightTree::validate`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TreeError {
    /// Array sizes disagree with the light count.
    #[error("tree of {lights} lights has {nodes} nodes (needs 2 N - 1 and N >= 2)")]
    Size {
        /// Lights.
        lights: usize,
        /// Nodes.
        nodes: usize,
    },
    /// A node breaks an invariant (the message says which).
    #[error("node {node}: {problem}")]
    Node {
        /// Post-order index.
        node: usize,
        /// The invariant.
        problem: &'static str,
    },
}

/// Pilot visibility vectors (sec. 3.4): for every light `i` and vertex cluster `j`, the mean
/// of the vertex visibility function ([`crate::cuts`] conventions) of the cluster's vertices
/// in the light's direction. `data[i * clusters + j]`.
#[derive(Clone, Debug, PartialEq)]
pub struct PilotVectors {
    /// Number of lights.
    pub lights: usize,
    /// Number of vertex clusters `M`.
    pub clusters: usize,
    /// Light-major values in `[0, 1]`.
    pub data: Vec<f32>,
}

/// A complete binary light tree stored in post-order.
#[derive(Clone, Debug, PartialEq)]
pub struct LightTree {
    nodes: Vec<TreeNode>,
    /// Mean light position of every node's cluster.
    centers: Vec<Vec3>,
    /// Representative unit direction of every node ([`LightTree::direction`]), computed once:
    /// the per-pixel merge reads it at every merged cluster.
    dirs: Vec<Vec3>,
    /// Post-order index of each light's leaf.
    leaf_of_light: Vec<u32>,
}

impl LightTree {
    /// The tree over lights at `positions` with unit `normals`, geometric metric (Eq. 11).
    ///
    /// # Errors
    /// [`CutsError::TooFewLights`] for fewer than two lights; [`CutsError::Input`] for
    /// mismatched lengths, non-finite values or a non-positive `k`.
    pub fn geometric(positions: &[Vec3], normals: &[Vec3], k: f32) -> Result<Self, CutsError> {
        let features = geometric_features(positions, normals, k, 1.0)?;
        Ok(Self::from_features(positions, &features, 6))
    }

    /// The tree of environment directions `dirs` (positions on the unit sphere, normals `-w`),
    /// geometric metric with `K` = [`DEFAULT_K`].
    ///
    /// # Errors
    /// As [`LightTree::geometric`].
    pub fn environment(dirs: &[Vec3]) -> Result<Self, CutsError> {
        let normals: Vec<Vec3> = dirs.iter().map(|&d| -d).collect();
        Self::geometric(dirs, &normals, DEFAULT_K)
    }

    /// The data-driven tree (Eq. 13): geometric distance weighted by `beta`, pilot-visibility
    /// distance (Eq. 12 without `A^2`, module docs) by `1 - beta`.
    ///
    /// # Errors
    /// As [`LightTree::geometric`], and [`CutsError::Input`] for `beta` outside `[0, 1]` or
    /// pilot vectors of another light count.
    pub fn data_driven(
        positions: &[Vec3],
        normals: &[Vec3],
        pilot: &PilotVectors,
        k: f32,
        beta: f32,
    ) -> Result<Self, CutsError> {
        if !(0.0..=1.0).contains(&beta) {
            return Err(CutsError::Input(format!("beta {beta} is not in [0, 1]")));
        }
        if pilot.lights != positions.len()
            || pilot.data.len() != pilot.lights * pilot.clusters
            || pilot.clusters == 0
        {
            return Err(CutsError::Input(format!(
                "pilot vectors of {} lights x {} clusters ({} values) for {} lights",
                pilot.lights,
                pilot.clusters,
                pilot.data.len(),
                positions.len()
            )));
        }
        if pilot.data.iter().any(|x| !x.is_finite()) {
            return Err(CutsError::Input("non-finite pilot visibility".into()));
        }
        let geo = geometric_features(positions, normals, k, beta)?;
        let m = pilot.clusters;
        let dim = 6 + m;
        let wv = ((1.0 - beta) * (k + 1.0) * (k + 1.0) / m as f32).sqrt();
        let mut features = Vec::with_capacity(positions.len() * dim);
        for i in 0..positions.len() {
            features.extend_from_slice(&geo[6 * i..6 * i + 6]);
            features.extend(pilot.data[i * m..(i + 1) * m].iter().map(|&l| wv * l));
        }
        Ok(Self::from_features(positions, &features, dim))
    }

    /// The tree over lights at `positions` whose leaves, left to right, are the lights
    /// `order` (what a bundle stores: the shape of a complete tree is fixed by the light
    /// count, so the leaf order is the whole tree). `from_leaf_order(p, &t.lights_in_order())`
    /// rebuilds `t`.
    ///
    /// # Errors
    /// [`CutsError::TooFewLights`]; [`CutsError::Input`] when `order` is not a permutation of
    /// the lights or a position is not finite.
    pub fn from_leaf_order(positions: &[Vec3], order: &[u32]) -> Result<Self, CutsError> {
        let n = positions.len();
        if n < 2 {
            return Err(CutsError::TooFewLights { count: n });
        }
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(CutsError::Input("non-finite light position".into()));
        }
        let mut seen = vec![false; n];
        for &l in order {
            if l as usize >= n || std::mem::replace(&mut seen[l as usize], true) {
                return Err(CutsError::Input(format!(
                    "leaf order repeats light {l} or names a light outside 0..{n}"
                )));
            }
        }
        if order.len() != n {
            return Err(CutsError::Input(format!(
                "leaf order of {} lights for {n} lights",
                order.len()
            )));
        }
        Ok(Self::from_order(positions, order))
    }

    /// Build from per-light features (`dim` each; the metric is their squared distance).
    fn from_features(positions: &[Vec3], features: &[f32], dim: usize) -> Self {
        let n = positions.len();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut groups = Vec::new();
        split_groups(features, dim, &mut order, n, &mut groups);
        Self::from_order(positions, &order)
    }

    /// The complete tree whose leaves, left to right, are `order` (a permutation).
    fn from_order(positions: &[Vec3], order: &[u32]) -> Self {
        let n = positions.len();
        let mut tree = LightTree {
            nodes: Vec::with_capacity(2 * n - 1),
            centers: Vec::with_capacity(2 * n - 1),
            dirs: Vec::new(),
            leaf_of_light: vec![0; n],
        };
        tree.emit(order, 0, positions);
        tree.dirs = (0..tree.nodes.len())
            .map(|i| {
                let c = tree.centers[i];
                if c.length_squared() > 1e-12 {
                    c.normalize()
                } else {
                    let leftmost = tree.centers[tree.nodes[i].leftleaf as usize];
                    leftmost.normalize_or(Vec3::Y)
                }
            })
            .collect();
        tree
    }

    /// Append the subtree of the lights `order[first..]` (`order.len()` of them) in
    /// post-order; returns its root.
    fn emit(&mut self, order: &[u32], first: u32, positions: &[Vec3]) -> u32 {
        if order.len() == 1 {
            let idx = self.nodes.len() as u32;
            self.nodes.push(TreeNode {
                leftleaf: idx,
                leaves: 1,
                first,
                kind: NodeKind::Leaf { light: order[0] },
            });
            self.centers.push(positions[order[0] as usize]);
            self.leaf_of_light[order[0] as usize] = idx;
            return idx;
        }
        let half = order.len().div_ceil(2);
        let left = self.emit(&order[..half], first, positions);
        let right = self.emit(&order[half..], first + half as u32, positions);
        let (l, r) = (self.nodes[left as usize], self.nodes[right as usize]);
        let leaves = l.leaves + r.leaves;
        let center = (self.centers[left as usize] * l.leaves as f32
            + self.centers[right as usize] * r.leaves as f32)
            / leaves as f32;
        self.nodes.push(TreeNode {
            leftleaf: l.leftleaf,
            leaves,
            first,
            kind: NodeKind::Inner { left, right },
        });
        self.centers.push(center);
        self.nodes.len() as u32 - 1
    }

    /// All nodes in post-order (the root last).
    pub fn nodes(&self) -> &[TreeNode] {
        &self.nodes
    }

    /// Node `i`.
    #[inline]
    pub fn node(&self, i: u32) -> &TreeNode {
        &self.nodes[i as usize]
    }

    /// Number of lights (leaves).
    pub fn light_count(&self) -> usize {
        self.leaf_of_light.len()
    }

    /// Post-order index of the root (`2 N - 2`).
    pub fn root(&self) -> u32 {
        self.nodes.len() as u32 - 1
    }

    /// Post-order index of light `light`'s leaf.
    pub fn leaf_of_light(&self, light: usize) -> u32 {
        self.leaf_of_light[light]
    }

    /// Mean position of node `i`'s lights.
    pub fn center(&self, i: u32) -> Vec3 {
        self.centers[i as usize]
    }

    /// Representative direction of node `i` for environment lights: its normalised mean
    /// direction, or its leftmost light's where the mean vanishes (a cluster as symmetric as
    /// the whole sphere).
    #[inline]
    pub fn direction(&self, i: u32) -> Vec3 {
        self.dirs[i as usize]
    }

    /// The lights in leaf order (left to right), i.e. by rank.
    pub fn lights_in_order(&self) -> Vec<u32> {
        let mut out = vec![0; self.light_count()];
        for n in &self.nodes {
            if let NodeKind::Leaf { light } = n.kind {
                out[n.first as usize] = light;
            }
        }
        out
    }

    /// Check every invariant: `2 N - 1` nodes for `N >= 2` lights; children before parents
    /// (the right child is the node just before its parent, the left child ends just before
    /// the right child's subtree); leftmost leaves and leaf ranks consistent; leaf counts
    /// adding up and halves balanced (`ceil(n / 2)` on the left); every light in exactly one
    /// leaf; the root last, covering everything; finite centres.
    ///
    /// # Errors
    /// The first broken invariant.
    pub fn validate(&self) -> Result<(), TreeError> {
        let n = self.leaf_of_light.len();
        if n < 2
            || self.nodes.len() != 2 * n - 1
            || self.centers.len() != self.nodes.len()
            || self.dirs.len() != self.nodes.len()
        {
            return Err(TreeError::Size {
                lights: n,
                nodes: self.nodes.len(),
            });
        }
        let bad = |node: usize, problem| Err(TreeError::Node { node, problem });
        let mut seen = vec![false; n];
        let mut next_rank = 0u32;
        for (p, node) in self.nodes.iter().enumerate() {
            if !self.centers[p].is_finite() {
                return bad(p, "non-finite centre");
            }
            // 1e-5: f32 normalisation.
            let unit = (self.dirs[p].length() - 1.0).abs() < 1e-5;
            if !unit {
                return bad(p, "direction not unit");
            }
            if node.leaves == 0 || node.leftleaf as usize + 2 * node.leaves as usize != p + 2 {
                return bad(p, "leftleaf is not index - 2 (leaves - 1)");
            }
            match node.kind {
                NodeKind::Leaf { light } => {
                    if node.leaves != 1 || node.leftleaf as usize != p {
                        return bad(p, "a leaf must have one light and be its own leftleaf");
                    }
                    if node.first != next_rank {
                        return bad(p, "leaf ranks are not 0, 1, 2, ... in post-order");
                    }
                    next_rank += 1;
                    let l = light as usize;
                    if l >= n || seen[l] || self.leaf_of_light[l] as usize != p {
                        return bad(p, "light out of range, repeated or not mapped to its leaf");
                    }
                    seen[l] = true;
                }
                NodeKind::Inner { left, right } => {
                    let (li, ri) = (left as usize, right as usize);
                    if ri + 1 != p || li >= ri {
                        return bad(p, "children must precede the node, right child last");
                    }
                    let (l, r) = (&self.nodes[li], &self.nodes[ri]);
                    if l.leaves + r.leaves != node.leaves
                        || l.leaves != node.leaves.div_ceil(2)
                        || r.leftleaf as usize != li + 1
                        || l.leftleaf != node.leftleaf
                    {
                        return bad(p, "children do not split the node's range in halves");
                    }
                    if l.first != node.first || r.first != node.first + l.leaves {
                        return bad(p, "children's leaf ranks do not follow the node's");
                    }
                }
            }
        }
        let root = &self.nodes[self.nodes.len() - 1];
        if root.leaves as usize != n || root.leftleaf != 0 || root.first != 0 {
            return bad(self.nodes.len() - 1, "the root does not cover every light");
        }
        if seen.iter().any(|&s| !s) {
            return bad(self.nodes.len() - 1, "a light has no leaf");
        }
        Ok(())
    }
}

/// Eq. 11 as features `[w K/d x, w n]` with `w = sqrt(weight)` (6 per light).
fn geometric_features(
    positions: &[Vec3],
    normals: &[Vec3],
    k: f32,
    weight: f32,
) -> Result<Vec<f32>, CutsError> {
    if positions.len() < 2 {
        return Err(CutsError::TooFewLights {
            count: positions.len(),
        });
    }
    if normals.len() != positions.len() {
        return Err(CutsError::Input(format!(
            "{} normals for {} light positions",
            normals.len(),
            positions.len()
        )));
    }
    if !(k.is_finite() && k > 0.0) {
        return Err(CutsError::Input(format!("K {k} must be positive")));
    }
    if positions.iter().chain(normals).any(|p| !p.is_finite()) {
        return Err(CutsError::Input(
            "non-finite light position or normal".into(),
        ));
    }
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let diag = (hi - lo).length();
    // All lights at one point: positions cannot separate them, normals still can.
    let wx = if diag > 0.0 { k / diag } else { 0.0 } * weight.sqrt();
    let wn = weight.sqrt();
    let mut f = Vec::with_capacity(6 * positions.len());
    for (p, n) in positions.iter().zip(normals) {
        f.extend_from_slice(&(*p * wx).to_array());
        f.extend_from_slice(&(*n * wn).to_array());
    }
    Ok(f)
}

/// Split `ids` top-down into `groups` contiguous groups (balanced 2-means at every level,
/// module docs), appending each group's length to `out` left to right. `groups >= ids.len()`
/// splits down to single lights.
pub(crate) fn split_groups(
    features: &[f32],
    dim: usize,
    ids: &mut [u32],
    groups: usize,
    out: &mut Vec<usize>,
) {
    if ids.len() <= 1 || groups <= 1 {
        out.push(ids.len());
        return;
    }
    let (gl, left_len) = if groups >= ids.len() {
        (ids.len().div_ceil(2), ids.len().div_ceil(2))
    } else {
        let gl = groups.div_ceil(2);
        (gl, (ids.len() * gl / groups).max(1))
    };
    split2(features, dim, ids, left_len);
    let (l, r) = ids.split_at_mut(left_len);
    if l.len() + r.len() > 8192 {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        rayon::join(
            || split_groups(features, dim, l, gl, &mut a),
            || split_groups(features, dim, r, groups - gl, &mut b),
        );
        out.extend(a);
        out.extend(b);
    } else {
        split_groups(features, dim, l, gl, out);
        split_groups(features, dim, r, groups - gl, out);
    }
}

#[inline]
fn dist2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

fn mean_of(features: &[f32], dim: usize, ids: &[u32]) -> Vec<f32> {
    let mut m = vec![0f64; dim];
    for &i in ids {
        let f = &features[i as usize * dim..(i as usize + 1) * dim];
        m.iter_mut().zip(f).for_each(|(a, &x)| *a += x as f64);
    }
    m.iter().map(|&a| (a / ids.len() as f64) as f32).collect()
}

/// The id of `ids` farthest from `c` (ties to the lowest id).
fn farthest(features: &[f32], dim: usize, ids: &[u32], c: &[f32]) -> u32 {
    let mut best = (f32::NEG_INFINITY, u32::MAX);
    for &i in ids {
        let d = dist2(&features[i as usize * dim..(i as usize + 1) * dim], c);
        if d > best.0 || (d == best.0 && i < best.1) {
            best = (d, i);
        }
    }
    best.1
}

/// Balanced 2-means: reorder `ids` so its first `left_len` entries are the left cluster.
fn split2(features: &[f32], dim: usize, ids: &mut [u32], left_len: usize) {
    debug_assert!(left_len >= 1 && left_len < ids.len());
    let feat = |i: u32| &features[i as usize * dim..(i as usize + 1) * dim];
    let m = mean_of(features, dim, ids);
    let a = farthest(features, dim, ids, &m);
    let b = farthest(features, dim, ids, feat(a));
    let (mut c1, mut c2) = (feat(a).to_vec(), feat(b).to_vec());
    let mut keyed: Vec<(f32, u32)> = Vec::with_capacity(ids.len());
    let mut previous: Option<Vec<u32>> = None;
    for _ in 0..SPLIT_ITERATIONS {
        keyed.clear();
        keyed.extend(
            ids.iter()
                .map(|&i| (dist2(feat(i), &c1) - dist2(feat(i), &c2), i)),
        );
        keyed.select_nth_unstable_by(left_len, |x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        for (slot, &(_, i)) in ids.iter_mut().zip(&keyed) {
            *slot = i;
        }
        let mut left: Vec<u32> = ids[..left_len].to_vec();
        left.sort_unstable();
        if previous.as_ref() == Some(&left) {
            break;
        }
        previous = Some(left);
        c1 = mean_of(features, dim, &ids[..left_len]);
        c2 = mean_of(features, dim, &ids[left_len..]);
    }
    // Canonical order inside each half, whatever the selection left.
    ids[..left_len].sort_unstable();
    ids[left_len..].sort_unstable();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cuts::samples::fibonacci_point;
    use relight_sphere::warp::Rng;

    fn sphere(n: usize) -> Vec<Vec3> {
        (0..n).map(|i| fibonacci_point(i, n)).collect()
    }

    #[test]
    fn builds_are_valid_for_every_size() {
        for n in [2usize, 3, 4, 5, 7, 8, 31, 100, 1000, 4097] {
            let t = LightTree::environment(&sphere(n)).unwrap();
            t.validate().unwrap();
            assert_eq!(t.nodes().len(), 2 * n - 1);
            let mut lights = t.lights_in_order();
            lights.sort_unstable();
            assert_eq!(lights, (0..n as u32).collect::<Vec<_>>());
        }
    }

    #[test]
    fn leaf_order_rebuilds_the_tree() {
        for n in [2usize, 3, 17, 1000] {
            let d = sphere(n);
            let t = LightTree::environment(&d).unwrap();
            let again = LightTree::from_leaf_order(&d, &t.lights_in_order()).unwrap();
            again.validate().unwrap();
            assert_eq!(again, t);
        }
        let d = sphere(4);
        assert!(LightTree::from_leaf_order(&d, &[0, 1, 2]).is_err());
        assert!(LightTree::from_leaf_order(&d, &[0, 1, 2, 2]).is_err());
        assert!(LightTree::from_leaf_order(&d, &[0, 1, 2, 4]).is_err());
        assert!(LightTree::from_leaf_order(&d[..1], &[0]).is_err());
    }

    #[test]
    fn too_few_lights_and_bad_input_refused() {
        for n in [0usize, 1] {
            assert_eq!(
                LightTree::environment(&sphere(n.max(1))[..n]).unwrap_err(),
                CutsError::TooFewLights { count: n }
            );
        }
        let d = sphere(4);
        assert!(LightTree::geometric(&d, &d[..3], 30.0).is_err());
        assert!(LightTree::geometric(&d, &d, 0.0).is_err());
        let mut nan = d.clone();
        nan[2].x = f32::NAN;
        assert!(LightTree::environment(&nan).is_err());
        let pilot = PilotVectors {
            lights: 4,
            clusters: 2,
            data: vec![0.0; 8],
        };
        assert!(LightTree::data_driven(&d, &d, &pilot, 30.0, 1.5).is_err());
        let short = PilotVectors {
            lights: 3,
            clusters: 2,
            data: vec![0.0; 6],
        };
        assert!(LightTree::data_driven(&d, &d, &short, 30.0, 0.5).is_err());
    }

    #[test]
    fn validate_catches_breakage() {
        let t = LightTree::environment(&sphere(16)).unwrap();
        let mut broken = t.clone();
        broken.nodes[5].leftleaf += 1;
        assert!(broken.validate().is_err());
        let mut broken = t.clone();
        // Two leaves claiming the same light.
        let leaves: Vec<usize> = (0..t.nodes.len())
            .filter(|&p| matches!(t.nodes[p].kind, NodeKind::Leaf { .. }))
            .collect();
        broken.nodes[leaves[1]].kind = broken.nodes[leaves[0]].kind;
        assert!(broken.validate().is_err());
        let mut broken = t.clone();
        broken.nodes.swap(0, 1);
        assert!(broken.validate().is_err());
        let mut broken = t.clone();
        broken.centers[3] = Vec3::NAN;
        assert!(broken.validate().is_err());
        let mut broken = t.clone();
        broken.dirs[4] *= 2.0;
        assert!(broken.validate().is_err());
        let mut broken = t.clone();
        broken.nodes.pop();
        assert!(broken.validate().is_err());
        let mut broken = t;
        let root = broken.nodes.len() - 1;
        broken.nodes[root].first = 1;
        assert!(broken.validate().is_err());
    }

    #[test]
    fn clusters_are_spatially_compact() {
        // At every level, a geometric cluster of the Fibonacci sphere is a cap-like patch:
        // its lights lie within a few times the radius of a disc of the same area (a random
        // partition would spread every cluster over the whole sphere).
        let n = 4096;
        let dirs = sphere(n);
        let t = LightTree::environment(&dirs).unwrap();
        let order = t.lights_in_order();
        for p in 0..t.nodes().len() as u32 {
            let node = t.node(p);
            if node.leaves < 16 || node.leaves as usize > n / 4 {
                continue;
            }
            let c = t.direction(p);
            let area = 4.0 * std::f32::consts::PI * node.leaves as f32 / n as f32;
            let disc_radius = (area / std::f32::consts::PI).sqrt();
            let members = &order[node.first as usize..(node.first + node.leaves) as usize];
            let spread = members
                .iter()
                .map(|&l| (dirs[l as usize] - c).length())
                .fold(0.0f32, f32::max);
            // Balanced halving makes elongated patches (aspect up to ~2:1 after a split);
            // 2.5 disc radii bounds them.
            assert!(
                spread < 2.5 * disc_radius,
                "node {p}: {spread} vs {disc_radius}"
            );
        }
    }

    #[test]
    fn data_driven_follows_visibility() {
        // Lights on a circle; pilot visibility 1 on one arc of non-adjacent lights (the odd
        // ones) and 0 elsewhere. With beta = 0 the first split separates them exactly; with
        // beta = 1 it is the geometric tree; both are valid.
        let n = 64;
        let dirs: Vec<Vec3> = (0..n)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                Vec3::new(a.cos(), 0.0, a.sin())
            })
            .collect();
        let normals: Vec<Vec3> = dirs.iter().map(|&d| -d).collect();
        let m = 8;
        let data: Vec<f32> = (0..n).flat_map(|i| vec![(i % 2) as f32; m]).collect();
        let pilot = PilotVectors {
            lights: n,
            clusters: m,
            data,
        };
        let t = LightTree::data_driven(&dirs, &normals, &pilot, 30.0, 0.0).unwrap();
        t.validate().unwrap();
        let order = t.lights_in_order();
        let left: Vec<u32> = order[..n / 2].iter().map(|&l| l % 2).collect();
        assert!(left.iter().all(|&p| p == left[0]), "{order:?}");
        let g = LightTree::data_driven(&dirs, &normals, &pilot, 30.0, 1.0).unwrap();
        g.validate().unwrap();
        assert_eq!(g, LightTree::geometric(&dirs, &normals, 30.0).unwrap());
        // Random pilot data at the default beta still gives a valid tree.
        let mut rng = Rng::new(1, 1);
        let pilot = PilotVectors {
            lights: n,
            clusters: m,
            data: (0..n * m).map(|_| rng.next_f32()).collect(),
        };
        LightTree::data_driven(&dirs, &normals, &pilot, DEFAULT_K, DEFAULT_BETA)
            .unwrap()
            .validate()
            .unwrap();
    }

    #[test]
    fn groups_partition_and_are_deterministic() {
        let dirs = sphere(1000);
        let f = geometric_features(&dirs, &dirs, 30.0, 1.0).unwrap();
        for g in [1usize, 2, 3, 10, 64, 999, 1000, 2000] {
            let mut ids: Vec<u32> = (0..1000).collect();
            let mut out = Vec::new();
            split_groups(&f, 6, &mut ids, g, &mut out);
            assert_eq!(out.len(), g.min(1000), "groups {g}");
            assert_eq!(out.iter().sum::<usize>(), 1000);
            assert!(out.iter().all(|&s| s >= 1));
            let mut sorted = ids.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..1000).collect::<Vec<_>>());
            let mut again: Vec<u32> = (0..1000).collect();
            split_groups(&f, 6, &mut again, g, &mut Vec::new());
            assert_eq!(ids, again);
        }
    }
}
