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

use super::{Hit, Ray, RayCaster};
use crate::mesh::TriMesh;
use crate::Vec3;
use std::mem::MaybeUninit;

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
/// Out-of-range vertex index, or no usable triangle.
pub(crate) fn check_mesh(mesh: &TriMesh) -> Result<usize, String> {
    let nv = mesh.positions.len();
    if let Some((i, t)) = mesh
        .indices
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&k| k as usize >= nv))
    {
        return Err(format!(
            "triangle {i} has vertex index out of range: {t:?} ({nv} vertices)"
        ));
    }
    let n = (0..mesh.triangle_count())
        .filter(|&t| usable(mesh.triangle(t)))
        .count();
    if n == 0 {
        return Err(format!(
            "mesh has no usable triangle ({} triangles, all degenerate or non-finite)",
            mesh.triangle_count()
        ));
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
    /// Out-of-range vertex index, or no usable (finite, non-degenerate) triangle.
    pub fn build(mesh: &TriMesh, preset: BuildPreset) -> Result<Bvh, String> {
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
    /// A message naming the first violated invariant.
    pub fn validate(&self) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("no root node".into());
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
                        return Err(format!(
                            "node {n} slot {s}: unused slot with a non-empty box"
                        ));
                    }
                    continue;
                }
                used += 1;
                if !(sb.lo.cmple(sb.hi).all()) || !sb.lo.is_finite() || !sb.hi.is_finite() {
                    return Err(format!("node {n} slot {s}: invalid box {sb:?}"));
                }
                if let Some(pb) = parent_box {
                    if !pb.contains(sb) {
                        return Err(format!(
                            "node {n} slot {s}: box {sb:?} outside parent {pb:?}"
                        ));
                    }
                }
                if code & LEAF_BIT != 0 {
                    let p = (code & !LEAF_BIT) as usize;
                    if p >= self.packs.len() || std::mem::replace(&mut pack_seen[p], true) {
                        return Err(format!(
                            "node {n} slot {s}: pack {p} out of range or shared"
                        ));
                    }
                    self.validate_pack(p, sb, &mut tri_seen)?;
                } else {
                    let c = code as usize;
                    if c <= n || c >= self.nodes.len() || std::mem::replace(&mut node_seen[c], true)
                    {
                        return Err(format!(
                            "node {n} slot {s}: child node {c} invalid or shared"
                        ));
                    }
                    todo.push((c, Some(sb), depth + 1));
                }
            }
            if used == 0 || (used == 1 && n != 0) {
                return Err(format!("node {n} has {used} children"));
            }
        }
        if let Some(n) = node_seen.iter().position(|s| !s) {
            return Err(format!("node {n} unreachable"));
        }
        if let Some(p) = pack_seen.iter().position(|s| !s) {
            return Err(format!("pack {p} unreachable"));
        }
        for (t, (&seen, tri)) in tri_seen.iter().zip(&self.tris).enumerate() {
            let want = tri.is_some() as u32;
            if seen != want {
                return Err(format!(
                    "triangle {t} referenced {seen} times, expected {want}"
                ));
            }
        }
        if 7 * max_depth + 1 > STACK {
            return Err(format!(
                "depth {max_depth} can overflow the {STACK}-entry stack"
            ));
        }
        Ok(())
    }

    fn validate_pack(&self, p: usize, leaf_box: Aabb, tri_seen: &mut [u32]) -> Result<(), String> {
        let pack = &self.packs[p];
        let count = pack.prim.iter().take_while(|&&t| t != u32::MAX).count();
        if count == 0 || pack.prim[count..].iter().any(|&t| t != u32::MAX) {
            return Err(format!(
                "pack {p}: lanes {:?} not 1..=4 filled then padding",
                pack.prim
            ));
        }
        for lane in 0..4 {
            let corner =
                |k: usize| Vec3::new(pack.v[k][0][lane], pack.v[k][1][lane], pack.v[k][2][lane]);
            if lane >= count {
                if (0..3).any(|k| !corner(k).is_nan()) {
                    return Err(format!("pack {p} lane {lane}: padding lane not NaN"));
                }
                continue;
            }
            let t = pack.prim[lane] as usize;
            let Some(Some(tri)) = self.tris.get(t) else {
                return Err(format!("pack {p} lane {lane}: triangle {t} not usable"));
            };
            tri_seen[t] += 1;
            for (k, c) in tri.iter().enumerate() {
                if corner(k) != *c {
                    return Err(format!(
                        "pack {p} lane {lane}: corner {k} differs from the mesh"
                    ));
                }
                if !leaf_box.contains(Aabb { lo: *c, hi: *c }) {
                    return Err(format!("pack {p} lane {lane}: corner outside the leaf box"));
                }
            }
        }
        Ok(())
    }
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

