//! relight's own BVH: binned SAH build, collapsed to an 8-wide tree with SoA boxes, triangles
//! in SoA packs of 4, watertight ray-triangle test. Pure Rust.
//!
//! **Build.** Top-down binary build minimising the surface area heuristic (MacDonald & Booth
//! 1990, "Heuristics for ray tracing using space subdivision") evaluated on centroid bins
//! (Wald 2007, "On fast construction of SAH-based bounding volume hierarchies"); the SAH counts
//! primitives in blocks of 4 because a leaf is one 4-wide triangle pack (as Embree does).
//! Subtrees of at least [`PAR_MIN`] primitives are built in parallel with `rayon::join`. Deeper
//! than [`SAH_MAX_DEPTH`], splits are object medians, bounding the depth and hence the
//! traversal stack.
//!
//! **Collapse.** The binary tree becomes an 8-wide one by greedily opening the child with the
//! largest surface area until a node has 8 children (the wide-BVH layout of Wald, Benthin &
//! Boulos 2008, "Getting rid of packets", and Ernst & Greiner 2008 "Multi bounding volume
//! hierarchies"; Ylitie et al. 2017 give an optimal, costlier collapse). Each `Node8` holds its
//! children's boxes as `[axis][child]` arrays (SoA), so the 8 slab tests of one node are a few
//! 8-wide AVX instructions (`std::arch`, used when run-time detection finds AVX2 and FMA; a
//! portable scalar loop otherwise).
//!
//! **Traversal.** Closest hit: nearest child first (hit children sorted by entry distance with
//! small sorting networks), subtrees farther than the current hit skipped. Occlusion: children
//! in stored order, exit at the first hit. Stacked subtrees are prefetched, since traversal is
//! bound by memory latency. The slab test computes `(p - o) * (1 / d)` and widens the exit
//! distance by `1 + 2 gamma(3)` (Ize 2013, "Robust BVH ray traversal"; Pharr et al., PBRT 3rd
//! ed., 3.9.2) so rounding never culls a box the ray touches; a zero direction component uses
//! `±f32::MAX` as its inverse, which keeps `0 * inv` finite (no NaN).
//!
//! **Triangles.** The watertight test of Woop, Benthin & Wald 2013 ("Watertight ray/triangle
//! intersection", JCGT 2(1)), 4 triangles at once: translate to the ray origin, shear so the
//! ray is +z, and take 2D edge functions. A shared edge yields exactly negated edge functions
//! in both triangles (same products, no FMA contraction), so a ray never slips between them.
//! Instead of the paper's double-precision fallback, an edge function of exactly zero counts
//! as inside, so a ray exactly through an edge may report either triangle but never neither.
//! The distance test is division-free (`T` against `t * det`, sign folded in). No back-face
//! culling. Degenerate triangles (zero cross product) and triangles with non-finite corners
//! are left out of the tree: they are never hit.

use super::AccelError;
use crate::mesh::TriMesh;
use crate::Vec3;

mod traverse;

/// Largest number of triangles in a leaf: one SoA pack.
pub const LEAF_MAX: usize = 4;
/// Depth below which binary splits are object medians instead of SAH (bounds the stack).
pub const SAH_MAX_DEPTH: u32 = 40;
/// Subtrees with at least this many triangles are built on two rayon tasks.
pub const PAR_MIN: usize = 4096;
/// Traversal stack entries; [`Bvh::validate`] checks the tree can never need more.
const STACK: usize = 512;
/// Child code of an unused node slot.
const EMPTY: u32 = u32::MAX;
/// Child code bit marking a leaf; the other bits index `Bvh::packs`.
const LEAF_BIT: u32 = 1 << 31;
/// `1 + 2 gamma(3)` with `gamma(n) = n eps / (1 - n eps)`, `eps = 2^-24` (Ize 2013).
const ROBUST_FAR: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Build quality presets (bins per axis for the binned SAH).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BuildPreset {
    /// 8 bins: quicker build, slightly worse trees.
    Fast,
    /// 32 bins: the default.
    Quality,
}

