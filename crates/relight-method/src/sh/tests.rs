//! The `sh` method through the seam: bake, store, load (also bundles from before schema 2),
//! content checks, vertex ranges, and its frames against each other.

use super::*;
use crate::{from_bundle, Baked, FrameOptions, FrameSettings, MethodKind};
use relight_bake::sh::ShTransferKind;
use relight_scene::scene_file::SceneDesc;

fn desc() -> SceneDesc {
    serde_json::from_str(
        r#"{"shapes": [
              {"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 8,
               "material": {"type": "lambert", "albedo": [0.8, 0.3, 0.2]}},
              {"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 4}],
            "environment": {"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 30,
                            "turbidity": 3, "ground_albedo": [0.3, 0.3, 0.3]},
            "camera": {"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 24, "height": 16}}"#,
    )
    .unwrap()
}

fn bake_of(settings: &ShBakeSettings, range: Option<Range<usize>>, f16: bool) -> ShBaked {
    let d = desc();
    let s = d.build(Path::new("<test>")).unwrap();
    let input = crate::BakeInput {
        desc: &d,
        scene: &s,
        origin: Path::new("<test>"),
    };
    let ctx = crate::BakeContext {
        f16,
        ..Default::default()
    };
    let range = range.unwrap_or(0..s.mesh.vertex_count());
    Sh::bake(input, settings, range, &ctx).unwrap()
}

fn shadowed() -> ShBakeSettings {
    ShBakeSettings {
        order: 4,
        samples: 64,
        seed: 2,
        ..Default::default()
    }
}

fn read_back(b: &Bundle) -> Result<ShBaked, MethodError> {
    let path = Path::new("mem.relight");
    match from_bundle(&Bundle::from_bytes(path, &b.to_bytes())?, path)? {
        Baked::Sh(s) => Ok(s),
        other => panic!("read back as {:?}", other.kind()),
    }
}

#[test]
fn bundles_round_trip_exactly_in_f32_and_within_half_precision_in_f16() {
    for s in [
        shadowed(),
        ShBakeSettings {
            transfer: ShTransferKind::Interreflected,
            bounces: 1,
            ..shadowed()
        },
    ] {
        let a = bake_of(&s, None, false);
        let b = read_back(&Sh::store(&a).unwrap()).unwrap();
        assert_eq!(a.transfer, b.transfer);
        assert_eq!(a.albedo, b.albedo);
        assert_eq!(a.settings, b.settings);
        // The wall time is reported, not stored (a bake's bytes are reproducible).
        assert_eq!(b.record.seconds, 0.0);
        assert_eq!(
            BakeRecord {
                seconds: 0.0,
                ..a.record.clone()
            },
            b.record
        );
        assert_eq!(a.scene.mesh.indices, b.scene.mesh.indices);
        let h = read_back(
            &Sh::store(&ShBaked {
                record: BakeRecord {
                    f16: true,
                    ..a.record.clone()
                },
                ..a.clone()
            })
            .unwrap(),
        )
        .unwrap();
        for (x, y) in a.transfer.data.iter().zip(&h.transfer.data) {
            // f16: 11 significant bits, and subnormals below 2^-14 (absolute 6e-8).
            assert!((x - y).abs() <= 2f32.powi(-11) * x.abs() + 6e-8, "{x} {y}");
        }
    }
}

#[test]
fn bundles_from_before_the_seam_still_load() {
    // Schema 1: no `schema` or `record`; the settings object held the record's fields.
    let a = bake_of(&shadowed(), None, false);
    let mut b = Sh::store(&a).unwrap();
    b.metadata.remove("schema");
    b.metadata.remove("record");
    b.metadata.insert(
        "settings".into(),
        r#"{"order":4,"transfer":"shadowed","bounces":0,"samples":64,"seed":2,"f16":false,
            "backend":"bvh","seconds":0.25}"#
            .into(),
    );
    let old = read_back(&b).unwrap();
    assert_eq!(old.settings, a.settings);
    assert_eq!(old.record.backend, "bvh");
    assert_eq!(old.record.range, None);
    assert_eq!(old.transfer, a.transfer);
}

#[test]
fn valid_checksums_with_invalid_contents_are_refused() {
    let a = bake_of(&shadowed(), None, false);
    let path = Path::new("bad.relight");
    let check = |edit: &dyn Fn(&mut Bundle), want: &str| {
        let mut b = Sh::store(&a).unwrap();
        edit(&mut b);
        // Through bytes, so the checksums are recomputed and valid.
        let b = Bundle::from_bytes(path, &b.to_bytes()).unwrap();
        let e = from_bundle(&b, path).expect_err("rejected").to_string();
        assert!(e.contains("bad.relight") && e.contains(want), "{want}: {e}");
    };
    let put = |b: &mut Bundle, name: &str, at: usize, x: &[u8]| {
        let t = b.tensors.get_mut(name).unwrap();
        t.bytes[at..at + x.len()].copy_from_slice(x);
    };
    check(&|b| put(b, "albedo", 0, &(-5f32).to_le_bytes()), "albedo");
    check(&|b| put(b, "albedo", 4, &1e30f32.to_le_bytes()), "albedo");
    check(
        &|b| put(b, "indices", 8, &u32::MAX.to_le_bytes()),
        "triangle index",
    );
    check(
        &|b| put(b, "transfer", 8, &f32::INFINITY.to_le_bytes()),
        "non-finite",
    );
    check(
        &|b| {
            drop(
                b.metadata
                    .insert("settings".into(), r#"{"order":3}"#.into()),
            )
        },
        "settings",
    );
    check(
        &|b| {
            drop(b.metadata.insert(
                "materials".into(),
                r#"[{"type":"lambert","albedo":[2,0,0]}]"#.into(),
            ))
        },
        "material",
    );
}

#[test]
fn part_bundles_hold_their_rows_and_are_not_rendered() {
    let whole = bake_of(&shadowed(), None, false);
    let n = whole.scene.mesh.vertex_count();
    let part = bake_of(&shadowed(), Some(10..n / 2), false);
    assert_eq!(part.record.range, Some((10, n / 2)));
    assert_eq!(
        part.transfer.data[..],
        whole.transfer.data[10 * 16..n / 2 * 16]
    );
    let back = read_back(&Sh::store(&part).unwrap()).unwrap();
    assert_eq!(back.transfer, part.transfer);
    let e = Baked::Sh(back)
        .frame_of(
            &FrameSettings::default_for(MethodKind::Sh),
            Path::new("p.relight"),
        )
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("p.relight") && e.contains("part bundle") && e.contains("merge"),
        "{e}"
    );
}

/// Render `b` with `settings` under the scene's own environment.
fn render(b: &Baked, settings: FrameSettings) -> relight_render::Image {
    let env = relight_scene::scene_file::build_env(&b.scene().desc.environment).unwrap();
    let mut f = b.frame(&settings).unwrap();
    f.set_environment(&env).unwrap();
    f.render(&b.scene().desc.camera, &FrameOptions::default())
        .image
}

#[test]
fn a_lower_lighting_order_is_the_bake_truncated() {
    // The SH basis is hierarchical: lighting of order 2 on an order-4 bake equals an order-2
    // bake (same directions: the first 4 coefficients of each sample are the same).
    let four: Baked = bake_of(&shadowed(), None, false).into();
    let two: Baked = bake_of(
        &ShBakeSettings {
            order: 2,
            ..shadowed()
        },
        None,
        false,
    )
    .into();
    let a = render(
        &four,
        FrameSettings::Sh(ShFrameSettings {
            sh_order: Some(2),
            ..Default::default()
        }),
    );
    let b = render(&two, FrameSettings::Sh(ShFrameSettings::default()));
    let d = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .fold(0f32, f32::max);
    // Same data up to float summation order in the dot products.
    assert!(d < 1e-5, "{d}");
    let e = four
        .frame(&FrameSettings::Sh(ShFrameSettings {
            sh_order: Some(5),
            ..Default::default()
        }))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("SH order 5") && e.contains("1..=4"), "{e}");
}