/// Per-ray constants for the slab and triangle tests.
struct RayPre {
    org: [f32; 3],
    /// `1 / dir`, with zero components replaced by `±f32::MAX` (finite, so `0 * inv = 0`).
    inv: [f32; 3],
    /// Per axis: whether `inv < 0` (the near plane is the box's `hi`).
    neg: [bool; 3],
    tmin: f32,
    /// Woop et al.: the axis of largest |dir| is `kz`; `(kx, ky)` keep the winding.
    k: [usize; 3],
    /// Shear `(dx/dz, dy/dz, 1/dz)` in the permuted axes.
    s: [f32; 3],
}

impl RayPre {
    #[inline(always)]
    fn new(r: &Ray) -> RayPre {
        debug_assert!(
            r.dir != Vec3::ZERO && r.dir.is_finite(),
            "bad ray direction {:?}",
            r.dir
        );
        debug_assert!(r.origin.is_finite(), "bad ray origin {:?}", r.origin);
        debug_assert!(r.tmin >= 0.0 && r.tmin <= r.tmax, "bad ray interval {r:?}");
        let d = r.dir.to_array();
        let inv = d.map(|x| {
            let i = 1.0 / x;
            if i.is_finite() {
                i
            } else {
                f32::MAX.copysign(x)
            }
        });
        let ad = r.dir.abs();
        let kz = ad.max_position();
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        RayPre {
            org: r.origin.to_array(),
            inv,
            neg: inv.map(|i| i < 0.0),
            tmin: r.tmin,
            k: [kx, ky, kz],
            s: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
        }
    }

    /// Slab test of the 8 child boxes for `t` in `[tmin, tmax]`: bit mask of hit children and
    /// their entry distances.
    #[inline(always)]
    fn boxes(&self, n: &Node8, tmax: f32) -> (u32, [f32; 8]) {
        let mut tn = [self.tmin; 8];
        let mut tf = [tmax; 8];
        for a in 0..3 {
            let (near, far) = if self.neg[a] {
                (&n.hi[a], &n.lo[a])
            } else {
                (&n.lo[a], &n.hi[a])
            };
            let (o, inv) = (self.org[a], self.inv[a]);
            for i in 0..8 {
                let t0 = (near[i] - o) * inv;
                let t1 = (far[i] - o) * inv;
                tn[i] = if t0 > tn[i] { t0 } else { tn[i] };
                tf[i] = if t1 < tf[i] { t1 } else { tf[i] };
            }
        }
        let mut mask = 0u32;
        for i in 0..8 {
            mask |= ((tn[i] <= tf[i] * ROBUST_FAR) as u32) << i;
        }
        (mask, tn)
    }

