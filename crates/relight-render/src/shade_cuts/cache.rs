//! The triangles' visibility unions, kept across frames and light cuts: what makes
//! [`super::CutsShader::render`]'s glossy frames cheap while the camera moves, the materials
//! change **or the environment changes or rotates** (Cheslack-Postava et al. 2008, sec. 3.2's
//! merge, sec. 4.2's Eq. 5).
//!
//! A triangle's merged cut (`shade_cuts::triangle`) is the union of four cuts: its three
//! vertex cuts and the light cut (the traversal of sec. 3.2). The paper merges at every pixel
//! of every frame; on the CPU that traversal was about two thirds of a glossy frame. The
//! merge is split in two here:
//!
//! 1. **The visibility union** of the three vertex cuts (the same traversal over three cuts),
//!    which depends on the triangle alone: neither on the camera, the fragments' barycentric
//!    weights, the material, nor the light cut. It is recorded the first time the triangle
//!    is drawn and kept. Per cluster 16 bytes: its tree node, its leftmost leaf and the three
//!    corners' quantised visibility means (the bake's own `u16`); clusters no corner sees
//!    are not kept (they add nothing under any light).
//! 2. **The union with the light cut**, per frame, by one pass over the record with a table
//!    of the light cut ([`LightTables`], built once per light cut): every cut partitions the
//!    leaves, so the light-cut node holding a union cluster's leftmost leaf either contains
//!    the cluster (the cluster is a merged cluster, lit by that node) or lies inside it (then
//!    the light-cut nodes from there up to the cluster's post-order index are the merged
//!    clusters, each with the cluster's visibility). Both cases emit the clusters in the
//!    traversal's order with the traversal's arithmetic, so a frame from the records is **the
//!    same bits as a fresh merge** (tested).
//!
//! A new light cut (a new environment or rotation) keeps the records: its first frame costs
//! the pass, not the traversal. Only triangles drawn for the first time are merged.
//!
//! **Memory**: at most `budget` bytes of records (default [`DEFAULT_BUDGET`]); a triangle
//! that would exceed it is merged per frame as without the cache. At the start of a frame,
//! when three quarters of the budget are used, the records of triangles not drawn in the
//! previous frame are dropped (the camera moved away from them). Per triangle the cache also
//! holds a slot of 32 bytes, and per light cut a table of 18 bytes per tree node. Light cuts
//! of more than 65,536 nodes are not tabled (the position is stored in 16 bits): their frames
//! merge every triangle.

use super::triangle::TriangleCut;
use super::CutsShader;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::tree::LightTree;
use relight_scene::mesh::TriMesh;
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering::Relaxed};
use std::sync::Mutex;

/// The default budget of the records, bytes (256 MiB: the unions of the bunny's triangles
/// drawn over nine frames of an orbit at 512 x 512 take 110 MiB).
pub const DEFAULT_BUDGET: usize = 256 << 20;

/// One cluster of a triangle's visibility union (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub(super) struct Cluster {
    /// The cluster's tree node (post-order index).
    pub node: u32,
    /// Its leftmost leaf (post-order index).
    pub leftleaf: u32,
    /// The three corners' quantised visibility means, not all zero.
    pub vis: [u16; 3],
}

/// What [`TriangleCut::walk`] reads of a tree node under the current light cut.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub(super) struct NodeInfo {
    /// The node's direction ([`LightCut::direction`]).
    pub dir: [f32; 3],
    /// [`LightCut::rule_cos`]: `cos theta_p` of its five-point rule, 1 if it does not spread.
    pub ring_cos: f32,
}

/// The tables of one light cut that the pass over a record reads (module docs, step 2).
pub(super) struct LightTables {
    /// Per tree node, its direction and `cos theta_p` ([`NodeInfo`]).
    pub nodes: Vec<NodeInfo>,
    /// Per tree node in the subtree of a light-cut node, that node's position in the light
    /// cut (read at leaves; nodes above the light cut hold 0 and are never read).
    pub cover: Vec<u16>,
}

