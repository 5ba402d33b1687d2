//! Adaptive angular refinement (paper section 4.2, Fig. 3): for one surface point, views are
//! added by icosahedral level until the slices of the next level are predicted well enough
//! by interpolating the current level's.
//!
//! # The rule
//! Start at level `lo` (all its views computed). While the level `L` is below `hi`: compute
//! the slices of level `L + 1` (a view of `L + 1` that is also a view of `L`, the geodesic
//! construction being nested, reuses its slice), predict each **new** view's slice from level
//! `L`'s by eq. 6 ([`ViewTable::interpolate`]), and take the mean over the new views of the L2
//! distance between computed and predicted slices ([`slice_distance`], section 4.1). If it is
//! below the threshold, stop and keep level `L`: its interpolation was checked against a finer
//! level and found good enough, so the finer slices are not stored (the vertex stores the
//! coarsest level that passed, which is what "we continue this process as long as these
//! slices improve the quality of the approximation significantly" asks). Otherwise keep
//! level `L + 1` and go on. At `hi` (at most [`MAX_VIEW_LEVEL`], the paper's 5) the process
//! stops without a test.
//!
//! So a vertex whose slices do not depend on the view (a diffuse point under an open sky)
//! stops at `lo` after one test, and a glossy one refines until its highlight moves little
//! between neighbouring views.
//!
//! # Determinism
//! The slice of view `v` of level `l` at vertex `x` is drawn from stream
//! [`slice_stream`]`(x, l, v)` (a reused view keeps the stream of the level that computed it),
//! so a bake depends on the seed only.

use super::bake::MAX_VIEW_LEVEL;
use super::interp::{slice_distance, ViewTable};
use super::slice::TransferSlice;
use glam::Vec3;

/// Streams reserved per vertex: every view of every level, `sum_l views(l)`, rounded up.
const STREAMS_PER_VERTEX: u64 = 1 << 14;

/// The first stream of each level's views: the view counts of the levels below, summed.
const LEVEL_STREAM_BASE: [u64; MAX_VIEW_LEVEL as usize + 1] = [0, 4, 21, 94, 399, 1648];

/// Views of all levels together: `sum_l views(l)` for `l` in `0..=MAX_VIEW_LEVEL`.
pub const LEVEL_VIEWS: usize = 6705;

/// The index of view `v` of `level` among the views of all levels (`< LEVEL_VIEWS`).
///
/// # Panics
/// Debug builds assert a level up to [`MAX_VIEW_LEVEL`] and a view of it.
pub fn level_view(level: u32, v: usize) -> usize {
    debug_assert!(level <= MAX_VIEW_LEVEL);
    LEVEL_STREAM_BASE[level as usize] as usize + v
}

/// The random stream of the slice of view `v` of level `level` at vertex `x`.
///
/// # Panics
/// Debug builds assert a level up to [`MAX_VIEW_LEVEL`] and a view of it.
pub fn slice_stream(x: usize, level: u32, v: usize) -> u64 {
    debug_assert!(level <= MAX_VIEW_LEVEL);
    // Level l's views start after those of the levels below it (4, 17, 73, 305, 1249 and
    // 5057 views; tested).
    debug_assert!(level_view(level, v) < LEVEL_VIEWS);
    x as u64 * STREAMS_PER_VERTEX + level_view(level, v) as u64
}

/// The views of levels `0..=hi` and, for each level above 0, which of its views are views
/// of the level below (built once per bake).
#[derive(Clone, Debug)]
pub struct Refiner {
    tables: Vec<ViewTable>,
    /// `parent[l][v]`: the index of view `v` of level `l` among the views of level `l - 1`.
    parent: Vec<Vec<Option<usize>>>,
}

/// What refining one point gave.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexRefinement {
    /// The level kept.
    pub level: u32,
    /// One slice per view of `level`.
    pub slices: Vec<TransferSlice>,
    /// The mean distance of each test, from `lo`: entry `i` compares level `lo + i + 1`'s
    /// new slices with their prediction from level `lo + i`.
    pub distances: Vec<f32>,
}

impl Refiner {
    /// The tables of levels `0..=hi`.
    ///
    /// # Panics
    /// If `hi > MAX_VIEW_LEVEL`.
    pub fn new(hi: u32) -> Refiner {
        assert!(hi <= MAX_VIEW_LEVEL, "view level {hi}");
        let tables: Vec<ViewTable> = (0..=hi).map(ViewTable::new).collect();
        let parent = (0..=hi as usize)
            .map(|l| {
                if l == 0 {
                    return vec![];
                }
                let coarse = &tables[l - 1];
                tables[l]
                    .views()
                    .iter()
                    .map(|&v| {
                        let (i, w) = coarse.locate(v);
                        (0..3)
                            .find(|&k| w[k] > 1.0 - 1e-4)
                            .map(|k| i[k])
                            .filter(|&j| coarse.views()[j].dot(v) > 1.0 - 1e-6)
                    })
                    .collect()
            })
            .collect();
        Refiner { tables, parent }
    }

    /// The table of `level`.
    ///
    /// # Panics
    /// If `level` is above the refiner's `hi`.
    pub fn table(&self, level: u32) -> &ViewTable {
        &self.tables[level as usize]
    }

    /// Refine one point from level `lo` up to at most `hi` (module docs) with `threshold` on
    /// the mean L2 distance; `compute(level, v, view)` gives the slice of view `v` (local
    /// frame) of `level`. `on_refine(level)` is called each time the point moves up to
    /// `level` (progress reports).
    ///
    /// # Panics
    /// If `lo > hi` or `hi` is above the refiner's; debug builds assert a finite threshold.
    pub fn refine(
        &self,
        lo: u32,
        hi: u32,
        threshold: f32,
        mut compute: impl FnMut(u32, usize, Vec3) -> TransferSlice,
        mut on_refine: impl FnMut(u32),
    ) -> VertexRefinement {
        assert!(lo <= hi && (hi as usize) < self.tables.len(), "{lo}..={hi}");
        debug_assert!(threshold.is_finite());
        let mut level = lo;
        let mut slices: Vec<TransferSlice> = self
            .table(lo)
            .views()
            .iter()
            .enumerate()
            .map(|(v, &d)| compute(lo, v, d))
            .collect();
        let mut distances = vec![];
        while level < hi {
            let (coarse, fine) = (self.table(level), self.table(level + 1));
            let parent = &self.parent[level as usize + 1];
            let (mut sum, mut new) = (0.0f64, 0usize);
            let next: Vec<TransferSlice> = fine
                .views()
                .iter()
                .enumerate()
                .map(|(v, &d)| match parent[v] {
                    Some(p) => slices[p],
                    None => {
                        let s = compute(level + 1, v, d);
                        sum += slice_distance(&s, &coarse.interpolate(&slices, d)) as f64;
                        new += 1;
                        s
                    }
                })
                .collect();
            let mean = (sum / new.max(1) as f64) as f32;
            distances.push(mean);
            if mean < threshold {
                break;
            }
            level += 1;
            slices = next;
            on_refine(level);
        }
        VertexRefinement {
            level,
            slices,
            distances,
        }
    }
}

#[cfg(test)]
mod tests;