impl BuildPreset {
    /// Every preset, for tests that loop over them.
    pub const ALL: [BuildPreset; 2] = [BuildPreset::Fast, BuildPreset::Quality];

    fn bins(self) -> usize {
        match self {
            BuildPreset::Fast => 8,
            BuildPreset::Quality => MAX_BINS,
        }
    }
}

const MAX_BINS: usize = 32;

/// Whether a triangle goes into the tree: finite corners and a non-zero cross product.
#[inline]
fn usable([a, b, c]: [Vec3; 3]) -> bool {
    a.is_finite() && b.is_finite() && c.is_finite() && (b - a).cross(c - a) != Vec3::ZERO
}

/// Check `mesh` for ray casting: every index in range and at least one usable triangle.
/// Returns the number of usable triangles.
///
/// # Errors
/// [`AccelError::IndexOutOfRange`] or [`AccelError::NoUsableTriangle`].
pub(crate) fn check_mesh(mesh: &TriMesh) -> Result<usize, AccelError> {
    let nv = mesh.positions.len();
    if let Some((i, t)) = mesh
        .indices
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&k| k as usize >= nv))
    {
        return Err(AccelError::IndexOutOfRange {
            triangle: i,
            indices: *t,
            vertices: nv,
        });
    }
    let n = (0..mesh.triangle_count())
        .filter(|&t| usable(mesh.triangle(t)))
        .count();
    if n == 0 {
        return Err(AccelError::NoUsableTriangle {
            triangles: mesh.triangle_count(),
        });
    }
    Ok(n)
}

/// Axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: Vec3,
    hi: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: Vec3::INFINITY,
        hi: Vec3::NEG_INFINITY,
    };

    #[inline]
    fn union(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
    #[inline]
    fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }
    /// Half the surface area (the SAH only needs ratios); 0 for an empty box.
    #[inline]
    fn half_area(self) -> f32 {
        let e = (self.hi - self.lo).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
    fn contains(self, o: Aabb) -> bool {
        self.lo.cmple(o.lo).all() && o.hi.cmple(self.hi).all()
    }
}

/// Binary build node; leaves index a range of the permuted primitive array.
enum BNode {
    Leaf {
        bounds: Aabb,
        start: usize,
        count: usize,
    },
    Inner {
        bounds: Aabb,
        kids: Box<[BNode; 2]>,
    },
}

impl BNode {
    fn bounds(&self) -> Aabb {
        match self {
            BNode::Leaf { bounds, .. } | BNode::Inner { bounds, .. } => *bounds,
        }
    }
}

/// Per-primitive data shared by all build tasks.
struct BuildCtx<'a> {
    bounds: &'a [Aabb],
    centroids: &'a [Vec3],
    bins: usize,
}

