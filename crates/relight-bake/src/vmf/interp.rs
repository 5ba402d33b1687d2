//! Interpolation of transfer slices (paper eq. 6, Fig. 2b): the slice of a view or a surface
//! point that was not computed is made from nearby computed slices by interpolating each
//! lobe's parameters,
//!
//! ```text
//! mu~ = T(mu) / |T(mu)|,   kappa~ = T(kappa),   alpha~ = T(alpha)          (eq. 6)
//! ```
//!
//! with `T` the barycentric interpolation over three corners (three views of a vertex, section
//! 6.1: "barycentric interpolation of the 3 closest computed view-points"; or the three
//! vertices of a triangle, section 4.3). Lobe `(term, class)` is blended with the same lobe of
//! the other corners (one lobe per light-path class, so the correspondence is given).
//!
//! # One deviation, stated
//! A corner whose lobe has zero amplitude (an empty class: no escaping sample, see
//! [`super::slice`]) has no direction: its axis (the normal) and `kappa = 0` are placeholders.
//! It takes part in `alpha~` with its weight but not in `mu~` and `kappa~`, whose weights are
//! renormalised over the corners that carry light. Blending the placeholders would pull a
//! highlight towards the normal and flatten it next to an occluder that hides the class.
//!
//! # Views of a vertex ([`ViewTable`])
//! The views of a level are the icosphere vertices with `z > 0` (local frame,
//! [`super::views_of_level`]). A view is located on the level's icosphere (triangle and
//! spherical-cone barycentrics); corners at or below the horizon were not computed, and their
//! weights go to the other corners (renormalised; a direction with `z > 0` is never in a
//! triangle whose three corners have `z <= 0`, since the cone of such corners lies in `z <= 0`).
//! Views at or below the horizon (a back-facing vertex seen at a silhouette) are moved just
//! above it.

use super::bake::{views_of_level, MAX_VIEW_LEVEL};
use super::slice::TransferSlice;
use glam::Vec3;
use relight_sphere::icosphere::Icosphere;
use relight_sphere::vmf::{mixture_l2_distance_squared, VmfLobe};

/// Height above the horizon that views at or below it are moved to (local `z`).
pub const HORIZON_Z: f32 = 1e-3;

/// Eq. 6 over three corners with weights `w` (non-negative, summing to 1), with the
/// zero-amplitude rule of the module docs. Three zero lobes give a zero lobe (axis of the
/// first corner, `kappa = 0`).
///
/// # Panics
/// Debug builds assert non-negative finite weights.
#[inline]
pub fn blend_lobes(l: [&VmfLobe; 3], w: [f32; 3]) -> VmfLobe {
    debug_assert!(w.iter().all(|x| x.is_finite() && *x >= 0.0), "{w:?}");
    let mut amplitude = Vec3::ZERO;
    let (mut axis, mut kappa, mut lit) = (Vec3::ZERO, 0.0f32, 0.0f32);
    for (lobe, &wk) in l.iter().zip(&w) {
        amplitude += lobe.amplitude * wk;
        if lobe.amplitude != Vec3::ZERO {
            axis += lobe.axis * wk;
            kappa += lobe.kappa * wk;
            lit += wk;
        }
    }
    if lit <= 0.0 {
        return VmfLobe {
            axis: l[0].axis,
            kappa: 0.0,
            amplitude,
        };
    }
    // Opposite axes cancel: keep the heaviest lit corner's.
    let axis = axis.try_normalize().unwrap_or_else(|| {
        let k = (0..3)
            .filter(|&k| l[k].amplitude != Vec3::ZERO)
            .fold(None, |b: Option<usize>, k| match b {
                Some(j) if w[j] >= w[k] => Some(j),
                _ => Some(k),
            })
            .unwrap_or(0);
        l[k].axis
    });
    VmfLobe {
        axis,
        kappa: kappa / lit,
        amplitude,
    }
}

/// Eq. 6 for every lobe of three slices ([`blend_lobes`]).
#[inline]
pub fn blend_slices(s: [&TransferSlice; 3], w: [f32; 3]) -> TransferSlice {
    TransferSlice {
        lobes: std::array::from_fn(|t| {
            std::array::from_fn(|c| blend_lobes(s.map(|x| &x.lobes[t][c]), w))
        }),
    }
}

