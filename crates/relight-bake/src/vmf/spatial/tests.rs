use super::*;
use relight_scene::accel::build_default;
use relight_scene::shapes::{aabb_box, ground_plane};

/// A 4x4 Lambert plane of 4 x 4 quads with a Lambert box on it near +X.
fn scene() -> (TriMesh, Vec<Material>) {
    let mut mesh = ground_plane(Vec3::ZERO, 4.0, 4);
    mesh.material_ids = vec![0; mesh.indices.len()];
    let mut b = aabb_box(Vec3::new(0.6, 0.0, -0.5), Vec3::new(1.4, 0.8, 0.5), 1);
    b.material_ids = vec![0; b.indices.len()];
    mesh.append(&b, 1);
    let l = |a: f32| Material::Lambert {
        albedo: Vec3::splat(a),
    };
    (mesh, vec![l(0.6), l(0.4)])
}

fn settings(threshold: f32) -> VmfBakeSettings {
    VmfBakeSettings {
        view_level: 1,
        paths: 256,
        material_samples: 128,
        spatial_threshold: threshold,
        spatial_min_area: 1.0 / 16.0,
        spatial_batch: 8,
        ..Default::default()
    }
}

#[test]
fn a_vertex_differs_from_itself_by_nothing_and_levels_may_differ() {
    let r = Refiner::new(2);
    let s = |k: f32| {
        let mut t = TransferSlice {
            lobes: [[relight_sphere::vmf::VmfLobe::new(Vec3::Z, 3.0, Vec3::splat(0.5)); 3]; 2],
        };
        t.lobes[0][0].kappa = k;
        t
    };
    let a1 = vec![s(3.0); 17];
    let a2 = vec![s(3.0); 73];
    assert_eq!(vertex_difference(&r, (1, &a1), (1, &a1)), 0.0);
    // The same (view-independent) transfer at two levels: nothing to tell apart.
    // (Up to the cancellation of the mixture distance: 1e-7 of the squared norms, whose
    // square root is about 3e-4 of the slice norm, 0.2 here.)
    assert!(vertex_difference(&r, (1, &a1), (2, &a2)) < 1e-3);
    let b2 = vec![s(30.0); 73];
    let d = vertex_difference(&r, (1, &a1), (2, &b2));
    assert!(d > 0.1, "{d}");
    assert_eq!(d, vertex_difference(&r, (2, &b2), (1, &a1)));
}

#[test]
fn refinement_follows_the_occluder_and_stops_by_its_rule() {
    let (mesh, mats) = scene();
    let caster = build_default(&mesh);
    let t = 0.05;
    let (bake, out, stats) =
        bake_refined(&mesh, &mats, None, caster.as_ref(), &settings(t)).expect("bake");
    bake.validate().expect("valid");
    assert_eq!(bake.vertex_count(), out.vertex_count());
    assert!(out
        .indices
        .iter()
        .flatten()
        .all(|&i| (i as usize) < out.vertex_count()));
    // Measured 2026-12-02: 18 iterations, 174 splits, 49 -> 372 vertices, largest error left
    // 0.0488.
    assert!(stats.iterations >= 1 && out.vertex_count() > mesh.vertex_count());
    // The rule: no triangle above the minimum area is left with an error above the threshold.
    assert!(stats.max_error_left <= t, "{stats:?}");
    // New vertices gather around the box (x in [0.6, 1.4]), not at the far side of the plane.
    let new = &out.positions[mesh.vertex_count()..];
    let far = new.iter().filter(|p| p.x < -1.0 && p.y < 1e-4).count();
    let near = new
        .iter()
        .filter(|p| p.x > 0.0 && p.x < 2.0 && p.y < 1e-4)
        .count();
    assert!(near > 2 * far.max(1), "near {near}, far {far}");
    // Determinism: the same bake again.
    let (again, out2, _) =
        bake_refined(&mesh, &mats, None, caster.as_ref(), &settings(t)).expect("bake");
    assert!(again == bake && out2.indices == out.indices);
    // Off is refused here (the caller bakes the mesh as it is).
    assert!(bake_refined(&mesh, &mats, None, caster.as_ref(), &settings(0.0)).is_err());
}