/// Bin of centroid coordinate `c` on an axis starting at `lo` with `scale = bins / extent`.
#[inline]
fn bin_of(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

impl BuildCtx<'_> {
    /// Best SAH plane `(axis, first right bin)` over centroid bins, or `None` if every axis
    /// has all centroids in one bin.
    fn sah_split(&self, prims: &[u32], cb: Aabb, scale: Vec3) -> Option<(usize, usize)> {
        let k = self.bins;
        let mut boxes = [[Aabb::EMPTY; MAX_BINS]; 3];
        let mut counts = [[0u32; MAX_BINS]; 3];
        for &p in prims {
            let c = self.centroids[p as usize];
            let b = self.bounds[p as usize];
            for a in 0..3 {
                let i = bin_of(c[a], cb.lo[a], scale[a], k);
                boxes[a][i] = boxes[a][i].union(b);
                counts[a][i] += 1;
            }
        }
        // Cost in 4-blocks: a leaf is one pack of 4 whatever its fill.
        let blocks = |n: u32| n.div_ceil(LEAF_MAX as u32) as f32;
        let mut best: Option<(f32, usize, usize)> = None;
        for a in 0..3 {
            if scale[a] <= 0.0 {
                continue;
            }
            // Sweep from the right: area and count of bins i..k.
            let mut right_cost = [0f32; MAX_BINS];
            let (mut rb, mut rn) = (Aabb::EMPTY, 0u32);
            for i in (1..k).rev() {
                rb = rb.union(boxes[a][i]);
                rn += counts[a][i];
                right_cost[i] = if rn > 0 {
                    rb.half_area() * blocks(rn)
                } else {
                    f32::NAN
                };
            }
            let (mut lb, mut ln) = (Aabb::EMPTY, 0u32);
            for i in 1..k {
                lb = lb.union(boxes[a][i - 1]);
                ln += counts[a][i - 1];
                if ln == 0 || right_cost[i].is_nan() {
                    continue;
                }
                let cost = lb.half_area() * blocks(ln) + right_cost[i];
                if best.is_none_or(|(bc, _, _)| cost < bc) {
                    best = Some((cost, a, i));
                }
            }
        }
        best.map(|(_, a, i)| (a, i))
    }

    /// Build the subtree over `prims` (which start at `start` in the full array).
    fn build(&self, prims: &mut [u32], start: usize, depth: u32) -> BNode {
        let (bounds, cb) = prims.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), &p| {
            (
                b.union(self.bounds[p as usize]),
                c.grow(self.centroids[p as usize]),
            )
        });
        let n = prims.len();
        if n <= LEAF_MAX {
            return BNode::Leaf {
                bounds,
                start,
                count: n,
            };
        }
        let ext = cb.hi - cb.lo;
        let k = self.bins as f32;
        // Slightly under `k / extent` so the largest centroid lands in the last bin.
        let scale = Vec3::select(ext.cmpgt(Vec3::ZERO), k * (1.0 - 1e-5) / ext, Vec3::ZERO);
        let split = (depth < SAH_MAX_DEPTH)
            .then(|| self.sah_split(prims, cb, scale))
            .flatten();
        let mid = match split {
            Some((a, first_right)) => {
                let mut m = 0;
                for j in 0..n {
                    let c = self.centroids[prims[j] as usize][a];
                    if bin_of(c, cb.lo[a], scale[a], self.bins) < first_right {
                        prims.swap(m, j);
                        m += 1;
                    }
                }
                m
            }
            None => {
                // Object median on the widest centroid axis (any split if all coincide).
                let a = ext.max_position();
                let m = n / 2;
                prims.select_nth_unstable_by(m, |&p, &q| {
                    let (cp, cq) = (self.centroids[p as usize][a], self.centroids[q as usize][a]);
                    cp.total_cmp(&cq)
                });
                m
            }
        };
        debug_assert!(mid > 0 && mid < n, "empty side in split ({mid} of {n})");
        let (l, r) = prims.split_at_mut(mid);
        let (a, b) = if n >= PAR_MIN {
            rayon::join(
                || self.build(l, start, depth + 1),
                || self.build(r, start + mid, depth + 1),
            )
        } else {
            (
                self.build(l, start, depth + 1),
                self.build(r, start + mid, depth + 1),
            )
        };
        BNode::Inner {
            bounds,
            kids: Box::new([a, b]),
        }
    }
}

/// An 8-wide node: child boxes as `[axis][child]` (SoA) and child codes (`EMPTY`, a node
/// index, or `LEAF_BIT | pack index`). Unused slots have empty boxes (`lo = +inf`,
/// `hi = -inf`), which no ray hits.
#[repr(C, align(64))]
#[derive(Clone, Debug)]
struct Node8 {
    lo: [[f32; 8]; 3],
    hi: [[f32; 8]; 3],
    child: [u32; 8],
}

/// Up to 4 triangles in SoA: `v[corner][axis][lane]`; unused lanes have NaN corners (never
/// hit) and `prim = u32::MAX`.
#[repr(C, align(16))]
#[derive(Clone, Debug)]
struct TriPack {
    v: [[[f32; 4]; 3]; 3],
    prim: [u32; 4],
}

