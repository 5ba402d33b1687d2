//! Materials with their texture and normal maps, evaluated where the renderers that apply
//! BRDFs at render time need them (the `cuts` method's local-light frame, Cheslack-Postava et
//! al. 2008 sec. 4.2: "spatially varying parameters ... applied per pixel"): at a fragment
//! (material and shading normal, [`shading_at`], the path tracer's lookup) and at a point of
//! a triangle (the diffuse albedo a surface sample re-emits with).
//!
//! A material without maps is prepared once ([`MaterialEval`]); a mapped one is prepared per
//! lookup into a caller-held slot, so the common unmapped case costs nothing extra.

use crate::raster::Fragment;
use glam::Vec3;
use relight_scene::material::maps::{shading_at, SceneMaps};
use relight_scene::material::{Material, MaterialEval};
use relight_scene::mesh::TriMesh;

/// A scene's materials, prepared, with their maps.
#[derive(Clone, Debug)]
pub struct MappedMaterials {
    /// The constant materials (what [`shading_at`] reads)...
    constants: Vec<Material>,
    /// ... and the same prepared for evaluation.
    evals: Vec<MaterialEval>,
    maps: SceneMaps,
}

impl MappedMaterials {
    /// `materials` (indexed by a mesh's `material_ids`) without maps.
    pub fn new(materials: Vec<Material>) -> Self {
        MappedMaterials {
            evals: materials.iter().copied().map(MaterialEval::new).collect(),
            constants: materials,
            maps: SceneMaps::default(),
        }
    }

    /// With `maps` (built over the mesh the lookups name).
    pub fn with_maps(self, maps: SceneMaps) -> Self {
        MappedMaterials { maps, ..self }
    }

    /// The constant material of triangle `tri` of `mesh`, its maps not applied.
    ///
    /// # Panics
    /// If `tri` or its material id is out of range.
    #[inline]
    pub fn of_triangle(&self, mesh: &TriMesh, tri: usize) -> &MaterialEval {
        &self.evals[mesh.material_ids[tri] as usize]
    }

    /// The prepared material and shading normal at fragment `f` of `mesh`: [`shading_at`]'s
    /// when its material has maps (prepared into `owned`), else the constant material and
    /// the interpolated normal.
    #[inline]
    pub fn at<'s>(
        &'s self,
        mesh: &TriMesh,
        f: &Fragment,
        owned: &'s mut Option<MaterialEval>,
    ) -> (&'s MaterialEval, Vec3) {
        let id = mesh.material_ids[f.tri as usize];
        if self.maps.of(id).is_none() {
            return (&self.evals[id as usize], f.shading_normal);
        }
        let (m, frame) = shading_at(
            mesh,
            &self.constants,
            &self.maps,
            f.tri,
            f.bary,
            f.shading_normal,
        );
        (owned.insert(MaterialEval::new(m)), frame.n)
    }

    /// Diffuse albedo ([`Material::diffuse_albedo`]) at point `p` of triangle `tri` of
    /// `mesh`, its maps applied at `p`'s texture coordinates.
    pub fn diffuse_albedo_at(&self, mesh: &TriMesh, tri: u32, p: Vec3) -> Vec3 {
        let id = mesh.material_ids[tri as usize];
        if self.maps.of(id).is_none() {
            return self.constants[id as usize].diffuse_albedo();
        }
        let bary = triangle_barycentrics(mesh, tri, p);
        let (m, _) = shading_at(mesh, &self.constants, &self.maps, tri, bary, Vec3::Z);
        m.diffuse_albedo()
    }
}

/// Barycentric weights of point `p` (on or near the triangle's plane) in triangle `tri`,
/// `mesh.indices` order, clamped into the triangle and summing to 1 (a degenerate triangle
/// gives its first corner).
fn triangle_barycentrics(mesh: &TriMesh, tri: u32, p: Vec3) -> [f32; 3] {
    let [a, b, c] = mesh.indices[tri as usize].map(|v| mesh.positions[v as usize]);
    let (e1, e2, d) = (b - a, c - a, p - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d1, d2) = (d.dot(e1), d.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det.abs() <= f32::EPSILON * d11 * d22 || !det.is_finite() {
        return [1.0, 0.0, 0.0];
    }
    let v = ((d22 * d1 - d12 * d2) / det).clamp(0.0, 1.0);
    let w = ((d11 * d2 - d12 * d1) / det).clamp(0.0, 1.0 - v);
    [1.0 - v - w, v, w]
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::shapes;

    #[test]
    fn barycentrics_recover_the_point() {
        let mesh = shapes::ground_plane(Vec3::new(0.3, 0.1, -0.2), 2.0, 3);
        let mut rng = relight_sphere::warp::Rng::new(5, 0);
        for tri in 0..mesh.triangle_count() as u32 {
            let [a, b, c] = mesh.indices[tri as usize].map(|v| mesh.positions[v as usize]);
            let (u, v) = (rng.next_f32(), rng.next_f32());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let p = a * (1.0 - u - v) + b * u + c * v;
            let w = triangle_barycentrics(&mesh, tri, p);
            let q = a * w[0] + b * w[1] + c * w[2];
            assert!((q - p).length() < 1e-5, "{tri}: {q} vs {p}");
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn unmapped_materials_are_the_constants() {
        let mesh = shapes::ground_plane(Vec3::ZERO, 1.0, 1);
        let m = Material::Lambert {
            albedo: Vec3::new(0.2, 0.4, 0.6),
        };
        let mm = MappedMaterials::new(vec![m]);
        assert_eq!(
            mm.diffuse_albedo_at(&mesh, 0, Vec3::ZERO),
            m.diffuse_albedo()
        );
        assert_eq!(*mm.of_triangle(&mesh, 1).material(), m);
    }
}