#[test]
fn hybrid_without_lights_is_the_sh_frame() {
    // A constant environment has nothing to extract: the hybrid frame is the SH frame.
    let mut b = bake_of(&shadowed(), None, false);
    b.scene.desc.environment =
        serde_json::from_str(r#"{"type": "constant", "radiance": [0.7, 0.8, 0.9]}"#).unwrap();
    let b: Baked = b.into();
    let sh = render(&b, FrameSettings::default_for(MethodKind::Sh));
    let hy = render(&b, FrameSettings::default_for(MethodKind::Hybrid));
    let d = sh
        .pixels
        .iter()
        .zip(&hy.pixels)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .fold(0f32, f32::max);
    // The decomposition's SH part of a constant map is its projection (up to its quadrature).
    assert!(d < 1e-3, "{d}");
    let lit = sh.pixels.iter().filter(|p| p.max_element() > 0.0).count();
    assert!(lit > sh.pixels.len() / 4, "{lit}");
}

#[test]
fn frame_sizes_are_checked_before_allocating() {
    let mut c = desc().camera;
    let o = FrameOptions::default();
    assert!(crate::check_frame_options(&o, &c).is_ok());
    (c.width, c.height) = (16384, 16384);
    let e = crate::check_frame_options(&o, &c).unwrap_err().to_string();
    assert!(e.contains("16384 x 16384"), "{e}");
    // 8192^2 pixels is the image limit; 3 x 3 samples each exceed the 2^28 samples.
    (c.width, c.height) = (8192, 8192);
    let three = FrameOptions {
        supersample: 3,
        ..o
    };
    let e = crate::check_frame_options(&three, &c)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--supersample"), "{e}");
    assert!(
        crate::check_frame_options(&o, &c).is_ok(),
        "2 x 2 is exactly 2^28"
    );
    let one = FrameOptions {
        supersample: 1,
        ..o
    };
    assert!(crate::check_frame_options(&one, &c).is_ok());
    let zero = FrameOptions {
        supersample: 0,
        ..o
    };
    assert!(crate::check_frame_options(&zero, &c).is_err());
}
