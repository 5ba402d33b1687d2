//! Round trips and rejections of `sg` bundles, on hand-made bakes (no baking needed).

use super::*;
use relight_sphere::warp::Rng;

fn scene() -> SceneDesc {
    serde_json::from_str(
        r#"{"shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 4}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 8, "height": 8}}"#,
    )
    .unwrap()
}

/// A random bake of a small sphere with 2 direct and 1 indirect lobes and a material blend.
fn bundle(f16: bool) -> SgBundle {
    let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 4, 8);
    let v = mesh.vertex_count();
    let mut rng = Rng::new(9, 0);
    let mut r = || rng.next_f32();
    let mut lobes = |n: usize| SgLobes {
        lobe_count: n,
        view_count: 92,
        lobes: (0..v * 92 * n)
            .map(|_| {
                SgLobe::new(
                    Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5),
                    0.5 + 3000.0 * r(),
                    Vec3::new(r(), 10.0 * r(), 300.0 * r()),
                )
            })
            .collect(),
    };
    let (direct, indirect) = (lobes(2), lobes(1));
    let diffuse = ShTransfer {
        order: 3,
        kind: ShTransferKind::Shadowed,
        vertex_count: v,
        channels: 1,
        data: (0..v * 9).map(|i| (i as f32 * 0.37).sin()).collect(),
    };
    let a = Material::GgxPlastic {
        diffuse: Vec3::splat(0.5),
        specular: Vec3::ONE,
        alpha: 0.3,
        ior: 1.5,
    };
    let materials = (0..v)
        .map(|x| match x % 3 {
            0 => a,
            _ => Material::GgxPlastic {
                diffuse: Vec3::splat(0.5),
                specular: Vec3::ONE,
                alpha: 0.01 + x as f32 * 1e-3,
                ior: 1.5,
            },
        })
        .collect();
    let mut settings = SgRecordedSettings::new(&SgBakeSettings::default(), 3);
    settings.direct_lobes = 2;
    settings.indirect_lobes = 1;
    settings.diffuse_order = 3;
    settings.f16 = f16;
    SgBundle {
        scene: scene(),
        mesh,
        materials: vec![a],
        bake: SgBake {
            view_frequency: 3,
            direct,
            indirect: Some(indirect),
            diffuse,
            materials,
            stats: SgFitStats {
                mean_relative_error: [0.1, 0.2],
                iterations: 7,
                flips: 3,
                flips_after_relaxation: 1,
            },
        },
        settings,
    }
}

/// Write to bytes and read back, as `write` + `read` do (minus the file).
fn round_trip(b: &SgBundle) -> Result<SgBundle> {
    let path = Path::new("mem.relight");
    let bytes = b.to_bundle()?.to_bytes();
    SgBundle::from_bundle(path, &Bundle::from_bytes(path, &bytes)?)
}

#[test]
fn f32_bundle_round_trips_exactly() {
    let a = bundle(false);
    let b = round_trip(&a).unwrap();
    assert_eq!(a.bake.direct, b.bake.direct);
    assert_eq!(a.bake.indirect, b.bake.indirect);
    assert_eq!(a.bake.diffuse.data, b.bake.diffuse.data);
    assert_eq!(a.bake.materials, b.bake.materials);
    assert_eq!(a.bake.stats, b.bake.stats);
    assert_eq!(a.settings, b.settings);
    assert_eq!(a.materials, b.materials);
    assert_eq!(a.mesh.positions, b.mesh.positions);
    assert_eq!(a.mesh.indices, b.mesh.indices);
    // 92 views x 3 lobes x 7 floats + 9 SH coefficients, 4 bytes each.
    assert_eq!(a.transfer_bytes_per_vertex(), 4 * (92 * 3 * 7 + 9));
}

#[test]
fn f16_bundle_round_trips_within_half_precision() {
    let a = bundle(true);
    let b = round_trip(&a).unwrap();
    assert_eq!(a.transfer_bytes_per_vertex(), 2 * (92 * 3 * 7 + 9));
    let close = |x: f32, y: f32| (x - y).abs() <= 2f32.powi(-11) * x.abs() + 1e-7;
    for (p, q) in a.bake.direct.lobes.iter().zip(&b.bake.direct.lobes) {
        // Axes are renormalised after rounding each component to 11 significant bits.
        assert!((p.axis - q.axis).length() < 2e-3, "{p:?} {q:?}");
        assert!((q.axis.length() - 1.0).abs() < 1e-6);
        assert!(close(p.sharpness, q.sharpness), "{p:?} {q:?}");
        for c in 0..3 {
            assert!(close(p.amplitude[c], q.amplitude[c]), "{p:?} {q:?}");
        }
    }
    for (x, y) in a.bake.diffuse.data.iter().zip(&b.bake.diffuse.data) {
        assert!(close(*x, *y), "{x} {y}");
    }
    assert_eq!(a.bake.materials, b.bake.materials);
}

#[test]
fn corrupt_sg_bundles_are_rejected_with_a_clear_error() {
    let path = Path::new("bad.relight");
    let a = bundle(false);
    // A flipped byte in the data section: the checksum says so.
    let mut bytes = a.to_bundle().unwrap().to_bytes();
    let k = bytes.len() - 100;
    bytes[k] ^= 0x40;
    let e = Bundle::from_bytes(path, &bytes).unwrap_err().to_string();
    assert!(e.contains("bad.relight") && e.contains("checksum"), "{e}");
    // Valid checksums but inconsistent content: each error names the file and the problem.
    let check = |edit: &dyn Fn(&mut Bundle), want: &str| {
        let mut b = a.to_bundle().unwrap();
        edit(&mut b);
        let e = format!(
            "{:#}",
            SgBundle::from_bundle(path, &b).err().expect("rejected")
        );
        assert!(e.contains("bad.relight") && e.contains(want), "{want}: {e}");
    };
    check(
        &|b| {
            b.tensors.remove("sg_direct");
        },
        "sg_direct",
    );
    check(
        &|b| {
            let t = b.tensors.get_mut("sg_direct").unwrap();
            t.shape[2] = 1;
            t.bytes.truncate(t.bytes.len() / 2);
        },
        "shape",
    );
    check(
        &|b| {
            let t = b.tensors.get_mut("sg_indirect").unwrap();
            t.bytes[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
        },
        "non-finite",
    );
    check(
        &|b| {
            let t = b.tensors.get_mut("sg_direct").unwrap();
            t.bytes[12..16].copy_from_slice(&(-1f32).to_le_bytes());
        },
        "sharpness",
    );
    check(
        &|b| {
            b.metadata.insert("method".into(), "sh".into());
        },
        "is not 'sg'",
    );
    check(
        &|b| {
            b.metadata.insert("sg_materials".into(), "[]".into());
        },
        "vertex material",
    );
}