    /// The slab test of [`RayPre::boxes`] in AVX (8 lanes at once).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn boxes_avx(&self, n: &Node8, tmax: f32) -> (u32, [f32; 8]) {
        use std::arch::x86_64::*;
        let mut tn = _mm256_set1_ps(self.tmin);
        let mut tf = _mm256_set1_ps(tmax);
        for a in 0..3 {
            let (near, far) = if self.neg[a] {
                (&n.hi[a], &n.lo[a])
            } else {
                (&n.lo[a], &n.hi[a])
            };
            let (o, inv) = (_mm256_set1_ps(self.org[a]), _mm256_set1_ps(self.inv[a]));
            // SAFETY: `Node8` is 64-byte aligned and each row is 32 bytes at a 32-byte offset.
            let (pn, pf) = unsafe { (_mm256_load_ps(near.as_ptr()), _mm256_load_ps(far.as_ptr())) };
            let t0 = _mm256_mul_ps(_mm256_sub_ps(pn, o), inv);
            let t1 = _mm256_mul_ps(_mm256_sub_ps(pf, o), inv);
            tn = _mm256_max_ps(t0, tn);
            tf = _mm256_min_ps(t1, tf);
        }
        let hit = _mm256_cmp_ps::<_CMP_LE_OQ>(tn, _mm256_mul_ps(tf, _mm256_set1_ps(ROBUST_FAR)));
        let mut out = [0f32; 8];
        // SAFETY: `out` holds 8 floats.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), tn) };
        (_mm256_movemask_ps(hit) as u32, out)
    }

    /// Slab test through the AVX path when `AVX` (checked by the caller), else the portable one.
    #[inline(always)]
    fn boxes_with<const AVX: bool>(&self, n: &Node8, tmax: f32) -> (u32, [f32; 8]) {
        #[cfg(target_arch = "x86_64")]
        if AVX {
            // SAFETY: `AVX` is only true on paths entered after detecting AVX2 and FMA.
            return unsafe { self.boxes_avx(n, tmax) };
        }
        self.boxes(n, tmax)
    }

    /// Watertight test of the 4 triangles of `p` for `t` in `[tmin, tmax]`: the hit mask and,
    /// per lane, the unnormalised barycentrics `[V, W]`, the scaled distance `T` and the
    /// determinant (`t = T / det`, `u = V / det`, `v = W / det`). No division: the interval
    /// test compares `T` against `t * det` with the sign of `det` folded in (as in the paper).
    /// Written lane-wise over `[f32; 4]` so it compiles to 4-wide SIMD.
    #[inline(always)]
    fn tris(&self, p: &TriPack, tmax: f32) -> (u32, [[f32; 4]; 4]) {
        let [kx, ky, kz] = self.k;
        let (ox, oy, oz) = (self.org[kx], self.org[ky], self.org[kz]);
        // Corners relative to the origin, sheared so the ray is the +z axis.
        #[inline(always)]
        fn shear(
            c: &[[f32; 4]; 3],
            [kx, ky, kz]: [usize; 3],
            o: [f32; 3],
            s: [f32; 3],
        ) -> [[f32; 4]; 3] {
            let (px, py, pz) = (&c[kx], &c[ky], &c[kz]);
            let mut r = [[0f32; 4]; 3];
            for i in 0..4 {
                let d = pz[i] - o[2];
                r[0][i] = (px[i] - o[0]) - s[0] * d;
                r[1][i] = (py[i] - o[1]) - s[1] * d;
                r[2][i] = s[2] * d;
            }
            r
        }
        let o = [ox, oy, oz];
        let [ax, ay, az] = shear(&p.v[0], self.k, o, self.s);
        let [bx, by, bz] = shear(&p.v[1], self.k, o, self.s);
        let [cx, cy, cz] = shear(&p.v[2], self.k, o, self.s);
        let mut out = [[0f32; 4]; 4];
        let mut mask = 0u32;
        for i in 0..4 {
            // 2D edge functions: U opposite a, V opposite b, W opposite c.
            let u = cx[i] * by[i] - cy[i] * bx[i];
            let v = ax[i] * cy[i] - ay[i] * cx[i];
            let w = bx[i] * ay[i] - by[i] * ax[i];
            let det = u + v + w;
            let tt = u * az[i] + v * bz[i] + w * cz[i];
            // T * sign(det) against [tmin, tmax] * |det|.
            let sign = det.to_bits() & 0x8000_0000;
            let t_abs = f32::from_bits(tt.to_bits() ^ sign);
            let det_abs = det.abs();
            let inside =
                ((u >= 0.0) & (v >= 0.0) & (w >= 0.0)) | ((u <= 0.0) & (v <= 0.0) & (w <= 0.0));
            let ok =
                inside & (det != 0.0) & (t_abs >= self.tmin * det_abs) & (t_abs <= tmax * det_abs);
            mask |= (ok as u32) << i;
            out[0][i] = v;
            out[1][i] = w;
            out[2][i] = tt;
            out[3][i] = det;
        }
        (mask, out)
    }
}

/// Compare-exchange pairs of local variables: `cas!(a b, c d)` puts the smaller first.
macro_rules! cas {
    ($($a:ident $b:ident),*) => {$(
        let (x, y) = ($a, $b);
        $a = x.min(y);
        $b = x.max(y);
    )*};
}

/// Sort the first 4 of 8 keys ascending (5-comparator network).
#[inline(always)]
fn sort4(k: &mut [u64; 8]) {
    let [mut k0, mut k1, mut k2, mut k3, ..] = *k;
    cas!(k0 k1, k2 k3);
    cas!(k0 k2, k1 k3);
    cas!(k1 k2);
    k[..4].copy_from_slice(&[k0, k1, k2, k3]);
}