/// relight's BVH over one triangle mesh. Triangle ids in hits are the mesh's indices.
pub struct Bvh {
    nodes: Vec<Node8>,
    packs: Vec<TriPack>,
    /// Usable triangles per mesh triangle (for `validate`): `Some(corners)` if in the tree.
    tris: Vec<Option<[Vec3; 3]>>,
    preset: BuildPreset,
    #[cfg(target_arch = "x86_64")]
    avx2: bool,
}

impl Bvh {
    /// Build over `mesh` with `preset`.
    ///
    /// # Errors
    /// [`AccelError::IndexOutOfRange`], or [`AccelError::NoUsableTriangle`] when no triangle
    /// is finite and non-degenerate.
    pub fn build(mesh: &TriMesh, preset: BuildPreset) -> Result<Bvh, AccelError> {
        check_mesh(mesh)?;
        let tris: Vec<Option<[Vec3; 3]>> = (0..mesh.triangle_count())
            .map(|t| Some(mesh.triangle(t)).filter(|&c| usable(c)))
            .collect();
        let mut prims: Vec<u32> = (0..tris.len() as u32)
            .filter(|&t| tris[t as usize].is_some())
            .collect();
        let bounds: Vec<Aabb> = tris
            .iter()
            .map(|c| c.map_or(Aabb::EMPTY, |[a, b, c]| Aabb::EMPTY.grow(a).grow(b).grow(c)))
            .collect();
        let centroids: Vec<Vec3> = bounds.iter().map(|b| (b.lo + b.hi) * 0.5).collect();
        let ctx = BuildCtx {
            bounds: &bounds,
            centroids: &centroids,
            bins: preset.bins(),
        };
        let root = ctx.build(&mut prims, 0, 0);

        let mut bvh = Bvh {
            nodes: Vec::with_capacity(prims.len() / 4 + 1),
            packs: Vec::with_capacity(prims.len() / 2 + 1),
            tris,
            preset,
            #[cfg(target_arch = "x86_64")]
            avx2: std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma"),
        };
        match &root {
            BNode::Inner { .. } => {
                bvh.collapse(&root, &prims);
            }
            // A single leaf still gets a root node, so traversal always starts at a node.
            BNode::Leaf { .. } => {
                bvh.nodes.push(empty_node());
                let code = bvh.collapse(&root, &prims);
                set_slot(&mut bvh.nodes[0], 0, root.bounds(), code);
            }
        }
        Ok(bvh)
    }

    /// The preset this tree was built with.
    pub fn preset(&self) -> BuildPreset {
        self.preset
    }

    /// Number of 8-wide nodes and of triangle packs.
    pub fn size(&self) -> (usize, usize) {
        (self.nodes.len(), self.packs.len())
    }

    /// Emit `b` (and its subtree) into the wide layout; returns its child code.
    fn collapse(&mut self, b: &BNode, prims: &[u32]) -> u32 {
        match b {
            BNode::Leaf { start, count, .. } => {
                let mut pack = TriPack {
                    v: [[[f32::NAN; 4]; 3]; 3],
                    prim: [u32::MAX; 4],
                };
                for (lane, &p) in prims[*start..start + count].iter().enumerate() {
                    let corners = self.tris[p as usize].expect("only usable triangles are built");
                    for (k, c) in corners.iter().enumerate() {
                        for a in 0..3 {
                            pack.v[k][a][lane] = c[a];
                        }
                    }
                    pack.prim[lane] = p;
                }
                self.packs.push(pack);
                LEAF_BIT | (self.packs.len() - 1) as u32
            }
            BNode::Inner { kids, .. } => {
                // Open the largest-area inner child until 8 children (greedy collapse).
                let mut ch: Vec<&BNode> = vec![&kids[0], &kids[1]];
                while ch.len() < 8 {
                    let open = ch
                        .iter()
                        .enumerate()
                        .filter(|(_, c)| matches!(c, BNode::Inner { .. }))
                        .max_by(|x, y| {
                            x.1.bounds()
                                .half_area()
                                .total_cmp(&y.1.bounds().half_area())
                        })
                        .map(|(i, _)| i);
                    let Some(i) = open else { break };
                    let BNode::Inner { kids: gk, .. } = ch.swap_remove(i) else {
                        unreachable!()
                    };
                    ch.push(&gk[0]);
                    ch.push(&gk[1]);
                }
                let idx = self.nodes.len();
                self.nodes.push(empty_node());
                for (slot, c) in ch.into_iter().enumerate() {
                    let code = self.collapse(c, prims);
                    set_slot(&mut self.nodes[idx], slot, c.bounds(), code);
                }
                idx as u32
            }
        }
    }