/// The spherical L2 distance between two slices as functions of the light direction (the
/// sum of their six lobes each), `sqrt` of the mean over RGB of `int (A - B)^2` (section 4.1,
/// with the exact inner products of appendix A instead of the large-kappa eq. 7: slices hold
/// broad diffuse lobes with `kappa` near 0 too). Units: those of the transfer, 1/sr.
pub fn slice_distance(a: &TransferSlice, b: &TransferSlice) -> f32 {
    let fa: Vec<VmfLobe> = a.lobes.iter().flatten().copied().collect();
    let fb: Vec<VmfLobe> = b.lobes.iter().flatten().copied().collect();
    (mixture_l2_distance_squared(&fa, &fb).element_sum() / 3.0).sqrt()
}

/// The views of one icosahedral level and how to interpolate between them (module docs).
#[derive(Clone, Debug)]
pub struct ViewTable {
    level: u32,
    sphere: Icosphere,
    /// For each icosphere vertex, its index among the level's views (`u32::MAX`: not a view).
    slot: Vec<u32>,
    views: Vec<Vec3>,
}

impl ViewTable {
    /// The table of `level` (`<= MAX_VIEW_LEVEL`).
    ///
    /// # Panics
    /// If `level > MAX_VIEW_LEVEL`.
    pub fn new(level: u32) -> ViewTable {
        assert!(level <= MAX_VIEW_LEVEL, "view level {level}");
        let sphere = Icosphere::new(1 << level);
        let mut next = 0u32;
        let slot = sphere
            .vertices()
            .iter()
            .map(|v| {
                if v.z > 0.0 {
                    next += 1;
                    next - 1
                } else {
                    u32::MAX
                }
            })
            .collect();
        let views = views_of_level(level);
        debug_assert_eq!(views.len(), next as usize);
        ViewTable {
            level,
            sphere,
            slot,
            views,
        }
    }

    /// Its level.
    pub fn level(&self) -> u32 {
        self.level
    }

    /// The level's views ([`views_of_level`]).
    pub fn views(&self) -> &[Vec3] {
        &self.views
    }

    /// The three views (indices into [`ViewTable::views`]) and weights (summing to 1) that
    /// interpolate the local view `v` (non-zero; module docs). Unused corners have weight 0
    /// and repeat a used one.
    pub fn locate(&self, v: Vec3) -> ([usize; 3], [f32; 3]) {
        let v = if v.z > HORIZON_Z {
            v
        } else {
            let h = Vec3::new(v.x, v.y, 0.0).try_normalize().unwrap_or(Vec3::X);
            h * (1.0 - HORIZON_Z * HORIZON_Z).sqrt() + Vec3::Z * HORIZON_Z
        };
        let (t, b) = self.sphere.locate(v);
        let corners = self.sphere.triangles()[t];
        let mut idx = [usize::MAX; 3];
        let mut w = [0.0f32; 3];
        let mut total = 0.0;
        for k in 0..3 {
            let s = self.slot[corners[k] as usize];
            if s != u32::MAX {
                idx[k] = s as usize;
                w[k] = b[k].max(0.0);
                total += w[k];
            }
        }
        let first = idx.iter().copied().find(|&i| i != usize::MAX).unwrap_or(0);
        if total <= 0.0 {
            // Only below-horizon corners carry weight (rounding at the horizon): the baked
            // corner alone.
            return ([first; 3], [1.0, 0.0, 0.0]);
        }
        for k in 0..3 {
            if idx[k] == usize::MAX {
                idx[k] = first;
            }
            w[k] /= total;
        }
        (idx, w)
    }

    /// The slice of the local view `v` interpolated from `slices` (one per view of this
    /// level, in order), eq. 6.
    ///
    /// # Panics
    /// If `slices` does not hold one slice per view.
    pub fn interpolate(&self, slices: &[TransferSlice], v: Vec3) -> TransferSlice {
        assert_eq!(slices.len(), self.views.len(), "one slice per view");
        let (i, w) = self.locate(v);
        blend_slices(i.map(|k| &slices[k]), w)
    }
}

#[cfg(test)]
mod tests;
