//! Transport sampling shared by the bakers: per-vertex albedo and normals, per-vertex
//! low-discrepancy hemisphere directions, ray offsets, thread pools and progress bars.
//!
//! Determinism: every per-vertex random choice is drawn from `Rng::new(seed, vertex index)`,
//! so a bake depends on the seed only, never on the thread count or scheduling.

use crate::BakeError;
use glam::{Vec2, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use relight_scene::accel::{offset_ray_origin, Ray};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_sphere::warp::{
    cranley_patterson, hammersley, square_to_cosine_hemisphere, Frame, Rng,
};
use std::collections::HashMap;

/// Check that a mesh is consistent enough to bake: one normal per vertex, one material id per
/// triangle, indices and material ids in range, finite positions.
///
/// # Errors
/// [`BakeError::Scene`] naming the first problem found.
pub fn check_mesh(mesh: &TriMesh, materials: &[Material]) -> Result<(), BakeError> {
    check_mesh_geometry(mesh)?;
    let err = |m: String| Err(BakeError::Scene(m));
    if mesh.material_ids.len() != mesh.indices.len() {
        return err(format!(
            "{} material ids for {} triangles",
            mesh.material_ids.len(),
            mesh.indices.len()
        ));
    }
    if let Some(t) = mesh
        .material_ids
        .iter()
        .position(|&m| m as usize >= materials.len())
    {
        return err(format!(
            "triangle {t} uses material {} but only {} exist",
            mesh.material_ids[t],
            materials.len()
        ));
    }
    Ok(())
}

/// The geometric half of [`check_mesh`]: one finite normal per vertex, finite positions,
/// vertex indices in range (what a bake with per-vertex materials needs).
///
/// # Errors
/// [`BakeError::Scene`] naming the first problem found.
pub fn check_mesh_geometry(mesh: &TriMesh) -> Result<(), BakeError> {
    let err = |m: String| Err(BakeError::Scene(m));
    if mesh.normals.len() != mesh.positions.len() {
        return err(format!(
            "{} normals for {} vertices",
            mesh.normals.len(),
            mesh.positions.len()
        ));
    }
    let nv = mesh.positions.len() as u32;
    if let Some(t) = mesh.indices.iter().position(|t| t.iter().any(|&i| i >= nv)) {
        return err(format!(
            "triangle {t} has a vertex index out of range (>= {nv})"
        ));
    }
    if let Some(v) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return err(format!("vertex {v} has a non-finite position"));
    }
    if let Some(v) = mesh.normals.iter().position(|n| !n.is_finite()) {
        return err(format!("vertex {v} has a non-finite normal"));
    }
    Ok(())
}

/// Diffuse albedo per vertex: the mean of [`Material::diffuse_albedo`] over the triangles
/// around the vertex (zero for a vertex used by no triangle). This is the `rho_p` of Sloan et
/// al. 2002, sec. 5, sampled at vertices like the transfer itself.
///
/// # Panics
/// If a material id or vertex index is out of range (see [`check_mesh`]).
pub fn vertex_albedo(mesh: &TriMesh, materials: &[Material]) -> Vec<Vec3> {
    let mut sum = vec![Vec3::ZERO; mesh.vertex_count()];
    let mut count = vec![0u32; mesh.vertex_count()];
    for (tri, &m) in mesh.indices.iter().zip(&mesh.material_ids) {
        let a = materials[m as usize].diffuse_albedo();
        for &v in tri {
            sum[v as usize] += a;
            count[v as usize] += 1;
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(&s, &c)| if c == 0 { Vec3::ZERO } else { s / c as f32 })
        .collect()
}

/// Geometric normal per vertex: the area-weighted mean of the geometric normals of all
/// triangles touching the vertex's *position* (the sum of their unnormalised cross products),
/// so split copies of a vertex (UV seams, the poles of a UV sphere) share the normal of the
/// whole surface around them. Falls back to the shading normal where that sum vanishes. Ray
/// origins are offset along it ([`surface_ray`]).
pub fn vertex_geometric_normals(mesh: &TriMesh) -> Vec<Vec3> {
    let key = |p: Vec3| p.to_array().map(f32::to_bits);
    let mut sum: HashMap<[u32; 3], Vec3> = HashMap::new();
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        let n = (b - a).cross(c - a);
        for p in [a, b, c] {
            *sum.entry(key(p)).or_insert(Vec3::ZERO) += n;
        }
    }
    mesh.positions
        .iter()
        .zip(&mesh.normals)
        .map(|(&p, &n)| {
            let g = sum
                .get(&key(p))
                .copied()
                .unwrap_or(Vec3::ZERO)
                .normalize_or_zero();
            if g == Vec3::ZERO {
                n.normalize_or_zero()
            } else {
                g
            }
        })
        .collect()
}

/// The cosine-weighted hemisphere directions of one vertex.
///
/// The `n`-point Hammersley set, Cranley-Patterson rotated by a shift drawn from
/// `Rng::new(seed, vertex)`, warped to the cosine-weighted hemisphere (pdf `cos theta / pi`)
/// around the unit `normal`. The same direction set is returned every time it is asked for the
/// same `(seed, vertex, n, normal)`, which lets the Neumann-series passes retrace the rays of
/// the first pass.
#[derive(Clone, Copy, Debug)]
pub struct VertexSamples {
    frame: Frame,
    shift: Vec2,
    n: u32,
}

