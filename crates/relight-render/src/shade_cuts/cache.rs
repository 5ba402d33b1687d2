//! The merged cuts of the visible triangles, kept across frames for one light cut: what
//! makes [`super::CutsShader::render`]'s glossy frames cheap while the camera moves or the
//! materials change (Cheslack-Postava et al. 2008, sec. 3.2's merge, sec. 4.2's Eq. 5).
//!
//! A triangle's merged cut (`shade_cuts::triangle`: its three vertex cuts and the light cut,
//! the traversal of sec. 3.2) depends on the triangle and the light cut only: neither on the
//! camera, nor on the fragments' barycentric weights, nor on the material (the BRDF is applied
//! per fragment). The paper merges at every pixel of every frame; on the CPU that traversal
//! is about two thirds of a glossy frame (docs/RESULTS.md §11). So the first frame under a
//! light cut merges each visible triangle as before and records its clusters here in a
//! compact form; the next frames under the same light cut (the camera moving, materials
//! edited) rebuild the per-fragment arrays from the record with no traversal, and merge only
//! the triangles that came into view. A new light cut (a new environment or rotation) starts
//! an empty cache.
//!
//! **Record**: per kept cluster 12 bytes, its tree node, its position in the light cut and
//! the three corners' quantised visibility means (the bake's own `u16`), from which
//! [`super::triangle::TriangleCut::expand`] computes exactly what the traversal computes
//! (`|C'| <L O>` from the light cut's node value and the node's light count, the node's
//! direction and `cos theta_p`, the dequantised means, in the same order): the same
//! bits as a fresh merge (tested).
//!
//! **Memory**: at most `budget` bytes of records (default [`DEFAULT_BUDGET`]); a triangle
//! that would exceed it is merged per frame as without the cache. At the start of a frame,
//! when three quarters of the budget are used, the records of triangles not drawn in the
//! previous frame are dropped (the camera moved away from them). Per triangle the cache
//! also holds a slot of 32 bytes. Light cuts of more than 65,536 nodes are not cached (the
//! position is stored in 16 bits).

use super::triangle::TriangleCut;
use super::CutsShader;
use relight_bake::cuts::light_cut::LightCut;
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering::Relaxed};
use std::sync::Mutex;

/// The default budget of the records, bytes (256 MiB: the bunny's 26K visible triangles at
/// 512 x 512 and light cut 256 take about 100 MiB).
pub const DEFAULT_BUDGET: usize = 256 << 20;

/// One kept cluster of a triangle's merged cut (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub(super) struct Cluster {
    /// The cluster's tree node (post-order index).
    pub node: u32,
    /// Position in the light cut of the node containing it.
    pub light: u16,
    /// The three corners' quantised visibility means.
    pub vis: [u16; 3],
}

/// What [`TriangleCut::expand`] reads of a tree node under the current light cut.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub(super) struct NodeInfo {
    /// The node's direction ([`LightCut::direction`]).
    pub dir: [f32; 3],
    /// [`LightCut::rule_cos`]: `cos theta_p` of its five-point rule, 1 if it does not spread.
    pub ring_cos: f32,
}

/// One triangle's record and the frame it was last drawn in.
#[derive(Default)]
struct Slot {
    cut: Mutex<Option<Box<[Cluster]>>>,
    used: AtomicU32,
}

/// The merged cuts of one light cut (module docs).
pub(super) struct MergedCache {
    slots: Vec<Slot>,
    /// Per tree node, its direction and `cos theta_p` ([`NodeInfo`]).
    pub(super) nodes: Vec<NodeInfo>,
    /// Per tree node, its number of lights `|C|` as `f32`.
    pub(super) leaves: Vec<f32>,
    bytes: AtomicUsize,
    budget: usize,
    frame: AtomicU32,
}

thread_local! {
    /// Each rendering thread's record being built (its records are copied out exactly sized).
    static RECORD: std::cell::RefCell<Vec<Cluster>> = Default::default();
}

impl MergedCache {
    /// An empty cache for `light` over `shader`'s mesh and tree, holding at most `budget`
    /// bytes of records; `None` if `budget` is 0 or the light cut is too long to record.
    pub(super) fn new(shader: &CutsShader<'_>, light: &LightCut, budget: usize) -> Option<Self> {
        if budget == 0 || light.len() > 1 << 16 {
            return None;
        }
        let tree = &shader.bake.tree;
        let nodes = (0..tree.nodes().len() as u32)
            .map(|p| NodeInfo {
                dir: light.direction(p).to_array(),
                ring_cos: light.rule_cos(p),
            })
            .collect();
        let leaves = tree.nodes().iter().map(|n| n.leaves as f32).collect();
        Some(MergedCache {
            slots: (0..shader.mesh.indices.len())
                .map(|_| Slot::default())
                .collect(),
            nodes,
            leaves,
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
                let mut cut = s.cut.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(c) = cut.take() {
                    self.bytes.fetch_sub(size_of_val(&*c), Relaxed);
                }
            }
        }
    }

    /// Triangle `tri`'s merged cut into `t`: from its record if there is one, else merged
    /// (`TriangleCut::build`) and recorded if the budget allows.
    pub(super) fn fill(
        &self,
        t: &mut TriangleCut,
        shader: &CutsShader<'_>,
        light: &LightCut,
        tri: u32,
        spread: bool,
    ) {
        let slot = &self.slots[tri as usize];
        slot.used.store(self.frame.load(Relaxed), Relaxed);
        let mut cut = slot.cut.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = &*cut {
            t.expand(light, self, c, spread);
            return;
        }
        if self.bytes() >= self.budget {
            t.build(shader, light, tri, spread, None);
            return;
        }
        RECORD.with_borrow_mut(|r| {
            r.clear();
            t.build(shader, light, tri, spread, Some(r));
            let size = size_of_val(&r[..]);
            if self.bytes.fetch_add(size, Relaxed) + size <= self.budget {
                *cut = Some(r[..].into());
            } else {
                self.bytes.fetch_sub(size, Relaxed);
            }
        });
    }
}
