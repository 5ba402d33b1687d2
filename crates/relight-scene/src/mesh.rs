//! Indexed triangle meshes.
//!
//! Winding is counter-clockwise seen from outside; the geometric normal of triangle
//! `[a, b, c]` is `normalize((p_b - p_a) x (p_c - p_a))`. Per-vertex `normals` are unit
//! shading normals. Barycentrics `(u, v)` weight vertices as `(1 - u - v) a + u b + v c`
//! (Embree's convention).

use crate::Vec3;
use glam::Vec2;

/// Largest coordinate magnitude (and length) a scene may use: 1e8. Normals are computed from
/// cross products of edges, whose squared length grows as the fourth power of the edge
/// length: edges beyond about 1e9 overflow `f32` and the normal silently becomes a fallback
/// (+Y). 1e8 keeps a margin of 10^4 in that fourth power.
pub const MAX_COORDINATE: f32 = 1e8;

/// An indexed triangle mesh with per-vertex attributes and a material index per triangle.
#[derive(Clone, Debug, Default)]
pub struct TriMesh {
    /// Vertex positions (world space).
    pub positions: Vec<Vec3>,
    /// Unit shading normal per vertex (same length as `positions`).
    pub normals: Vec<Vec3>,
    /// Texture coordinates per vertex, if the source had them.
    pub uvs: Option<Vec<Vec2>>,
    /// Triangles as vertex indices, counter-clockwise seen from the outside.
    pub indices: Vec<[u32; 3]>,
    /// Index into the scene's material list, one per triangle.
    pub material_ids: Vec<u32>,
}

impl TriMesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The three corner positions of triangle `tri`.
    #[inline]
    pub fn triangle(&self, tri: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[tri];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Unit geometric normal of triangle `tri` (zero for a degenerate triangle).
    #[inline]
    pub fn geometric_normal(&self, tri: usize) -> Vec3 {
        let [a, b, c] = self.triangle(tri);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Interpolated, normalised shading normal at barycentrics `(u, v)` of triangle `tri`.
    #[inline]
    pub fn shading_normal(&self, tri: usize, u: f32, v: f32) -> Vec3 {
        let [a, b, c] = self.indices[tri];
        let n = self.normals[a as usize] * (1.0 - u - v)
            + self.normals[b as usize] * u
            + self.normals[c as usize] * v;
        let n = n.normalize_or_zero();
        if n == Vec3::ZERO {
            self.geometric_normal(tri)
        } else {
            n
        }
    }

    /// Position at barycentrics `(u, v)` of triangle `tri`.
    #[inline]
    pub fn point(&self, tri: usize, u: f32, v: f32) -> Vec3 {
        let [a, b, c] = self.triangle(tri);
        a * (1.0 - u - v) + b * u + c * v
    }

    /// Axis-aligned bounds `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }

    /// Append `other` (its material ids offset by `material_offset`).
    pub fn append(&mut self, other: &TriMesh, material_offset: u32) {
        let base = self.positions.len() as u32;
        let was_empty = self.positions.is_empty();
        let old_len = self.positions.len();
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        // Keep UVs if either side has them; pad the side without them with zeros.
        self.uvs = match (self.uvs.take(), &other.uvs) {
            (_, Some(b)) if was_empty => Some(b.clone()),
            (None, None) => None,
            (a, b) => {
                let mut a = a.unwrap_or_else(|| vec![Vec2::ZERO; old_len]);
                match b {
                    Some(b) => a.extend_from_slice(b),
                    None => a.extend(std::iter::repeat_n(Vec2::ZERO, other.positions.len())),
                }
                Some(a)
            }
        };
        self.indices
            .extend(other.indices.iter().map(|t| t.map(|i| i + base)));
        self.material_ids
            .extend(other.material_ids.iter().map(|m| m + material_offset));
    }
}