impl LightTables {
    /// The tables of `light` over `tree`; `None` if the light cut has more than 65,536 nodes.
    pub(super) fn new(tree: &LightTree, light: &LightCut) -> Option<Self> {
        if light.len() > 1 << 16 {
            return None;
        }
        let nodes = (0..tree.nodes().len() as u32)
            .map(|p| NodeInfo {
                dir: light.direction(p).to_array(),
                ring_cos: light.rule_cos(p),
            })
            .collect();
        let mut cover = vec![0u16; tree.nodes().len()];
        // A node's subtree is the post-order range [leftleaf, index].
        for (p, (&i, &l)) in light.index.iter().zip(&light.leftleaf).enumerate() {
            cover[l as usize..=i as usize].fill(p as u16);
        }
        Some(LightTables { nodes, cover })
    }
}

/// One triangle's record and the frame it was last drawn in.
#[derive(Default)]
struct Slot {
    union: Mutex<Option<Box<[Cluster]>>>,
    used: AtomicU32,
}

/// The visibility unions of the drawn triangles (module docs).
pub(super) struct MergedCache {
    slots: Vec<Slot>,
    bytes: AtomicUsize,
    budget: usize,
    frame: AtomicU32,
}

thread_local! {
    /// Each rendering thread's record being built (its records are copied out exactly sized).
    static RECORD: std::cell::RefCell<Vec<Cluster>> = Default::default();
}

impl MergedCache {
    /// An empty cache over `mesh`'s triangles, holding at most `budget` bytes of records;
    /// `None` if `budget` is 0.
    pub(super) fn new(mesh: &TriMesh, budget: usize) -> Option<Self> {
        if budget == 0 {
            return None;
        }
        Some(MergedCache {
            slots: (0..mesh.indices.len()).map(|_| Slot::default()).collect(),
            bytes: AtomicUsize::new(0),
            budget,
            frame: AtomicU32::new(1),
        })
    }

    /// Bytes of records held.
    pub(super) fn bytes(&self) -> usize {
        self.bytes.load(Relaxed)
    }

    /// Start a frame: when three quarters of the budget are used, drop the records of the
    /// triangles not drawn in the previous frame.
    pub(super) fn begin_frame(&self) {
        let frame = self.frame.fetch_add(1, Relaxed) + 1;
        if self.bytes() * 4 < self.budget * 3 {
            return;
        }
        for s in &self.slots {
            if s.used.load(Relaxed) + 1 < frame {
                let mut union = s.union.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(c) = union.take() {
                    self.bytes.fetch_sub(size_of_val(&*c), Relaxed);
                }
            }
        }
    }

    /// Triangle `tri`'s merged cut with `light` (whose tables are `tables`) into `t`: by the
    /// pass over its record (module docs), recorded first if it has none and the budget
    /// allows, else merged (`TriangleCut::build`).
    pub(super) fn fill(
        &self,
        t: &mut TriangleCut,
        shader: &CutsShader<'_>,
        (light, tables): (&LightCut, &LightTables),
        tri: u32,
        spread: bool,
    ) {
        let slot = &self.slots[tri as usize];
        slot.used.store(self.frame.load(Relaxed), Relaxed);
        let mut union = slot.union.lock().unwrap_or_else(|e| e.into_inner());
        if union.is_none() {
            if self.bytes() >= self.budget {
                t.build(shader, light, tri, spread);
                return;
            }
            let record = RECORD.with_borrow_mut(|r| {
                TriangleCut::union(shader, tri, r);
                let size = size_of_val(&r[..]);
                if self.bytes.fetch_add(size, Relaxed) + size <= self.budget {
                    Some(r[..].into())
                } else {
                    self.bytes.fetch_sub(size, Relaxed);
                    None
                }
            });
            match record {
                Some(r) => *union = Some(r),
                None => {
                    t.build(shader, light, tri, spread);
                    return;
                }
            }
        }
        let record = union.as_deref().expect("recorded above");
        t.walk(light, tables, record, spread);
    }
}
