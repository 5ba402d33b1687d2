//! Procedural shapes for built-in scenes and tests: spheres, ground planes, boxes, a table.
//!
//! All are closed or single-sided triangle meshes, counter-clockwise seen from outside, with
//! exact smooth (sphere) or flat (plane, box faces) per-vertex normals and material id 0.

use crate::mesh::TriMesh;
use crate::Vec3;
use glam::Vec2;

/// A UV sphere: `rings` latitude bands (>= 2) and `segments` longitude slices (>= 3).
/// Normals are exact (radial); UVs follow the Mitsuba latlong convention of the normal.
pub fn uv_sphere(center: Vec3, radius: f32, rings: u32, segments: u32) -> TriMesh {
    debug_assert!(rings >= 2 && segments >= 3 && radius > 0.0);
    let mut m = TriMesh::default();
    let mut uvs = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..=segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            // Mitsuba's latlong parametrisation: d = (sin phi sin theta, cos theta, -cos phi sin theta).
            let n = Vec3::new(
                phi.sin() * theta.sin(),
                theta.cos(),
                -phi.cos() * theta.sin(),
            );
            m.positions.push(center + n * radius);
            m.normals.push(n);
            uvs.push(Vec2::new(
                j as f32 / segments as f32,
                i as f32 / rings as f32,
            ));
        }
    }
    let row = segments + 1;
    for i in 0..rings {
        for j in 0..segments {
            let a = i * row + j;
            let b = a + row;
            // Skip the degenerate triangles at the poles.
            if i != 0 {
                m.indices.push([a, a + 1, b]);
            }
            if i + 1 != rings {
                m.indices.push([a + 1, b + 1, b]);
            }
        }
    }
    fix_winding_outward(&mut m, center);
    m.uvs = Some(uvs);
    m.material_ids = vec![0; m.indices.len()];
    m
}

/// A horizontal square of side `size` centred at `center`, facing +Y, split into
/// `divisions x divisions` quads (more vertices give per-vertex PRT more resolution).
pub fn ground_plane(center: Vec3, size: f32, divisions: u32) -> TriMesh {
    debug_assert!(divisions >= 1 && size > 0.0);
    let mut m = TriMesh::default();
    let mut uvs = Vec::new();
    let n = divisions + 1;
    for i in 0..n {
        for j in 0..n {
            let s = j as f32 / divisions as f32;
            let t = i as f32 / divisions as f32;
            m.positions
                .push(center + Vec3::new((s - 0.5) * size, 0.0, (t - 0.5) * size));
            m.normals.push(Vec3::Y);
            uvs.push(Vec2::new(s, t));
        }
    }
    for i in 0..divisions {
        for j in 0..divisions {
            let a = i * n + j;
            // Counter-clockwise seen from +Y: (x, z) -> (x, z+1) -> (x+1, z).
            m.indices.push([a, a + n, a + 1]);
            m.indices.push([a + 1, a + n, a + n + 1]);
        }
    }
    m.uvs = Some(uvs);
    m.material_ids = vec![0; m.indices.len()];
    m
}

/// A closed room: [`aabb_box`] from `lo` to `hi` turned inside out (triangles wound and
/// normals pointing inwards), its faces in the same order (`-x, +x, -y, +y, -z, +z`,
/// `2 divisions^2` triangles each), for scenes lit from inside.
pub fn inward_box(lo: Vec3, hi: Vec3, divisions: u32) -> TriMesh {
    let mut m = aabb_box(lo, hi, divisions);
    for t in &mut m.indices {
        t.swap(1, 2);
    }
    for n in &mut m.normals {
        *n = -*n;
    }
    m
}

/// A Cornell-box-like room: [`inward_box`] from `lo` to `hi`, its `-x` wall material 1, its
/// `+x` wall material 2, the floor, ceiling and the `-z` and `+z` walls material 0.
pub fn coloured_room(lo: Vec3, hi: Vec3, divisions: u32) -> TriMesh {
    let mut m = inward_box(lo, hi, divisions);
    let per_face = (2 * divisions * divisions) as usize;
    m.material_ids = (0..m.indices.len())
        .map(|t| match t / per_face {
            0 => 1,
            1 => 2,
            _ => 0,
        })
        .collect();
    m
}

