use super::*;
use glam::Vec3;
use relight_scene::shapes::ground_plane;

#[test]
fn uniform_refinement_of_a_grid_is_the_finer_grid() {
    // A grid of equal triangles refined down to a fraction f of their area is split k times
    // with 4^-k <= f < 4^-(k-1), and has the counts of the grid 2^k times finer: each level
    // adds one vertex per edge and makes four triangles of one, with no T-vertex left. (Fractions away from
    // the powers of 1/4, where the area test is a tie up to rounding.)
    let g = ground_plane(Vec3::ZERO, 2.0, 3);
    for (f, k) in [(1.5, 0), (0.3, 1), (0.07, 2)] {
        let u = uniform_refinement(&g, f);
        let fine = ground_plane(Vec3::ZERO, 2.0, 3 << k);
        assert_eq!(u.vertex_count(), fine.vertex_count(), "fraction {f}");
        assert_eq!(u.triangle_count(), fine.triangle_count(), "fraction {f}");
        let area: f32 = u
            .indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| u.positions[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        assert!((area - 4.0).abs() < 1e-4, "fraction {f}: area {area}");
    }
}

#[test]
fn set_exponent_changes_blinn_phong_only() {
    let mut m = [
        Material::BlinnPhong {
            diffuse: Vec3::splat(0.1),
            specular: Vec3::splat(0.5),
            exponent: 4.0,
        },
        Material::Lambert {
            albedo: Vec3::splat(0.5),
        },
    ];
    let lambert = m[1];
    set_exponent(&mut m, 128.0);
    assert!(matches!(m[0], Material::BlinnPhong { exponent, .. } if exponent == 128.0));
    assert_eq!(m[1], lambert);
}

/// A small glossy sphere on a plane under a constant sky: the whole evaluation (tables and
/// the uniform comparison) in a few seconds.
#[test]
fn tiny_evaluation_writes_its_tables() {
    let dir = std::env::temp_dir().join(format!("relight_eval_vmf_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("tiny.json");
    std::fs::write(
        &scene,
        r#"{"shapes": [
             {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "rings": 6,
              "material": {"type": "blinn_phong", "diffuse": [0.2, 0.2, 0.2], "specular": [0.5, 0.5, 0.5], "exponent": 16}},
             {"type": "plane", "center": [0, 0, 0], "size": 3.0, "divisions": 2,
              "material": {"type": "lambert", "albedo": [0.5, 0.5, 0.5]}}],
           "environment": {"type": "constant", "radiance": [1, 1, 1]},
           "camera": {"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                      "fov_deg": 40, "width": 32, "height": 24}}"#,
    )
    .unwrap();
    let mut cases = scene_cases(&[scene]);
    cases[0].exponent = Some(32.0);
    let e = VmfEval {
        cases,
        settings: VmfBakeSettings {
            view_level: 1,
            paths: 32,
            material_samples: 64,
            progress: false,
            ..eval_settings(true)
        },
        uniform_case: Some("tiny".into()),
        sg: false,
        mitsuba: false,
        spp: 64,
        mitsuba_spp: 4,
        width: None,
        supersample: 1,
        out: dir.join("out"),
    };
    let rows = run(&e).unwrap();
    let tables: Vec<_> = rows.iter().filter(|r| r.table == "tables").collect();
    let uniform: Vec<_> = rows.iter().filter(|r| r.table == "uniform").collect();
    assert_eq!((tables.len(), uniform.len()), (1, 3));
    let r = tables[0];
    assert!(r.final_vertices >= r.initial_vertices, "{r:?}");
    assert!(
        r.views_per_vertex >= 17.0 - 1e-9,
        "level 1 has 17 views: {r:?}"
    );
    let desc = SceneDesc::read(&e.cases[0].scene).unwrap();
    let mesh = desc.build(&e.cases[0].scene).unwrap().mesh;
    assert_eq!(uniform[0].final_vertices, mesh.vertex_count());
    assert_eq!(
        uniform[2].final_vertices,
        uniform_refinement(&mesh, e.settings.spatial_min_area).vertex_count()
    );
    // The plane's 8 triangles are too coarse for the sphere's shadow: refining it must help
    // (measured 30 % on the initial mesh, 11 % adaptive, 13 % uniform at 16 spp).
    assert!(uniform[1].rel_rmse < uniform[0].rel_rmse, "{uniform:?}");
    // The refined meshes (adaptive, and uniform to the same area) with the default diffuse
    // term (SH transfer): measured 2026-12-07 at 6.71 % and 6.69 % against a path tracer whose
    // noise is 5.19 %, so 4.2 % without it; bounded by that plus 20 % in quadrature with the
    // row's noise (the run is seeded: the margin is for other platforms' rounding). A diffuse
    // term 5 % too dark measures 7.9 % and fails; the 45 % below passed it.
    const REFINED: f64 = 0.042;
    for r in [tables[0], uniform[1], uniform[2]] {
        let bound = (REFINED * 1.2).hypot(r.reference_noise);
        assert!(
            r.rel_rmse <= bound,
            "refined: {} above {bound}: {r:?}",
            r.rel_rmse
        );
    }
    for r in &rows {
        // Under a constant sky the transfer's energy is exact (sum of amplitudes times L);
        // what is left is 32 paths per slice, a 6-ring sphere, the path tracer's 64 spp
        // (its noise is in the row) and per-vertex interpolation of the shadow on the
        // 2 x 2 plane (the initial mesh's 29 %); 45 % catches a broken pipeline (a frame
        // without its glossy or its diffuse term is off by more).
        assert!(r.rel_rmse.is_finite() && r.rel_rmse < 0.45, "{r:?}");
        assert!(r.reference_noise > 0.0 && r.reference_noise < 0.1, "{r:?}");
        assert!(
            r.transfer_mib_f16 > 0.0 && r.bundle_mib_f16 > r.transfer_mib_f16,
            "{r:?}"
        );
    }
    let md = std::fs::read_to_string(e.out.join("results.md")).unwrap();
    assert!(md.contains("Tables 1-2") && md.contains("uniform"), "{md}");
    for f in [
        "pathtracer.png",
        "vmf.png",
        "vmf_error.png",
        "vmf_uniform.png",
    ] {
        assert!(e.out.join("tiny").join(f).is_file(), "{f}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
