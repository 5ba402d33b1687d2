//! Ray casting against triangle meshes, behind one small interface ([`RayCaster`]).
//!
//! Back-ends ([`Backend`]): relight's own BVH ([`bvh`], pure Rust, 8-wide, watertight) and
//! Embree 3 (`embree`, feature `embree`, Debian `libembree-dev`, through relight's own FFI).
//! [`build_default`] picks the fastest available one (Embree's default mode, which is not
//! watertight: a ray aimed exactly at a shared edge or vertex can slip through; use
//! [`Backend::Bvh`] or `embree::EmbreeScene::build_robust` where that matters).
//! `relight bench` (`relight-eval`) measures them against each other on the same rays.
//!
//! Hits report `t` along the (not necessarily unit) direction, the triangle index and
//! Embree-convention barycentrics `(u, v)`: point = `(1-u-v) a + u b + v c`. Rays start at
//! `origin + tmin * dir`; spawn secondary rays with [`offset_ray_origin`] and `tmin = 0`.

use crate::mesh::TriMesh;
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
        Ray {
            origin,
            dir,
            tmin,
            tmax,
        }
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
    /// Closest hits of many rays; `out[i] = intersect(&rays[i])`. Back-ends may override this
    /// with stream traversal.
    fn intersect_many(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        debug_assert_eq!(rays.len(), out.len());
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.intersect(r);
        }
    }
    /// Short name of the back-end (for logs and benchmarks).
    fn name(&self) -> &'static str;
}

pub mod bvh;
#[cfg(feature = "embree")]
pub mod embree;

/// The ray-casting back-ends (a closed set: match it exhaustively).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Backend {
    /// relight's own 8-wide BVH ([`bvh::Bvh`], pure Rust, SAH quality preset).
    Bvh,
    /// Embree 3 through relight's own FFI (`embree::EmbreeScene`, default scene flags); needs
    /// feature `embree`.
    Embree,
}

impl Backend {
    /// Every back-end compiled into this build, fastest first.
    pub fn available() -> &'static [Backend] {
        #[cfg(feature = "embree")]
        {
            &[Backend::Embree, Backend::Bvh]
        }
        #[cfg(not(feature = "embree"))]
        {
            &[Backend::Bvh]
        }
    }
}

/// Why a ray caster could not be built ([`build`], [`bvh::Bvh::build`],
/// `embree::EmbreeScene::build`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AccelError {
    /// A triangle references a vertex that does not exist.
    #[error(
        "triangle {triangle} has vertex index out of range: {indices:?} ({vertices} vertices)"
    )]
    IndexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// Its vertex indices.
        indices: [u32; 3],
        /// Vertices in the mesh.
        vertices: usize,
    },
    /// No triangle has finite corners and a non-zero area (this includes an empty mesh).
    #[error("mesh has no usable triangle ({triangles} triangles, all degenerate or non-finite)")]
    NoUsableTriangle {
        /// Triangles in the mesh.
        triangles: usize,
    },
    /// [`Backend::Embree`] was asked of a build without the `embree` feature.
    #[error("relight was built without the `embree` feature")]
    EmbreeNotBuilt,
    /// An Embree call returned null or reported a device error.
    #[error("Embree: {call}: {message}")]
    Embree {
        /// The Embree function (or step) that failed.
        call: &'static str,
        /// Embree's error code and message, or what went wrong.
        message: String,
    },
}

/// Build a ray caster over `mesh` with `backend`.
///
/// # Errors
/// An empty mesh (no triangle with finite, non-degenerate corners), out-of-range vertex
/// indices, an Embree device error, or `Backend::Embree` without the `embree` feature.
pub fn build(mesh: &TriMesh, backend: Backend) -> Result<Box<dyn RayCaster>, AccelError> {
    match backend {
        Backend::Bvh => Ok(Box::new(bvh::Bvh::build(mesh, bvh::BuildPreset::Quality)?)),
        #[cfg(feature = "embree")]
        Backend::Embree => Ok(Box::new(embree::EmbreeScene::build(mesh)?)),
        #[cfg(not(feature = "embree"))]
        Backend::Embree => Err(AccelError::EmbreeNotBuilt),
    }
}

