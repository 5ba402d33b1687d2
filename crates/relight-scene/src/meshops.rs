//! Mesh clean-up: welding, smooth normals, degenerate and unused geometry, validation; midpoint
//! subdivision.

use crate::mesh::TriMesh;
use crate::Vec3;
use std::collections::HashMap;

/// Most levels of [`subdivide_midpoint`] a scene may ask (each multiplies the triangles by 4).
pub const MAX_SUBDIVISION: u32 = 6;

/// One level of midpoint subdivision: every triangle `(a, b, c)` becomes four, through one new
/// vertex per edge (shared by the edge's triangles) at the edge's midpoint, with the
/// normalised mean of the endpoints' normals (the first endpoint's where they cancel) and the
/// mean of their texture coordinates. The surface is unchanged (no smoothing); vertices
/// `0..V` keep their indices, new ones follow in order of first use.
pub fn subdivide_midpoint(mesh: &TriMesh) -> TriMesh {
    let mut out = TriMesh {
        positions: mesh.positions.clone(),
        normals: mesh.normals.clone(),
        uvs: mesh.uvs.clone(),
        indices: Vec::with_capacity(mesh.indices.len() * 4),
        material_ids: Vec::with_capacity(mesh.material_ids.len() * 4),
    };
    let mut mid: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.indices.len() * 3 / 2);
    let mut midpoint = |a: u32, b: u32, out: &mut TriMesh| -> u32 {
        *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
            let (i, j) = (a as usize, b as usize);
            out.positions
                .push((mesh.positions[i] + mesh.positions[j]) * 0.5);
            let n = mesh.normals[i] + mesh.normals[j];
            out.normals
                .push(n.try_normalize().unwrap_or(mesh.normals[i]));
            if let (Some(uv), Some(src)) = (out.uvs.as_mut(), mesh.uvs.as_ref()) {
                uv.push((src[i] + src[j]) * 0.5);
            }
            (out.positions.len() - 1) as u32
        })
    };
    for (&[a, b, c], &m) in mesh.indices.iter().zip(&mesh.material_ids) {
        let ab = midpoint(a, b, &mut out);
        let bc = midpoint(b, c, &mut out);
        let ca = midpoint(c, a, &mut out);
        out.indices
            .extend_from_slice(&[[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        out.material_ids.extend_from_slice(&[m; 4]);
    }
    out
}

/// How face normals are weighted when averaged into vertex normals.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NormalWeighting {
    /// Weight by triangle area (the unnormalised cross product).
    Area,
    /// Weight by the corner angle at the vertex (Thürmer & Wüthrich 1998, "Computing vertex
    /// normals from polygonal facets"): independent of how a surface is triangulated.
    Angle,
}

/// Smooth per-vertex normals of `mesh` (its `normals` are ignored). A vertex whose weighted
/// sum vanishes (unused, or facing faces cancelling) gets +Y so the result is always unit.
pub fn smooth_normals(mesh: &TriMesh, weighting: NormalWeighting) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; mesh.positions.len()];
    for tri in &mesh.indices {
        let p = tri.map(|i| mesh.positions[i as usize]);
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        match weighting {
            NormalWeighting::Area => tri.iter().for_each(|&i| acc[i as usize] += cross),
            NormalWeighting::Angle => {
                let n = cross.normalize_or_zero();
                for k in 0..3 {
                    let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
                    let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
                    let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
                    acc[tri[k] as usize] += n * angle;
                }
            }
        }
    }
    acc.into_iter()
        .map(|n| {
            let u = n.normalize_or_zero();
            if u == Vec3::ZERO {
                Vec3::Y
            } else {
                u
            }
        })
        .collect()
}

