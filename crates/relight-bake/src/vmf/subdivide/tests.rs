use super::*;
use relight_scene::shapes::ground_plane;
use relight_sphere::warp::Rng;

fn total_area(m: &TriMesh) -> f64 {
    (0..m.triangle_count())
        .map(|t| {
            let [a, b, c] = m.triangle(t);
            0.5 * (b - a).cross(c - a).length() as f64
        })
        .sum()
}

/// Undirected edge -> number of triangles using it.
fn edge_uses(m: &TriMesh) -> HashMap<(u32, u32), usize> {
    let mut e = HashMap::new();
    for t in &m.indices {
        for k in 0..3 {
            *e.entry(key(t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    e
}

/// No vertex of `m` lies strictly inside an edge of `m` (no T-junction), checked by position.
fn assert_conforming(m: &TriMesh) {
    for (&(a, b), _) in edge_uses(m).iter() {
        let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
        for t in &m.indices {
            for &v in t {
                if v == a || v == b {
                    continue;
                }
                let p = m.positions[v as usize];
                let d = pb - pa;
                let s = (p - pa).dot(d) / d.length_squared();
                let off = (pa + d * s - p).length();
                assert!(
                    !(s > 1e-4 && s < 1.0 - 1e-4 && off < 1e-6),
                    "vertex {v} lies inside edge ({a}, {b})"
                );
            }
        }
    }
}

/// Every live leaf's edge holds at most one T-vertex (neighbours within one level).
fn assert_one_level(m: &AdaptiveMesh) {
    for t in m.live() {
        let v = m.leaves[t].v;
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            if let Some(&x) = m.mid.get(&key(a, b)) {
                assert!(
                    !m.mid.contains_key(&key(a, x)) && !m.mid.contains_key(&key(x, b)),
                    "leaf {t}: two levels on edge ({a}, {b})"
                );
            }
        }
    }
}

#[test]
fn random_splits_stay_conforming_within_one_level_and_keep_the_area() {
    let plane = ground_plane(Vec3::ZERO, 2.0, 3);
    let area = total_area(&plane);
    let mut m = AdaptiveMesh::new(&plane);
    let mut rng = Rng::new(9, 0);
    for _ in 0..60 {
        let live: Vec<usize> = m.live().collect();
        let t = live[(rng.next_f32() * live.len() as f32) as usize % live.len()];
        let split = m.split(t);
        assert_eq!(*split.last().unwrap(), t);
        assert_one_level(&m);
    }
    assert!(m.leaves.iter().any(|l| l.alive && l.level >= 3));
    let out = m.finish();
    assert!((total_area(&out) - area).abs() < 1e-4 * area);
    assert_conforming(&out);
    // Interior edges are used twice, the plane's border once.
    for (&(a, b), &n) in &edge_uses(&out) {
        let mid = 0.5 * (out.positions[a as usize] + out.positions[b as usize]);
        let border = mid.x.abs() > 0.999 || mid.z.abs() > 0.999;
        assert_eq!(n, if border { 1 } else { 2 }, "edge ({a}, {b})");
    }
    // Counter-clockwise as the input: every triangle faces +Y.
    for t in 0..out.triangle_count() {
        assert!(out.geometric_normal(t).y > 0.99);
    }
    // New vertices are midpoints with unit normals.
    for (v, p) in m.parents.iter().enumerate() {
        if let Some([a, b]) = p {
            let want = 0.5 * (m.positions[*a as usize] + m.positions[*b as usize]);
            assert!((m.positions[v] - want).length() < 1e-6);
            assert!((m.normals[v].length() - 1.0).abs() < 1e-5);
        }
    }
}

#[test]
fn non_manifold_edges_and_holes_subdivide_cleanly() {
    // Three triangles on the edge (0, 1) (a fin: non-manifold) and a plane with a hole.
    let mut mesh = TriMesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, 0.0, 1.0),
        ],
        normals: vec![Vec3::Z; 5],
        uvs: None,
        indices: vec![[0, 1, 2], [1, 0, 3], [1, 0, 4]],
        material_ids: vec![0, 0, 1],
    };
    let area = total_area(&mesh);
    let mut m = AdaptiveMesh::new(&mesh);
    m.split(0);
    m.split(4); // a child of triangle 0 touching the shared edge
    assert_one_level(&m);
    let out = m.finish();
    assert!((total_area(&out) - area).abs() < 1e-5 * area);
    assert_conforming(&out);
    // The fin kept its material on every piece.
    assert!(out.material_ids.contains(&1));
    // A hole: the plane without one triangle.
    mesh = ground_plane(Vec3::ZERO, 2.0, 2);
    mesh.indices.remove(3);
    mesh.material_ids.truncate(mesh.indices.len());
    let area = total_area(&mesh);
    let mut m = AdaptiveMesh::new(&mesh);
    for t in [2, 3, 4] {
        if m.leaves[t].alive {
            m.split(t);
        }
    }
    let live: Vec<usize> = m.live().collect();
    m.split(live[live.len() - 1]);
    assert_one_level(&m);
    let out = m.finish();
    assert!((total_area(&out) - area).abs() < 1e-5 * area);
    assert_conforming(&out);
}