/// Build the fastest available ray caster: Embree when the `embree` feature is on (falling
/// back to the own BVH if Embree fails), otherwise the own BVH.
///
/// # Panics
/// If no back-end can be built (e.g. an empty mesh); use [`build`] to handle that.
pub fn build_default(mesh: &TriMesh) -> Box<dyn RayCaster> {
    let mut last_err = None;
    for &b in Backend::available() {
        match build(mesh, b) {
            Ok(c) => return c,
            Err(e) => last_err = Some(e),
        }
    }
    match last_err {
        Some(e) => panic!("no ray-casting back-end could be built: {e}"),
        None => panic!("no ray-casting back-end is compiled in"),
    }
}

/// Move a ray origin `p` on a surface with geometric normal `ng` off that surface, to the side
/// `dir` points to, so the new ray does not re-hit the surface it starts on.
///
/// Method of Wächter & Binder 2019, "A Fast and Robust Method for Avoiding Self-Intersection"
/// (Ray Tracing Gems, ch. 6): offset in integer ULPs proportional to the normal (so the
/// offset scales with the floating-point spacing at `p`), and by a small fixed distance near
/// the origin where ULPs are tiny. Use `tmin = 0` with the returned origin.
///
/// # Panics
/// Debug builds: if `ng` is not finite.
#[inline]
pub fn offset_ray_origin(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    debug_assert!(
        ng.is_finite(),
        "offset_ray_origin: non-finite normal {ng:?}"
    );
    // Constants of the paper: below |x| < ORIGIN use a fixed float offset, else integer ULPs.
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let n = if ng.dot(dir) < 0.0 { -ng } else { ng };
    let offset = |x: f32, nx: f32| -> f32 {
        if x.abs() < ORIGIN {
            return x + FLOAT_SCALE * nx;
        }
        let of_i = (INT_SCALE * nx) as i32;
        // Moving the bits away from zero grows |x|; towards zero shrinks it.
        let bits = x.to_bits() as i32;
        let moved = if x < 0.0 {
            bits.wrapping_sub(of_i)
        } else {
            bits.wrapping_add(of_i)
        };
        f32::from_bits(moved as u32)
    };
    Vec3::new(offset(p.x, n.x), offset(p.y, n.y), offset(p.z, n.z))
}

/// A tiny deterministic generator for the ray sets and meshes of this module's tests (and
/// `bvh/tests.rs`).
#[cfg(test)]
pub(crate) mod test_rng {
    /// SplitMix64 (Steele, Lea & Flood 2014).
    #[derive(Clone, Debug)]
    pub(crate) struct SplitMix64(pub u64);

    impl SplitMix64 {
        /// Next 64 random bits.
        pub(crate) fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }

        /// Uniform in `[0, 1)`.
        pub(crate) fn next_f32(&mut self) -> f32 {
            (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use test_rng::SplitMix64;

    #[test]
    fn offset_origin_avoids_self_intersection() {
        // Triangles far from and near the world origin; rays leaving points on them to both
        // sides must not re-hit the triangle they start on.
        let mut rng = SplitMix64(3);
        let mut r3 = |s: f32| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * s;
        for &(centre, size) in &[(0.0f32, 1.0f32), (0.01, 0.01), (1000.0, 5.0), (1e5, 50.0)] {
            for _ in 0..40 {
                let c = Vec3::splat(centre) + r3(centre.max(1.0));
                let [a, b, cc] = [c + r3(size), c + r3(size), c + r3(size)];
                let m = TriMesh {
                    positions: vec![a, b, cc],
                    normals: vec![Vec3::Y; 3],
                    uvs: None,
                    indices: vec![[0, 1, 2]],
                    material_ids: vec![0],
                };
                let Ok(casters) = Backend::available()
                    .iter()
                    .map(|&k| build(&m, k))
                    .collect::<Result<Vec<_>, _>>()
                else {
                    continue; // degenerate random triangle
                };
                let ng = m.geometric_normal(0);
                for _ in 0..50 {
                    let (u, v) = (r3(0.5).x, r3(0.5).y);
                    let p = m.point(0, u, v);
                    let d = (r3(2.0) - Vec3::ONE).normalize_or(Vec3::X);
                    if d.dot(ng).abs() < 1e-3 {
                        continue;
                    }
                    let o = offset_ray_origin(p, ng, d);
                    assert!(
                        (o - p).dot(ng) * d.dot(ng) > 0.0,
                        "origin moved to the wrong side"
                    );
                    for c in &casters {
                        let r = Ray::new(o, d, 0.0, f32::INFINITY);
                        assert!(
                            !c.occluded(&r),
                            "{}: self-hit from {p} (offset {o})",
                            c.name()
                        );
                    }
                }
            }
        }
    }
}