/// Merge vertices whose positions lie within `eps` of a kept vertex (each vertex joins the
/// first earlier kept vertex found within `eps`, via a hash grid of cell `eps`). Welding is by
/// position only: the kept vertex's normal and UV win (UV seams are lost), so recompute normals
/// afterwards with [`smooth_normals`] if the input was faceted. Triangles are kept (some may
/// become degenerate: see [`drop_degenerate`]). Returns the welded mesh.
pub fn weld(mesh: &TriMesh, eps: f32) -> TriMesh {
    let eps = eps.max(f32::MIN_POSITIVE);
    let cell = |p: Vec3| {
        let c = (p / eps).floor();
        (c.x as i64, c.y as i64, c.z as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
    let mut remap = vec![0u32; mesh.positions.len()];
    let mut kept: Vec<usize> = Vec::new();
    for (i, &p) in mesh.positions.iter().enumerate() {
        let c = cell(p);
        let mut found = None;
        'search: for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = grid.get(&(c.0 + dx, c.1 + dy, c.2 + dz)) {
                        if let Some(&k) = list
                            .iter()
                            .find(|&&k| mesh.positions[kept[k as usize]].distance(p) <= eps)
                        {
                            found = Some(k);
                            break 'search;
                        }
                    }
                }
            }
        }
        remap[i] = match found {
            Some(k) => k,
            None => {
                let k = kept.len() as u32;
                kept.push(i);
                grid.entry(c).or_default().push(k);
                k
            }
        };
    }
    TriMesh {
        positions: kept.iter().map(|&i| mesh.positions[i]).collect(),
        normals: if mesh.normals.len() == mesh.positions.len() {
            kept.iter().map(|&i| mesh.normals[i]).collect()
        } else {
            Vec::new()
        },
        uvs: mesh
            .uvs
            .as_ref()
            .map(|uv| kept.iter().map(|&i| uv[i]).collect()),
        indices: mesh
            .indices
            .iter()
            .map(|t| t.map(|i| remap[i as usize]))
            .collect(),
        material_ids: mesh.material_ids.clone(),
    }
}

/// Whether a triangle is degenerate: a repeated index or zero area (in f32).
pub fn is_degenerate(mesh: &TriMesh, tri: [u32; 3]) -> bool {
    if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
        return true;
    }
    let p = tri.map(|i| mesh.positions[i as usize]);
    (p[1] - p[0]).cross(p[2] - p[0]).length_squared() == 0.0
}

/// Remove degenerate triangles (with their material ids); returns how many were removed.
pub fn drop_degenerate(mesh: &mut TriMesh) -> usize {
    let before = mesh.indices.len();
    let keep: Vec<bool> = mesh
        .indices
        .iter()
        .map(|&t| !is_degenerate(mesh, t))
        .collect();
    let mut k = keep.iter();
    mesh.indices.retain(|_| *k.next().unwrap_or(&true));
    if mesh.material_ids.len() == keep.len() {
        let mut k = keep.iter();
        mesh.material_ids.retain(|_| *k.next().unwrap_or(&true));
    }
    before - mesh.indices.len()
}

/// Remove vertices no triangle uses; returns how many were removed.
pub fn remove_unused_vertices(mesh: &mut TriMesh) -> usize {
    let n = mesh.positions.len();
    let mut new_index = vec![u32::MAX; n];
    let mut order = Vec::new();
    for t in &mesh.indices {
        for &i in t {
            if new_index[i as usize] == u32::MAX {
                new_index[i as usize] = order.len() as u32;
                order.push(i as usize);
            }
        }
    }
    order.sort_unstable();
    for (k, &i) in order.iter().enumerate() {
        new_index[i] = k as u32;
    }
    let pick = |v: &Vec<Vec3>| order.iter().map(|&i| v[i]).collect::<Vec<_>>();
    mesh.positions = pick(&mesh.positions);
    if mesh.normals.len() == n {
        mesh.normals = pick(&mesh.normals);
    }
    if let Some(uv) = &mesh.uvs {
        mesh.uvs = Some(order.iter().map(|&i| uv[i]).collect());
    }
    for t in &mut mesh.indices {
        *t = t.map(|i| new_index[i as usize]);
    }
    n - order.len()
}

/// Err if the mesh has no triangles or no vertices.
pub fn check_non_empty(mesh: &TriMesh) -> Result<(), crate::error::Invalid> {
    non_empty_msg(mesh).map_err(crate::error::Invalid)
}