    /// Check every invariant: the tree is a tree rooted at node 0 (each node reached once,
    /// from a lower index), child boxes lie inside their slot box in the parent, leaves hold
    /// 1..=4 triangles whose corners match the mesh and lie inside the leaf box, every usable
    /// triangle is referenced exactly once and no other, and the traversal stack is deep
    /// enough.
    ///
    /// # Errors
    /// The first violated invariant.
    pub fn validate(&self) -> Result<(), BvhError> {
        if self.nodes.is_empty() {
            return Err(BvhError::NoRoot);
        }
        let mut node_seen = vec![false; self.nodes.len()];
        let mut pack_seen = vec![false; self.packs.len()];
        let mut tri_seen = vec![0u32; self.tris.len()];
        let mut max_depth = 0;
        // (node, box of its slot in the parent, depth)
        let mut todo = vec![(0usize, None::<Aabb>, 1usize)];
        node_seen[0] = true;
        while let Some((n, parent_box, depth)) = todo.pop() {
            max_depth = max_depth.max(depth);
            let node = &self.nodes[n];
            let mut used = 0;
            for s in 0..8 {
                let code = node.child[s];
                let sb = slot_box(node, s);
                if code == EMPTY {
                    if sb.lo.cmplt(Vec3::INFINITY).any() || sb.hi.cmpgt(Vec3::NEG_INFINITY).any() {
                        return Err(BvhError::NonEmptyUnusedSlot { node: n, slot: s });
                    }
                    continue;
                }
                used += 1;
                if !(sb.lo.cmple(sb.hi).all()) || !sb.lo.is_finite() || !sb.hi.is_finite() {
                    return Err(BvhError::InvalidBox {
                        node: n,
                        slot: s,
                        lo: sb.lo,
                        hi: sb.hi,
                    });
                }
                if let Some(pb) = parent_box {
                    if !pb.contains(sb) {
                        return Err(BvhError::OutsideParent {
                            node: n,
                            slot: s,
                            lo: sb.lo,
                            hi: sb.hi,
                            parent_lo: pb.lo,
                            parent_hi: pb.hi,
                        });
                    }
                }
                if code & LEAF_BIT != 0 {
                    let p = (code & !LEAF_BIT) as usize;
                    if p >= self.packs.len() || std::mem::replace(&mut pack_seen[p], true) {
                        return Err(BvhError::BadPack {
                            node: n,
                            slot: s,
                            pack: p,
                        });
                    }
                    self.validate_pack(p, sb, &mut tri_seen)?;
                } else {
                    let c = code as usize;
                    if c <= n || c >= self.nodes.len() || std::mem::replace(&mut node_seen[c], true)
                    {
                        return Err(BvhError::BadChild {
                            node: n,
                            slot: s,
                            child: c,
                        });
                    }
                    todo.push((c, Some(sb), depth + 1));
                }
            }
            if used == 0 || (used == 1 && n != 0) {
                return Err(BvhError::ChildCount {
                    node: n,
                    children: used,
                });
            }
        }
        if let Some(n) = node_seen.iter().position(|s| !s) {
            return Err(BvhError::UnreachableNode { node: n });
        }
        if let Some(p) = pack_seen.iter().position(|s| !s) {
            return Err(BvhError::UnreachablePack { pack: p });
        }
        for (t, (&seen, tri)) in tri_seen.iter().zip(&self.tris).enumerate() {
            let want = tri.is_some() as u32;
            if seen != want {
                return Err(BvhError::TriangleCount {
                    triangle: t,
                    count: seen,
                    expected: want,
                });
            }
        }
        if 7 * max_depth + 1 > STACK {
            return Err(BvhError::TooDeep {
                depth: max_depth,
                stack: STACK,
            });
        }
        Ok(())
    }

