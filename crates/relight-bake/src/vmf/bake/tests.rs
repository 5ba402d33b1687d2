use super::*;
use crate::vmf::slice::transfer_slice;
use relight_scene::accel::build_default;
use relight_scene::shapes::{aabb_box, ground_plane};

/// A 2x2-quad plane (Blinn-Phong) with a Lambert box on it: 9 + 24 vertices.
fn scene() -> (TriMesh, Vec<Material>) {
    let mut mesh = ground_plane(Vec3::ZERO, 4.0, 2);
    mesh.material_ids = vec![0; mesh.indices.len()];
    let mut b = aabb_box(Vec3::new(0.2, 0.0, -0.5), Vec3::new(0.8, 0.6, 0.5), 1);
    b.material_ids = vec![0; b.indices.len()];
    mesh.append(&b, 1);
    let mats = vec![
        Material::BlinnPhong {
            diffuse: Vec3::splat(0.3),
            specular: Vec3::splat(0.6),
            exponent: 32.0,
        },
        Material::Lambert {
            albedo: Vec3::splat(0.5),
        },
    ];
    (mesh, mats)
}

fn small() -> VmfBakeSettings {
    VmfBakeSettings {
        view_level: 1,
        paths: 64,
        material_samples: 128,
        ..Default::default()
    }
}

#[test]
fn views_are_the_upper_half_of_the_level() {
    for level in 0..=3 {
        let s = VmfBakeSettings {
            view_level: level,
            ..Default::default()
        };
        let views = s.views();
        let all = Icosphere::new(1 << level).vertices().len();
        assert!(views
            .iter()
            .all(|v| v.z > 0.0 && (v.length() - 1.0).abs() < 1e-5));
        // The icosphere is symmetric under w -> -w: at most half its vertices are above.
        assert!(
            views.len() <= all / 2 && views.len() >= all / 2 - 4 * (1 << level),
            "{level}"
        );
        // The counts the module docs give (4 icosahedron vertices lie on the horizon).
        if level <= 1 {
            assert_eq!(views.len(), [4, 17][level as usize]);
        }
    }
}

#[test]
fn bake_is_valid_deterministic_and_equals_its_slices() {
    let (mesh, mats) = scene();
    let caster = build_default(&mesh);
    let one = bake(
        &mesh,
        &mats,
        None,
        caster.as_ref(),
        &VmfBakeSettings {
            threads: Some(1),
            ..small()
        },
    )
    .expect("bake");
    one.validate().expect("a fresh bake is valid");
    assert_eq!(one.vertex_count(), mesh.vertex_count());
    let two = bake(
        &mesh,
        &mats,
        None,
        caster.as_ref(),
        &VmfBakeSettings {
            threads: Some(2),
            ..small()
        },
    )
    .expect("bake");
    // (`threads` itself is recorded in the settings, so compare the slices.)
    assert_eq!((&one.levels, &one.offsets), (&two.levels, &two.offsets));
    assert!(one.slices == two.slices, "the thread count changes nothing");
    // A slice of the bake is the slice of its (vertex, view) stream.
    let vm = crate::sg::transport::vertex_materials(&mesh, &mats);
    let ng = crate::transport::vertex_geometric_normals(&mesh);
    let sc = SliceScene {
        mesh: &mesh,
        caster: caster.as_ref(),
        vertex_materials: &vm,
    };
    let views = one.settings.views();
    let nv = views.len();
    for (x, v) in [(4, 0), (4, nv - 1), (12, 3)] {
        let p = SurfacePoint {
            position: mesh.positions[x],
            normal: mesh.normals[x],
            geometric_normal: ng[x],
            material: vm[x],
        };
        let s = small();
        let direct = transfer_slice(
            &sc,
            &p,
            views[v],
            &s.slice_settings(),
            s.seed,
            crate::vmf::refine::slice_stream(x, s.view_level, v),
        );
        assert_eq!(*one.slice(x, v), direct);
    }
    // The centre of the plane (vertex 4) sees light at every view.
    for v in 0..nv {
        assert!(one.slice(4, v).integral().x > 0.0);
    }
}