/// Sort 8 keys ascending with Knuth's 19-comparator network (branch-free min/max, so no
/// mispredictions on random ray data).
#[inline(always)]
fn sort8(k: &mut [u64; 8]) {
    let [mut k0, mut k1, mut k2, mut k3, mut k4, mut k5, mut k6, mut k7] = *k;
    cas!(k0 k2, k1 k3, k4 k6, k5 k7);
    cas!(k0 k4, k1 k5, k2 k6, k3 k7);
    cas!(k0 k1, k2 k3, k4 k5, k6 k7);
    cas!(k2 k4, k3 k5);
    cas!(k1 k4, k3 k6);
    cas!(k1 k2, k3 k4, k5 k6);
    *k = [k0, k1, k2, k3, k4, k5, k6, k7];
}

/// A fixed-size traversal stack as two locals (entries, length), so the length stays in a
/// register: `stack!(push st, sp, x)` / `stack!(pop st, sp)` (an `Option`). The entries are
/// not zeroed per ray; `validate` guarantees `7 * depth + 1 <= STACK` entries suffice.
macro_rules! stack {
    (new $t:ty) => {
        ([const { MaybeUninit::<$t>::uninit() }; STACK], 0usize)
    };
    (push $st:ident, $sp:ident, $x:expr) => {{
        $st[$sp] = MaybeUninit::new($x);
        $sp += 1;
    }};
    (pop $st:ident, $sp:ident) => {
        if $sp == 0 {
            None
        } else {
            $sp -= 1;
            // SAFETY: every entry below the old length was written by a push.
            Some(unsafe { $st[$sp].assume_init() })
        }
    };
}

impl Bvh {
    /// Start loading the node or triangle pack of child code `code` into the cache (the
    /// traversal is bound by memory latency; this overlaps the loads of stacked subtrees
    /// with work on the current one).
    #[inline(always)]
    fn prefetch(&self, code: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let (ptr, bytes) = if code & LEAF_BIT != 0 {
                let i = ((code & !LEAF_BIT) as usize).min(self.packs.len() - 1);
                (
                    self.packs.as_ptr().wrapping_add(i) as *const i8,
                    size_of::<TriPack>(),
                )
            } else {
                let i = (code as usize).min(self.nodes.len() - 1);
                (
                    self.nodes.as_ptr().wrapping_add(i) as *const i8,
                    size_of::<Node8>(),
                )
            };
            for off in (0..bytes).step_by(64) {
                // SAFETY: prefetching has no architectural effect and cannot fault; the
                // address is inside the node or pack array anyway.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(ptr.wrapping_add(off)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = code;
    }

    #[inline(always)]
    fn occluded_impl<const AVX: bool>(&self, ray: &Ray) -> bool {
        let rp = RayPre::new(ray);
        let (mut st, mut sp) = stack!(new u32);
        let mut cur = 0u32;
        loop {
            if cur & LEAF_BIT == 0 {
                let (mut mask, _) = rp.boxes_with::<AVX>(&self.nodes[cur as usize], ray.tmax);
                if mask != 0 {
                    let child = &self.nodes[cur as usize].child;
                    cur = child[mask.trailing_zeros() as usize];
                    mask &= mask - 1;
                    while mask != 0 {
                        let c = child[mask.trailing_zeros() as usize];
                        self.prefetch(c);
                        stack!(push st, sp, c);
                        mask &= mask - 1;
                    }
                    continue;
                }
            } else {
                let (mask, _) = rp.tris(&self.packs[(cur & !LEAF_BIT) as usize], ray.tmax);
                if mask != 0 {
                    return true;
                }
            }
            match stack!(pop st, sp) {
                Some(c) => cur = c,
                None => return false,
            }
        }
    }

    #[inline(always)]
    fn intersect_impl<const AVX: bool>(&self, ray: &Ray) -> Option<Hit> {
        let rp = RayPre::new(ray);
        let (mut st, mut sp) = stack!(new(u32, f32));
        let mut best_t = ray.tmax;
        let mut best: Option<Hit> = None;
        let mut cur = 0u32;
        loop {
            if cur & LEAF_BIT == 0 {
                let node = &self.nodes[cur as usize];
                let (mask, tn) = rp.boxes_with::<AVX>(node, best_t);
                if mask != 0 {
                    let i0 = mask.trailing_zeros() as usize;
                    let rest = mask & (mask - 1);
                    if rest == 0 {
                        cur = node.child[i0];
                        continue;
                    }
                    if rest & (rest - 1) == 0 {
                        // Two children (the most common case after one): one comparison.
                        let i1 = rest.trailing_zeros() as usize;
                        let (near, far) = if tn[i1] < tn[i0] { (i1, i0) } else { (i0, i1) };
                        self.prefetch(node.child[far]);
                        stack!(push st, sp, (node.child[far], tn[far]));
                        cur = node.child[near];
                        continue;
                    }
                    // Sort the hit children by entry distance (keys `dist bits << 32 | code`;
                    // distances are >= 0, so their bits order like the floats), descend into
                    // the nearest and stack the others nearest-on-top.
                    let key = |i: usize| ((tn[i].to_bits() as u64) << 32) | node.child[i] as u64;
                    let count = mask.count_ones() as usize;
                    let mut keys = [u64::MAX; 8];
                    if count <= 4 {
                        // Three or four children: compact and sort with a 5-comparator network.
                        let mut m = mask;
                        for k in keys.iter_mut().take(count) {
                            *k = key(m.trailing_zeros() as usize);
                            m &= m - 1;
                        }
                        sort4(&mut keys);
                    } else {
                        for (i, k) in keys.iter_mut().enumerate() {
                            *k = if mask & (1 << i) != 0 {
                                key(i)
                            } else {
                                u64::MAX
                            };
                        }
                        sort8(&mut keys);
                    }
                    for &k in keys[1..count].iter().rev() {
                        self.prefetch(k as u32);
                        stack!(push st, sp, (k as u32, f32::from_bits((k >> 32) as u32)));
                    }
                    cur = keys[0] as u32;
                    continue;
                }
            } else {
                let pack = &self.packs[(cur & !LEAF_BIT) as usize];
                let (mut mask, [bv, bw, tt, det]) = rp.tris(pack, best_t);
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let inv_det = 1.0 / det[i];
                    let t = tt[i] * inv_det;
                    if t <= best_t {
                        best_t = t;
                        best = Some(Hit {
                            t,
                            tri: pack.prim[i],
                            u: bv[i] * inv_det,
                            v: bw[i] * inv_det,
                        });
                    }
                }
            }
            // Pop the nearest subtree that can still hold a closer hit.
            loop {
                match stack!(pop st, sp) {
                    Some((c, d)) if d <= best_t => {
                        cur = c;
                        break;
                    }
                    Some(_) => continue,
                    None => return best,
                }
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn occluded_many_avx2(&self, rays: &[Ray], out: &mut [bool]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.occluded_impl::<true>(r);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn intersect_many_avx2(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.intersect_impl::<true>(r);
        }
    }
}

impl RayCaster for Bvh {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut out = [None];
        self.intersect_many(std::slice::from_ref(ray), &mut out);
        out[0]
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let mut out = [false];
        self.occluded_many(std::slice::from_ref(ray), &mut out);
        out[0]
    }

    fn occluded_many(&self, rays: &[Ray], out: &mut [bool]) {
        debug_assert_eq!(rays.len(), out.len());
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU reports AVX2 and FMA.
            return unsafe { self.occluded_many_avx2(rays, out) };
        }
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.occluded_impl::<false>(r);
        }
    }