    fn validate_pack(
        &self,
        p: usize,
        leaf_box: Aabb,
        tri_seen: &mut [u32],
    ) -> Result<(), BvhError> {
        let pack = &self.packs[p];
        let count = pack.prim.iter().take_while(|&&t| t != u32::MAX).count();
        if count == 0 || pack.prim[count..].iter().any(|&t| t != u32::MAX) {
            return Err(BvhError::PackLanes {
                pack: p,
                lanes: pack.prim,
            });
        }
        for lane in 0..4 {
            let corner =
                |k: usize| Vec3::new(pack.v[k][0][lane], pack.v[k][1][lane], pack.v[k][2][lane]);
            if lane >= count {
                if (0..3).any(|k| !corner(k).is_nan()) {
                    return Err(BvhError::PaddingNotNan { pack: p, lane });
                }
                continue;
            }
            let t = pack.prim[lane] as usize;
            let Some(Some(tri)) = self.tris.get(t) else {
                return Err(BvhError::UnusableTriangle {
                    pack: p,
                    lane,
                    triangle: t,
                });
            };
            tri_seen[t] += 1;
            for (k, c) in tri.iter().enumerate() {
                if corner(k) != *c {
                    return Err(BvhError::CornerMismatch {
                        pack: p,
                        lane,
                        corner: k,
                    });
                }
                if !leaf_box.contains(Aabb { lo: *c, hi: *c }) {
                    return Err(BvhError::CornerOutsideLeaf { pack: p, lane });
                }
            }
        }
        Ok(())
    }
}

