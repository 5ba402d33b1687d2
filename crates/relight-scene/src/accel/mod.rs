//! Ray casting against triangle meshes, behind one small interface ([`RayCaster`]).
//!
//! Back-ends: relight's own BVH (`bvh`, pure Rust) and Embree 3 (`embree`, feature
//! `embree`, Debian `libembree-dev`). [`build_default`] picks the fastest available one.
//! Hits report `t` along the (not necessarily unit) direction, the triangle index and
//! Embree-convention barycentrics `(u, v)`: point = `(1-u-v) a + u b + v c`.

use crate::Vec3;

/// A ray `origin + t * dir`, `t` in `[tmin, tmax]`.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Direction (need not be unit; `t` is measured in its units).
    pub dir: Vec3,
    /// Smallest accepted `t`.
    pub tmin: f32,
    /// Largest accepted `t`.
    pub tmax: f32,
}

impl Ray {
    /// A ray over `[tmin, tmax]`.
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        Ray { origin, dir, tmin, tmax }
    }

    /// Point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// Closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Index of the triangle hit.
    pub tri: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
}

/// Closest-hit and occlusion queries over one triangle mesh. Implementations are `Sync`:
/// call them from many threads at once.
pub trait RayCaster: Send + Sync {
    /// Closest hit in `[ray.tmin, ray.tmax]`, if any.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;
    /// Whether anything is hit in `[ray.tmin, ray.tmax]`.
    fn occluded(&self, ray: &Ray) -> bool;
    /// Occlusion of many rays; `out[i] = occluded(&rays[i])`. Back-ends may override this with
    /// stream traversal.
    fn occluded_many(&self, rays: &[Ray], out: &mut [bool]) {
        debug_assert_eq!(rays.len(), out.len());
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.occluded(r);
        }
    }
    /// Short name of the back-end (for logs and benchmarks).
    fn name(&self) -> &'static str;
}