impl VertexSamples {
    /// Samples for `vertex` with unit shading `normal`.
    ///
    /// # Panics
    /// Debug builds: `n == 0` or a non-unit normal.
    pub fn new(seed: u64, vertex: usize, n: u32, normal: Vec3) -> Self {
        debug_assert!(n > 0, "at least one sample");
        let mut rng = Rng::new(seed, vertex as u64);
        VertexSamples {
            frame: Frame::from_normal(normal),
            shift: rng.next_vec2(),
            n,
        }
    }

    /// Number of directions.
    pub fn len(&self) -> u32 {
        self.n
    }

    /// Whether there are no directions (never: `n > 0`).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Direction `i` (world space, unit, in the hemisphere of the normal).
    #[inline]
    pub fn dir(&self, i: u32) -> Vec3 {
        let u = cranley_patterson(hammersley(i, self.n), self.shift);
        self.frame
            .to_world(square_to_cosine_hemisphere(u))
            .normalize()
    }
}

/// A ray leaving surface point `p` (geometric normal `ng`) in direction `dir`, unbounded, its
/// origin moved off the surface to the front (the side `ng` points to) with
/// [`offset_ray_origin`] (Wächter & Binder 2019), whatever `dir`: a direction inside the
/// shading hemisphere but below the geometric surface then hits the surface itself and counts
/// as blocked, instead of starting behind it and seeing the inside of the object.
#[inline]
pub fn surface_ray(p: Vec3, ng: Vec3, dir: Vec3) -> Ray {
    Ray::new(offset_ray_origin(p, ng, ng), dir, 0.0, f32::INFINITY)
}

/// Run `f` on a rayon pool of `threads` workers, or on the current (global) pool for `None`.
///
/// # Errors
/// [`BakeError::Threads`] if the pool cannot be built or `threads == Some(0)`.
pub fn with_threads<R: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> R + Send,
) -> Result<R, BakeError> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(BakeError::Threads {
            threads: 0,
            message: "need at least one".into(),
        }),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(|pool| pool.install(f))
            .map_err(|e| BakeError::Threads {
                threads: n,
                message: e.to_string(),
            }),
    }
}

/// A progress bar over `len` work items, hidden unless `show`.
pub fn progress_bar(show: bool, len: u64, what: &str) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template(
        "{msg:>16} [{elapsed_precise}] {wide_bar} {pos}/{len} ({eta} left)",
    ) {
        pb.set_style(style);
    }
    pb.set_message(what.to_string());
    pb
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::shapes::ground_plane;

    #[test]
    fn samples_are_deterministic_and_in_the_hemisphere() {
        let n = Vec3::new(0.3, 0.9, -0.2).normalize();
        let a = VertexSamples::new(7, 12, 64, n);
        let b = VertexSamples::new(7, 12, 64, n);
        let c = VertexSamples::new(7, 13, 64, n);
        let mut differs = false;
        for i in 0..64 {
            assert_eq!(a.dir(i), b.dir(i));
            assert!(a.dir(i).dot(n) >= 0.0);
            // 1e-5: f32 warp and frame rounding.
            assert!((a.dir(i).length() - 1.0).abs() < 1e-5);
            differs |= a.dir(i) != c.dir(i);
        }
        assert!(differs, "vertices get different rotations");
        // Cosine-weighted: E[cos] = 2/3; a stratified 64-point set gets it within 1%.
        let mean_cos: f32 = (0..64).map(|i| a.dir(i).dot(n)).sum::<f32>() / 64.0;
        assert!((mean_cos - 2.0 / 3.0).abs() < 0.01, "{mean_cos}");
    }

    #[test]
    fn albedo_and_normals_per_vertex() {
        let mut m = ground_plane(Vec3::ZERO, 2.0, 1);
        m.material_ids = vec![0, 1];
        let mats = [
            Material::Lambert {
                albedo: Vec3::splat(0.2),
            },
            Material::Lambert {
                albedo: Vec3::splat(0.6),
            },
        ];
        check_mesh(&m, &mats).unwrap();
        let a = vertex_albedo(&m, &mats);
        // Vertices 1 and 2 are shared by both triangles, 0 and 3 by one each.
        let shared = m.indices[0]
            .iter()
            .filter(|v| m.indices[1].contains(v))
            .count();
        assert_eq!(shared, 2);
        for v in 0..4u32 {
            let in0 = m.indices[0].contains(&v);
            let in1 = m.indices[1].contains(&v);
            let expect = match (in0, in1) {
                (true, true) => 0.4,
                (true, false) => 0.2,
                _ => 0.6,
            };
            assert!((a[v as usize].x - expect).abs() < 1e-6);
        }
        for g in vertex_geometric_normals(&m) {
            assert!((g - Vec3::Y).length() < 1e-6);
        }
        m.material_ids[1] = 5;
        assert!(check_mesh(&m, &mats).is_err());
    }
}