/// An axis-aligned box from `lo` to `hi` with flat faces (24 vertices, 12 triangles), each
/// face split into `divisions^2` quads.
pub fn aabb_box(lo: Vec3, hi: Vec3, divisions: u32) -> TriMesh {
    debug_assert!(lo.cmplt(hi).all() && divisions >= 1);
    let c = (lo + hi) * 0.5;
    let e = (hi - lo) * 0.5;
    let mut out = TriMesh::default();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            // Two tangent axes.
            let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut face = TriMesh::default();
            let k = divisions + 1;
            for i in 0..k {
                for j in 0..k {
                    let s = j as f32 / divisions as f32 * 2.0 - 1.0;
                    let t = i as f32 / divisions as f32 * 2.0 - 1.0;
                    let mut p = c + n * e;
                    p[ua] += s * e[ua];
                    p[va] += t * e[va];
                    face.positions.push(p);
                    face.normals.push(n);
                }
            }
            for i in 0..divisions {
                for j in 0..divisions {
                    let a = i * k + j;
                    face.indices.push([a, a + 1, a + k]);
                    face.indices.push([a + 1, a + k + 1, a + k]);
                }
            }
            fix_winding_outward(&mut face, c);
            face.material_ids = vec![0; face.indices.len()];
            out.append(&face, 0);
        }
    }
    out
}

/// A small table: a top slab of `width x depth x thickness` whose upper face is at
/// `height`, on four square legs, centred on the Y axis (for the teapot-on-a-table scenes).
pub fn table(width: f32, depth: f32, height: f32, thickness: f32, leg: f32) -> TriMesh {
    let mut m = aabb_box(
        Vec3::new(-width / 2.0, height - thickness, -depth / 2.0),
        Vec3::new(width / 2.0, height, depth / 2.0),
        // Fine enough for per-vertex PRT to carry the shadow of an object standing on it.
        24,
    );
    let inset = leg;
    for (sx, sz) in [(-1.0f32, -1.0f32), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let x = sx * (width / 2.0 - inset);
        let z = sz * (depth / 2.0 - inset);
        let l = aabb_box(
            Vec3::new(x - leg / 2.0, 0.0, z - leg / 2.0),
            Vec3::new(x + leg / 2.0, height - thickness, z + leg / 2.0),
            // Per-vertex PRT needs vertices along the legs: the top shadows their upper part.
            12,
        );
        m.append(&l, 0);
    }
    m
}

/// Apply `p -> scale * p + translate` (uniform scale keeps normals).
pub fn transform(mesh: &mut TriMesh, scale: f32, translate: Vec3) {
    debug_assert!(scale > 0.0);
    for p in &mut mesh.positions {
        *p = *p * scale + translate;
    }
}

/// Flip triangles whose geometric normal points towards `inside` (for convex pieces).
fn fix_winding_outward(m: &mut TriMesh, inside: Vec3) {
    for t in 0..m.indices.len() {
        let [a, b, c] = m.triangle(t);
        let centroid = (a + b + c) / 3.0;
        if (b - a).cross(c - a).dot(centroid - inside) < 0.0 {
            m.indices[t].swap(1, 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signed_volume(m: &TriMesh) -> f32 {
        (0..m.triangle_count())
            .map(|t| {
                let [a, b, c] = m.triangle(t);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn sphere_is_outward_with_radial_normals_and_right_volume() {
        let m = uv_sphere(Vec3::ZERO, 2.0, 48, 96);
        let v = signed_volume(&m);
        let exact = 4.0 / 3.0 * std::f32::consts::PI * 8.0;
        // A tessellated sphere is inscribed: slightly smaller, within 1% at this resolution.
        assert!(
            v > 0.0 && (v - exact).abs() / exact < 0.01,
            "{v} vs {exact}"
        );
        for t in 0..m.triangle_count() {
            let g = m.geometric_normal(t);
            let [a, b, c] = m.triangle(t);
            assert!(g.dot((a + b + c).normalize()) > 0.9);
        }
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((p.normalize() - *n).length() < 1e-5);
        }
    }

    #[test]
    fn plane_faces_up_and_box_is_closed_outward() {
        let p = ground_plane(Vec3::ZERO, 2.0, 3);
        assert_eq!(p.triangle_count(), 18);
        for t in 0..p.triangle_count() {
            assert!((p.geometric_normal(t) - Vec3::Y).length() < 1e-6);
        }
        let b = aabb_box(Vec3::splat(-1.0), Vec3::new(1.0, 2.0, 3.0), 2);
        assert!((signed_volume(&b) - 2.0 * 3.0 * 4.0).abs() < 1e-4);
        for t in 0..b.triangle_count() {
            let g = b.geometric_normal(t);
            let n = b.normals[b.indices[t][0] as usize];
            assert!((g - n).length() < 1e-6);
        }
    }

    #[test]
    fn table_volume_is_top_plus_legs() {
        let t = table(1.0, 0.6, 0.5, 0.05, 0.05);
        let top = 1.0 * 0.6 * 0.05;
        let legs = 4.0 * 0.05 * 0.05 * 0.45;
        assert!((signed_volume(&t) - (top + legs)).abs() < 1e-5);
    }
}