/// The first invariant of a [`Bvh`] found violated by [`Bvh::validate`]. A valid mesh always
/// builds a valid tree, so any of these is a bug in the builder (or a corrupted tree).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BvhError {
    /// The tree has no node at all.
    #[error("no root node")]
    NoRoot,
    /// An unused child slot has a box other than the empty one.
    #[error("node {node} slot {slot}: unused slot with a non-empty box")]
    NonEmptyUnusedSlot {
        /// Node index.
        node: usize,
        /// Child slot, `0..8`.
        slot: usize,
    },
    /// A used child slot has an inverted or non-finite box.
    #[error("node {node} slot {slot}: invalid box [{lo}, {hi}]")]
    InvalidBox {
        /// Node index.
        node: usize,
        /// Child slot, `0..8`.
        slot: usize,
        /// Box minimum.
        lo: Vec3,
        /// Box maximum.
        hi: Vec3,
    },
    /// A child's box is not inside the box its parent stores for it.
    #[error("node {node} slot {slot}: box [{lo}, {hi}] outside parent [{parent_lo}, {parent_hi}]")]
    OutsideParent {
        /// Node index.
        node: usize,
        /// Child slot, `0..8`.
        slot: usize,
        /// Box minimum.
        lo: Vec3,
        /// Box maximum.
        hi: Vec3,
        /// Minimum of the parent's slot box.
        parent_lo: Vec3,
        /// Maximum of the parent's slot box.
        parent_hi: Vec3,
    },
    /// A leaf slot's triangle pack does not exist or is referenced twice.
    #[error("node {node} slot {slot}: pack {pack} out of range or shared")]
    BadPack {
        /// Node index.
        node: usize,
        /// Child slot, `0..8`.
        slot: usize,
        /// Pack index.
        pack: usize,
    },
    /// An inner slot's child does not exist, is not after its parent, or is referenced twice.
    #[error("node {node} slot {slot}: child node {child} invalid or shared")]
    BadChild {
        /// Node index.
        node: usize,
        /// Child slot, `0..8`.
        slot: usize,
        /// Child node index.
        child: usize,
    },
    /// A node has no child, or a non-root node has a single one.
    #[error("node {node} has {children} children")]
    ChildCount {
        /// Node index.
        node: usize,
        /// Used slots.
        children: usize,
    },
    /// A node is not reached from the root.
    #[error("node {node} unreachable")]
    UnreachableNode {
        /// Node index.
        node: usize,
    },
    /// A triangle pack is not reached from the root.
    #[error("pack {pack} unreachable")]
    UnreachablePack {
        /// Pack index.
        pack: usize,
    },
    /// A usable triangle is not in exactly one leaf, or an unusable one is in the tree.
    #[error("triangle {triangle} referenced {count} times, expected {expected}")]
    TriangleCount {
        /// Mesh triangle index.
        triangle: usize,
        /// Leaves holding it.
        count: u32,
        /// 1 for a usable triangle, 0 otherwise.
        expected: u32,
    },
    /// The tree is deeper than the traversal stack can hold.
    #[error("depth {depth} can overflow the {stack}-entry stack")]
    TooDeep {
        /// Depth of the tree.
        depth: usize,
        /// Entries of the traversal stack.
        stack: usize,
    },
    /// A pack's lanes are not 1 to 4 triangles followed by padding.
    #[error("pack {pack}: lanes {lanes:?} not 1..=4 filled then padding")]
    PackLanes {
        /// Pack index.
        pack: usize,
        /// Its triangle ids (`u32::MAX` = padding).
        lanes: [u32; 4],
    },
    /// A padding lane holds a corner that is not NaN (so it could be hit).
    #[error("pack {pack} lane {lane}: padding lane not NaN")]
    PaddingNotNan {
        /// Pack index.
        pack: usize,
        /// Lane, `0..4`.
        lane: usize,
    },
    /// A pack references a triangle that is not usable or does not exist.
    #[error("pack {pack} lane {lane}: triangle {triangle} not usable")]
    UnusableTriangle {
        /// Pack index.
        pack: usize,
        /// Lane, `0..4`.
        lane: usize,
        /// Mesh triangle index.
        triangle: usize,
    },
    /// A corner stored in a pack differs from the mesh's.
    #[error("pack {pack} lane {lane}: corner {corner} differs from the mesh")]
    CornerMismatch {
        /// Pack index.
        pack: usize,
        /// Lane, `0..4`.
        lane: usize,
        /// Corner, `0..3`.
        corner: usize,
    },
    /// A triangle corner lies outside its leaf's box.
    #[error("pack {pack} lane {lane}: corner outside the leaf box")]
    CornerOutsideLeaf {
        /// Pack index.
        pack: usize,
        /// Lane, `0..4`.
        lane: usize,
    },
}

fn empty_node() -> Node8 {
    Node8 {
        lo: [[f32::INFINITY; 8]; 3],
        hi: [[f32::NEG_INFINITY; 8]; 3],
        child: [EMPTY; 8],
    }
}

fn set_slot(n: &mut Node8, s: usize, b: Aabb, code: u32) {
    for a in 0..3 {
        n.lo[a][s] = b.lo[a];
        n.hi[a][s] = b.hi[a];
    }
    n.child[s] = code;
}

fn slot_box(n: &Node8, s: usize) -> Aabb {
    Aabb {
        lo: Vec3::new(n.lo[0][s], n.lo[1][s], n.lo[2][s]),
        hi: Vec3::new(n.hi[0][s], n.hi[1][s], n.hi[2][s]),
    }
}

#[cfg(test)]
pub(crate) mod tests;