    fn intersect_many(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        debug_assert_eq!(rays.len(), out.len());
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `occluded_many`.
            return unsafe { self.intersect_many_avx2(rays, out) };
        }
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.intersect_impl::<false>(r);
        }
    }

    fn name(&self) -> &'static str {
        "relight-bvh8"
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::accel::bench::SplitMix64;
    use crate::accel::{build, Backend};

    fn mesh(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> TriMesh {
        TriMesh {
            normals: vec![Vec3::Y; positions.len()],
            uvs: None,
            material_ids: vec![0; indices.len()],
            positions,
            indices,
        }
    }

    /// Closed UV sphere of radius 1 (shared vertices, single-vertex poles, CCW outward).
    pub(crate) fn sphere(stacks: u32, slices: u32) -> TriMesh {
        let mut p = vec![Vec3::Y];
        for i in 1..stacks {
            let th = std::f32::consts::PI * i as f32 / stacks as f32;
            for j in 0..slices {
                let ph = std::f32::consts::TAU * j as f32 / slices as f32;
                p.push(Vec3::new(
                    th.sin() * ph.cos(),
                    th.cos(),
                    -th.sin() * ph.sin(),
                ));
            }
        }
        p.push(-Vec3::Y);
        let ring = |i: u32, j: u32| 1 + (i - 1) * slices + j % slices;
        let south = p.len() as u32 - 1;
        let mut t = Vec::new();
        for j in 0..slices {
            t.push([0, ring(1, j), ring(1, j + 1)]);
            t.push([south, ring(stacks - 1, j + 1), ring(stacks - 1, j)]);
        }
        for i in 1..stacks - 1 {
            for j in 0..slices {
                let (a, b, c, d) = (
                    ring(i, j),
                    ring(i, j + 1),
                    ring(i + 1, j),
                    ring(i + 1, j + 1),
                );
                t.push([a, c, d]);
                t.push([a, d, b]);
            }
        }
        mesh(p, t)
    }

    /// `n x n` quads on a bumpy height field over `[-1, 1]^2` (shared vertices and edges).
    fn grid(n: u32, rng: &mut SplitMix64) -> TriMesh {
        let mut p = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let (x, z) = (
                    2.0 * i as f32 / n as f32 - 1.0,
                    2.0 * j as f32 / n as f32 - 1.0,
                );
                p.push(Vec3::new(x, 0.1 * rng.next_f32(), z));
            }
        }
        let id = |i: u32, j: u32| i * (n + 1) + j;
        let mut t = Vec::new();
        for i in 0..n {
            for j in 0..n {
                t.push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
                t.push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
            }
        }
        mesh(p, t)
    }

    /// `n` random triangles of varied sizes in `[-1, 1]^3`.
    fn soup(n: usize, rng: &mut SplitMix64) -> TriMesh {
        let mut p = Vec::new();
        let mut u = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let mut t = Vec::new();
        for i in 0..n as u32 {
            let (c, s) = (u(), 0.02 + 0.3 * (i % 7) as f32 / 7.0);
            p.extend([c, c + u() * s, c + u() * s]);
            t.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        mesh(p, t)
    }

    fn unit(rng: &mut SplitMix64) -> Vec3 {
        loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    type D3 = [f64; 3];
    fn d3(v: Vec3) -> D3 {
        [v.x as f64, v.y as f64, v.z as f64]
    }
    fn sub(a: D3, b: D3) -> D3 {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    fn dot(a: D3, b: D3) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }
    fn cross(a: D3, b: D3) -> D3 {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    /// Reference: Möller & Trumbore 1997 in f64 over every triangle.
    fn brute(m: &TriMesh, r: &Ray) -> Option<(f64, u32)> {
        let (o, d) = (d3(r.origin), d3(r.dir));
        let mut best: Option<(f64, u32)> = None;
        for tri in 0..m.triangle_count() {
            let [a, b, c] = m.triangle(tri).map(d3);
            let (e1, e2) = (sub(b, a), sub(c, a));
            let pv = cross(d, e2);
            let det = dot(e1, pv);
            if det == 0.0 || !det.is_finite() {
                continue;
            }
            let tv = sub(o, a);
            let u = dot(tv, pv) / det;
            let qv = cross(tv, e1);
            let v = dot(d, qv) / det;
            let t = dot(e2, qv) / det;
            if u >= 0.0
                && v >= 0.0
                && u + v <= 1.0
                && t >= r.tmin as f64
                && t <= r.tmax as f64
                && best.is_none_or(|(bt, _)| t < bt)
            {
                best = Some((t, tri as u32));
            }
        }
        best
    }

    /// Random rays: from inside and outside the meshes, some with axis-aligned directions
    /// (zero components, infinite inverse), some with a limited `[tmin, tmax]`.
    fn rays(n: usize, rng: &mut SplitMix64) -> Vec<Ray> {
        (0..n)
            .map(|i| {
                let o =
                    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0) * 1.6;
                let mut d = unit(rng);
                match i % 4 {
                    0 => d = Vec3::AXES[i / 4 % 3] * if rng.next_f32() < 0.5 { -1.0 } else { 1.0 },
                    1 => d.y = 0.0,
                    _ => {}
                }
                let d = if d == Vec3::ZERO { Vec3::X } else { d };
                let (tmin, tmax) = if i % 3 == 0 {
                    (rng.next_f32() * 0.5, 0.5 + rng.next_f32() * 1.5)
                } else {
                    (0.0, f32::INFINITY)
                };
                Ray::new(o, d, tmin, tmax)
            })
            .collect()
    }

    /// Compare `c` against the brute-force loop on `rs`; ignores rays whose reference hit is
    /// within 1e-4 (relative) of `tmin`/`tmax`, where f32 and f64 may legitimately disagree.
    fn check_against_brute(m: &TriMesh, c: &dyn RayCaster, rs: &[Ray]) {
        let mut hits = 0;
        for r in rs {
            let want = brute(m, r);
            let near_limit = |t: f64| {
                (t - r.tmin as f64).abs() <= 1e-4 * t.abs().max(1e-3)
                    || (r.tmax.is_finite() && (t - r.tmax as f64).abs() <= 1e-4 * t.abs())
            };
            if want.is_some_and(|(t, _)| near_limit(t)) {
                continue;
            }
            let got = c.intersect(r);
            assert_eq!(
                c.occluded(r),
                want.is_some(),
                "{}: occluded {r:?} want {want:?}",
                c.name()
            );
            match (got, want) {
                (None, None) => {}
                (Some(h), Some((t, tri))) => {
                    hits += 1;
                    assert!(
                        ((h.t as f64 - t) / t.max(1e-3)).abs() < 1e-4,
                        "{}: t {} vs {t} for {r:?}",
                        c.name(),
                        h.t
                    );
                    if h.tri != tri {
                        // A tie: the reported triangle must be hit at the same t.
                        let [a, b, cc] = m.triangle(h.tri as usize);
                        let p = a * (1.0 - h.u - h.v) + b * h.u + cc * h.v;
                        assert!(
                            (p - r.at(h.t)).length() < 1e-4,
                            "{}: tri {} vs {tri}",
                            c.name(),
                            h.tri
                        );
                    }
                    // Barycentrics reproduce the hit point.
                    let p = m.point(h.tri as usize, h.u, h.v);
                    assert!(
                        (p - r.at(h.t)).length() < 1e-4 * (1.0 + h.t),
                        "{}: bary {h:?}",
                        c.name()
                    );
                }
                _ => panic!("{}: {r:?} got {got:?} want {want:?}", c.name()),
            }
        }
        assert!(
            hits > rs.len() / 20,
            "{}: too few hits ({hits}) to test anything",
            c.name()
        );
    }

    fn test_meshes() -> Vec<(&'static str, TriMesh)> {
        let mut rng = SplitMix64(11);
        vec![
            ("soup", soup(600, &mut rng)),
            ("sphere", sphere(12, 24)),
            ("grid", grid(20, &mut rng)),
        ]
    }

    #[test]
    fn bvh_matches_brute_force_for_every_preset() {
        let mut rng = SplitMix64(5);
        for (name, m) in test_meshes() {
            let rs = rays(1500, &mut rng);
            for preset in BuildPreset::ALL {
                let b = Bvh::build(&m, preset).unwrap();
                b.validate()
                    .unwrap_or_else(|e| panic!("{name} {preset:?}: {e}"));
                check_against_brute(&m, &b, &rs);
                // The scalar (non-AVX2) path too.
                #[cfg(target_arch = "x86_64")]
                check_against_brute(&m, &Bvh { avx2: false, ..b }, &rs);
            }
        }
    }

    #[test]
    fn every_backend_matches_brute_force() {
        let mut rng = SplitMix64(6);
        for (_, m) in test_meshes() {
            let rs = rays(1500, &mut rng);
            for &backend in Backend::available() {
                check_against_brute(&m, &*build(&m, backend).unwrap(), &rs);
            }
        }
    }

    #[test]
    fn many_queries_match_single_ones() {
        let m = sphere(10, 20);
        let rs = rays(700, &mut SplitMix64(8));
        for &backend in Backend::available() {
            let c = build(&m, backend).unwrap();
            let mut occ = vec![false; rs.len()];
            let mut hit = vec![None; rs.len()];
            c.occluded_many(&rs, &mut occ);
            c.intersect_many(&rs, &mut hit);
            for (i, r) in rs.iter().enumerate() {
                assert_eq!(occ[i], c.occluded(r));
                assert_eq!(hit[i], c.intersect(r));
            }
        }
    }

    #[test]
    fn large_random_mesh_validates_and_matches() {
        // Enough triangles for parallel subtrees (PAR_MIN) and several wide levels.
        let m = soup(20_000, &mut SplitMix64(9));
        for preset in BuildPreset::ALL {
            let b = Bvh::build(&m, preset).unwrap();
            b.validate().unwrap();
            assert!(b.size().0 > 100, "{:?}", b.size());
            check_against_brute(&m, &b, &rays(150, &mut SplitMix64(10)));
        }
    }

    /// Rays from inside a closed mesh aimed exactly at its vertices and at points on its
    /// edges: a watertight caster hits every one.
    fn check_watertight(m: &TriMesh, c: &dyn RayCaster) -> usize {
        let mut rng = SplitMix64(12);
        let mut misses = 0;
        let mut n = 0;
        for origin in [
            Vec3::ZERO,
            Vec3::new(0.31, -0.2, 0.17),
            Vec3::new(-0.5, 0.4, 0.1),
        ] {
            for (k, t) in m.indices.iter().enumerate() {
                let [a, b, cc] = t.map(|i| m.positions[i as usize]);
                let s = rng.next_f32();
                // A vertex, and points on two edges (computed in f32, so on or a rounding off).
                for target in [a, a + (b - a) * s, b + (cc - b) * 0.5] {
                    let r = Ray::new(origin, target - origin, 0.0, f32::INFINITY);
                    n += 1;
                    if c.intersect(&r).is_none() || !c.occluded(&r) {
                        misses += 1;
                        eprintln!("{}: ray {r:?} (triangle {k}) slipped through", c.name());
                    }
                }
            }
        }
        assert!(n > 1000);
        misses
    }

    #[test]
    fn bvh_is_watertight() {
        // A sphere with jittered vertices, so edges are not aligned with anything.
        let mut m = sphere(16, 32);
        let mut rng = SplitMix64(13);
        for p in &mut m.positions {
            *p *= 1.0 + 0.05 * rng.next_f32();
        }
        for preset in BuildPreset::ALL {
            let b = Bvh::build(&m, preset).unwrap();
            b.validate().unwrap();
            assert_eq!(check_watertight(&m, &b), 0);
        }
    }

    #[cfg(feature = "embree")]
    #[test]
    fn embree_robust_is_watertight() {
        let m = sphere(16, 32);
        let e = crate::accel::embree::EmbreeScene::build_robust(&m).unwrap();
        assert_eq!(check_watertight(&m, &e), 0);
    }

    #[test]
    fn empty_and_invalid_meshes_are_errors() {
        for &backend in Backend::available() {
            assert!(build(&TriMesh::default(), backend).is_err());
            let degenerate = mesh(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]]);
            assert!(build(&degenerate, backend).is_err());
            let out_of_range = mesh(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 3]]);
            assert!(build(&out_of_range, backend).is_err());
        }
    }

    #[test]
    fn degenerate_triangles_are_ignored() {
        // A unit triangle plus a zero-area one, a collinear one and one with a NaN corner,
        // all on the ray's path.
        let p = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, -0.5),
            Vec3::new(-1.0, 0.0, -0.3),
            Vec3::new(1.0, 0.0, -0.3),
            Vec3::new(0.0, f32::NAN, -0.2),
        ];
        let m = mesh(p, vec![[3, 3, 3], [4, 3, 5], [0, 1, 2], [6, 4, 5]]);
        let r = Ray::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        for preset in BuildPreset::ALL {
            let b = Bvh::build(&m, preset).unwrap();
            b.validate().unwrap();
            assert_eq!(b.intersect(&r).map(|h| h.tri), Some(2));
        }
        for &backend in Backend::available() {
            let c = build(&m, backend).unwrap();
            assert_eq!(c.intersect(&r).map(|h| h.tri), Some(2), "{}", c.name());
            assert!(c.occluded(&r));
        }
    }

    #[test]
    fn sort8_sorts_every_zero_one_input() {
        // Zero-one principle: a comparator network sorting all 2^8 binary inputs sorts all.
        for bits in 0u32..256 {
            let mut k = [0u64; 8];
            for (i, x) in k.iter_mut().enumerate() {
                *x = (bits >> i & 1) as u64;
            }
            sort8(&mut k);
            assert!(k.windows(2).all(|w| w[0] <= w[1]), "{bits:08b} -> {k:?}");
        }
    }

    #[test]
    fn sort4_sorts_every_zero_one_input() {
        for bits in 0u32..16 {
            let mut k = [9u64; 8];
            for (i, x) in k.iter_mut().take(4).enumerate() {
                *x = (bits >> i & 1) as u64;
            }
            sort4(&mut k);
            assert!(k.windows(2).all(|w| w[0] <= w[1]), "{bits:04b} -> {k:?}");
        }
    }

    #[test]
    fn validate_catches_corruption() {
        let m = sphere(12, 24);
        let good = Bvh::build(&m, BuildPreset::Quality).unwrap();
        good.validate().unwrap();
        // Shrink a child box: it no longer holds its triangles.
        let mut b = Bvh::build(&m, BuildPreset::Quality).unwrap();
        b.nodes[0].hi[0][0] = b.nodes[0].lo[0][0];
        assert!(b.validate().is_err());
        // Reference a triangle twice.
        let mut b = Bvh::build(&m, BuildPreset::Quality).unwrap();
        b.packs[1].prim[0] = b.packs[0].prim[0];
        assert!(b.validate().is_err());
        // Lose a triangle.
        let mut b = Bvh::build(&m, BuildPreset::Quality).unwrap();
        b.tris.push(Some(m.triangle(0)));
        assert!(b.validate().is_err());
    }
}