fn non_empty_msg(mesh: &TriMesh) -> Result<(), String> {
    if mesh.indices.is_empty() || mesh.positions.is_empty() {
        return Err(format!(
            "empty mesh ({} vertices, {} non-degenerate triangles)",
            mesh.positions.len(),
            mesh.indices.len()
        ));
    }
    Ok(())
}

/// Check every invariant of a [`TriMesh`]: non-empty; attribute arrays as long as
/// `positions`; one material id per triangle; indices in range; finite positions; unit
/// normals (within 1e-3).
pub fn validate(mesh: &TriMesh) -> Result<(), crate::error::Invalid> {
    validate_msg(mesh).map_err(crate::error::Invalid)
}

fn validate_msg(mesh: &TriMesh) -> Result<(), String> {
    check_non_empty(mesh)?;
    let n = mesh.positions.len();
    if mesh.normals.len() != n {
        return Err(format!("{} normals for {n} vertices", mesh.normals.len()));
    }
    if let Some(uv) = &mesh.uvs {
        if uv.len() != n {
            return Err(format!("{} UVs for {n} vertices", uv.len()));
        }
        if let Some(i) = uv.iter().position(|u| !u.is_finite()) {
            return Err(format!("UV of vertex {i} is not finite"));
        }
    }
    if mesh.material_ids.len() != mesh.indices.len() {
        return Err(format!(
            "{} material ids for {} triangles",
            mesh.material_ids.len(),
            mesh.indices.len()
        ));
    }
    if let Some((t, tri)) = mesh
        .indices
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i as usize >= n))
    {
        return Err(format!("triangle {t} {tri:?} indexes beyond {n} vertices"));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("position of vertex {i} is not finite"));
    }
    if let Some(i) = mesh
        .normals
        .iter()
        .position(|v| v.is_nan() || (v.length() - 1.0).abs() > 1e-3)
    {
        return Err(format!(
            "normal of vertex {i} is not unit: {}",
            mesh.normals[i]
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube as 12 triangles over 24 unwelded vertices (4 per face).
    fn unwelded_cube() -> TriMesh {
        let mut m = TriMesh::default();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let n =
                    Vec3::from_array(std::array::from_fn(|k| if k == axis { sign } else { 0.0 }));
                let u = Vec3::from_array(std::array::from_fn(|k| {
                    if k == (axis + 1) % 3 {
                        1.0
                    } else {
                        0.0
                    }
                }));
                let v = n.cross(u);
                let base = m.positions.len() as u32;
                for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    m.positions.push(n + u * a + v * b);
                    m.normals.push(n);
                }
                m.indices.push([base, base + 1, base + 2]);
                m.indices.push([base, base + 2, base + 3]);
                m.material_ids.extend([0, 0]);
            }
        }
        m
    }

    #[test]
    fn cube_welds_to_eight_vertices() {
        let m = unwelded_cube();
        assert_eq!(m.vertex_count(), 24);
        validate(&m).unwrap();
        let w = weld(&m, 1e-5);
        assert_eq!(w.vertex_count(), 8);
        assert_eq!(w.triangle_count(), 12);
        // Welded smooth normals of a cube corner point along the diagonal.
        let n = smooth_normals(&w, NormalWeighting::Angle);
        for (p, n) in w.positions.iter().zip(&n) {
            assert!(n.dot(p.normalize()) > 0.9999, "{p} {n}");
        }
    }

    #[test]
    fn weld_keeps_distinct_points_apart() {
        let m = unwelded_cube();
        assert_eq!(weld(&m, 1e-3).vertex_count(), 8);
        // eps larger than the cube merges everything.
        assert_eq!(weld(&m, 10.0).vertex_count(), 1);
    }

    /// A UV sphere (poles shared), outward winding.
    fn sphere(n_theta: u32, n_phi: u32) -> TriMesh {
        let mut m = TriMesh::default();
        m.positions.push(Vec3::Y);
        for i in 1..n_theta {
            let t = std::f32::consts::PI * i as f32 / n_theta as f32;
            for j in 0..n_phi {
                let p = std::f32::consts::TAU * j as f32 / n_phi as f32;
                // Non-uniform radius scaling would break radial normals; keep the unit sphere
                // but jitter the azimuth so triangles differ in size.
                let p = p + 0.1 * (i as f32).sin();
                m.positions
                    .push(Vec3::new(t.sin() * p.cos(), t.cos(), -t.sin() * p.sin()));
            }
        }
        m.positions.push(-Vec3::Y);
        let ring = |i: u32, j: u32| 1 + (i - 1) * n_phi + j % n_phi;
        let last = m.positions.len() as u32 - 1;
        for j in 0..n_phi {
            m.indices.push([0, ring(1, j), ring(1, j + 1)]);
            for i in 1..n_theta - 1 {
                m.indices
                    .push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
                m.indices
                    .push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
            }
            m.indices
                .push([ring(n_theta - 1, j), last, ring(n_theta - 1, j + 1)]);
        }
        m.material_ids = vec![0; m.indices.len()];
        m
    }

    #[test]
    fn sphere_normals_point_radially() {
        let m = sphere(24, 48);
        for w in [NormalWeighting::Angle, NormalWeighting::Area] {
            let n = smooth_normals(&m, w);
            for (p, n) in m.positions.iter().zip(&n) {
                // Averaging chords of a 24x48 tessellation tilts normals by well under 1 degree.
                assert!(n.dot(*p) > 0.9995, "{w:?}: {p} -> {n}");
            }
        }
    }

    #[test]
    fn degenerate_triangles_are_dropped_and_counted() {
        let mut m = unwelded_cube();
        m.indices.push([0, 0, 1]); // repeated index
        m.positions.push(Vec3::ZERO);
        m.positions.push(Vec3::X);
        m.positions.push(Vec3::X * 2.0);
        m.normals.extend([Vec3::Y; 3]);
        m.indices.push([24, 25, 26]); // collinear: zero area
        m.material_ids.extend([0, 0]);
        assert_eq!(drop_degenerate(&mut m), 2);
        assert_eq!(m.triangle_count(), 12);
        assert_eq!(m.material_ids.len(), 12);
        assert_eq!(remove_unused_vertices(&mut m), 3);
        validate(&m).unwrap();
    }

    #[test]
    fn empty_mesh_is_rejected() {
        assert!(validate(&TriMesh::default()).unwrap_err().contains("empty"));
    }

    #[test]
    fn validate_catches_broken_invariants() {
        let mut m = unwelded_cube();
        m.indices[0][1] = 99;
        assert!(validate(&m).unwrap_err().contains("beyond"));
        let mut m = unwelded_cube();
        m.normals[3] = Vec3::ZERO;
        assert!(validate(&m).unwrap_err().contains("unit"));
        let mut m = unwelded_cube();
        m.material_ids.pop();
        assert!(validate(&m).is_err());
    }

    #[test]
    fn midpoint_subdivision_keeps_the_surface_and_its_closure() {
        let m = weld(&unwelded_cube(), 1e-5);
        let (v, t) = (m.vertex_count(), m.triangle_count());
        let area = |m: &TriMesh| -> f32 {
            m.indices
                .iter()
                .map(|&[a, b, c]| {
                    let p = |i: u32| m.positions[i as usize];
                    0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length()
                })
                .sum()
        };
        let s = subdivide_midpoint(&m);
        // A closed mesh: E = 3T/2 new vertices, 4T triangles, the same area, and every
        // edge still shared by exactly two triangles.
        assert_eq!(s.vertex_count(), v + 3 * t / 2);
        assert_eq!(s.triangle_count(), 4 * t);
        assert_eq!(s.material_ids.len(), 4 * t);
        assert!(
            (area(&s) - area(&m)).abs() < 1e-4,
            "{} {}",
            area(&s),
            area(&m)
        );
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for &[a, b, c] in &s.indices {
            for (x, y) in [(a, b), (b, c), (c, a)] {
                *edges.entry((x.min(y), x.max(y))).or_default() += 1;
            }
        }
        assert!(edges.values().all(|&n| n == 2));
        assert_eq!(&s.positions[..v], &m.positions[..]);
        assert!(s.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
        validate(&s).unwrap();
    }
}