#[test]
fn validate_catches_broken_bakes() {
    let (mesh, mats) = scene();
    let caster = build_default(&mesh);
    let good = bake(&mesh, &mats, None, caster.as_ref(), &small()).expect("bake");
    let mut b = good.clone();
    b.slices.pop();
    assert!(b.validate().is_err());
    let mut b = good.clone();
    b.slices[3].lobes[1][0].kappa = f32::NAN;
    assert!(b.validate().is_err());
    let mut b = good.clone();
    b.slices[0].lobes[0][0].amplitude.y = -1.0;
    assert!(b.validate().is_err());
    let mut b = good.clone();
    b.slices[0].lobes[0][2].axis = Vec3::ZERO;
    assert!(b.validate().is_err());
    let mut b = good.clone();
    b.levels[2] = 2;
    assert!(b.validate().is_err());
    let mut b = good.clone();
    b.offsets[3] += 1;
    assert!(b.validate().is_err());
    let mut b = good;
    b.offsets.pop();
    assert!(b.validate().is_err());
}

#[test]
fn bad_settings_and_scenes_are_refused_by_name() {
    let (mesh, mats) = scene();
    let caster = build_default(&mesh);
    let run = |s: &VmfBakeSettings, m: &[Material], vm: Option<&[Material]>| {
        bake(&mesh, m, vm, caster.as_ref(), s)
    };
    for (s, name) in [
        (
            VmfBakeSettings {
                view_level: MAX_VIEW_LEVEL + 1,
                ..small()
            },
            "view_level",
        ),
        (
            VmfBakeSettings {
                paths: 0,
                ..small()
            },
            "paths",
        ),
        (
            VmfBakeSettings {
                kappa_max: f32::INFINITY,
                ..small()
            },
            "kappa_max",
        ),
    ] {
        match run(&s, &mats, None) {
            Err(BakeError::Settings(m)) => assert!(m.contains(name), "{m}"),
            other => panic!("{name}: {other:?}"),
        }
    }
    // One material for two material ids; vertex materials of the wrong count; a bad one.
    assert!(matches!(
        run(&small(), &mats[..1], None),
        Err(BakeError::Scene(_))
    ));
    assert!(matches!(
        run(&small(), &mats, Some(&mats)),
        Err(BakeError::Scene(_))
    ));
    let mut vm = crate::sg::transport::vertex_materials(&mesh, &mats);
    vm[3] = Material::Lambert {
        albedo: Vec3::splat(2.0),
    };
    match run(&small(), &mats, Some(&vm)) {
        Err(BakeError::Scene(m)) => assert!(m.contains("vertex 3"), "{m}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn parts_of_a_bake_concatenate_to_the_whole() {
    let (mesh, mats) = scene();
    let caster = build_default(&mesh);
    let whole = bake(&mesh, &mats, None, caster.as_ref(), &small()).expect("bake");
    let n = mesh.vertex_count();
    let mut parts: Option<VmfBake> = None;
    for r in [0..7, 7..7, 7..20, 20..n] {
        let p = bake_vertices(&mesh, &mats, None, caster.as_ref(), &small(), r).expect("part");
        p.validate().expect("a part is valid");
        match &mut parts {
            None => parts = Some(p),
            Some(all) => all.append(p),
        }
    }
    assert!(parts.as_ref() == Some(&whole));
    for r in [0..n + 1, n + 1..n + 2] {
        assert!(matches!(
            bake_vertices(&mesh, &mats, None, caster.as_ref(), &small(), r),
            Err(BakeError::Settings(_))
        ));
    }
}

#[test]
fn adaptive_bakes_are_valid_split_exactly_and_refuse_bad_levels() {
    let (mesh, mats) = scene();
    let caster = build_default(&mesh);
    let s = VmfBakeSettings {
        view_level: 2,
        min_view_level: 0,
        angular_threshold: 0.05,
        ..small()
    };
    let whole = bake(&mesh, &mats, None, caster.as_ref(), &s).expect("bake");
    whole.validate().expect("valid");
    assert!(whole.levels.iter().all(|&l| l <= 2));
    let n = mesh.vertex_count();
    let mut parts = bake_vertices(&mesh, &mats, None, caster.as_ref(), &s, 0..10).unwrap();
    parts.append(bake_vertices(&mesh, &mats, None, caster.as_ref(), &s, 10..n).unwrap());
    assert!(parts == whole);
    // A level outside min_view_level..=view_level is invalid.
    let mut b = whole.clone();
    let l = b.levels[0];
    b.levels[0] = 3;
    assert!(b.validate().is_err() || l == 3);
    for (bad, name) in [
        (
            VmfBakeSettings {
                min_view_level: 3,
                ..s
            },
            "min_view_level",
        ),
        (
            VmfBakeSettings {
                angular_threshold: -1.0,
                ..s
            },
            "angular_threshold",
        ),
    ] {
        match bake(&mesh, &mats, None, caster.as_ref(), &bad) {
            Err(BakeError::Settings(m)) => assert!(m.contains(name), "{m}"),
            other => panic!("{name}: {other:?}"),
        }
    }
}
