//! `vmf` through the seam: bundle round trips (f32 exact, f16 within half precision),
//! corruptions and other methods' bundles refused by name, sharded bakes merged to the
//! whole bake's bytes, a frame through `Baked::frame`.

use super::*;
use crate::shard::{bake_part, merge, Shard};
use crate::test_scene::with_input;
use crate::{Baked, FrameOptions, FrameSettings, MethodKind};
use relight_bundle::{Bundle, Tensor};
use relight_scene::accel::Backend;
use std::path::{Path, PathBuf};

fn settings() -> VmfBakeSettings {
    VmfBakeSettings {
        view_level: 1,
        paths: 32,
        material_samples: 64,
        seed: 3,
        ..Default::default()
    }
}

fn ctx(f16: bool) -> BakeContext {
    BakeContext {
        backend: Backend::Bvh,
        f16,
        progress: false,
    }
}

/// A small real bake of the test scene (all vertices, or part `shard`).
fn baked(f16: bool, shard: Option<Shard>) -> Baked {
    with_input(0.5, |input| match shard {
        Some(s) => bake_part::<Vmf>(input, &settings(), s, &ctx(f16)).unwrap(),
        None => Vmf::bake(
            input,
            &settings(),
            0..input.scene.mesh.vertex_count(),
            &ctx(f16),
        )
        .unwrap()
        .into(),
    })
}

fn vmf(b: &Baked) -> &VmfBaked {
    match b {
        Baked::Vmf(v) => v,
        _ => panic!("not a vmf bake"),
    }
}

fn round_trip(b: &Baked) -> Result<Baked, MethodError> {
    let bytes = b.to_bundle()?.to_bytes();
    crate::from_bundle(
        &Bundle::from_bytes(Path::new("x.relight"), &bytes)?,
        Path::new("x.relight"),
    )
}

#[test]
fn f32_round_trip_is_exact() {
    let b = baked(false, None);
    let v = vmf(&b);
    v.validate().unwrap();
    assert_eq!(v.bake.slices.len(), v.scene.mesh.vertex_count() * 17);
    assert!(v.bake.slices.iter().any(|s| s.integral().x > 0.1));
    let back = round_trip(&b).unwrap();
    assert_eq!(vmf(&back).bake, v.bake);
    assert_eq!(vmf(&back).settings, v.settings);
    // (The wall time is not written to bundles.)
    let (r, q) = (back.record(), b.record());
    assert_eq!(
        (&r.backend, r.f16, r.range, r.shard),
        (&q.backend, q.f16, q.range, q.shard)
    );
    assert_eq!(back.scene().mesh.positions, b.scene().mesh.positions);
}

#[test]
fn f16_round_trip_within_half_precision() {
    let b = baked(true, None);
    let back = round_trip(&b).unwrap();
    let (x, y) = (&vmf(&back).bake, &vmf(&b).bake);
    assert_eq!((&x.levels, &x.offsets), (&y.levels, &y.offsets));
    // f16: 11-bit significand (relative rounding 2^-11), and values below 2^-14 subnormal
    // (absolute rounding 2^-25).
    let close = |a: f32, b: f32| (a - b).abs() <= b.abs() * 2f32.powi(-11) + 2f32.powi(-24);
    for (p, q) in x.slices.iter().zip(&y.slices) {
        for (l, m) in p.lobes.iter().flatten().zip(q.lobes.iter().flatten()) {
            assert!(
                (l.axis - m.axis).length() < 2e-3,
                "{} vs {}",
                l.axis,
                m.axis
            );
            assert!(close(l.kappa, m.kappa), "{} vs {}", l.kappa, m.kappa);
            for c in 0..3 {
                assert!(close(l.amplitude[c], m.amplitude[c]), "{l:?} vs {m:?}");
            }
        }
    }
}

/// Store `b`, change the bundle with `f`, load: the error message.
fn corrupt(b: &Baked, f: impl FnOnce(&mut Bundle)) -> String {
    let mut bundle = b.to_bundle().unwrap();
    f(&mut bundle);
    let bytes = bundle.to_bytes();
    let bundle = Bundle::from_bytes(Path::new("x.relight"), &bytes).unwrap();
    load(&bundle, Path::new("x.relight"))
        .unwrap_err()
        .to_string()
}

#[test]
fn corruptions_are_refused_by_name() {
    let b = baked(false, None);
    let v = vmf(&b);
    let n = v.bake.vertex_count();
    let msg = corrupt(&b, |x| {
        let mut l = vec![1u32; n];
        l[4] = 9;
        x.insert("vmf_levels", Tensor::from_u32(vec![n], &l));
    });
    assert!(
        msg.contains("vmf_levels") && msg.contains("level 9"),
        "{msg}"
    );
    // A level the settings do not allow: more slices than stored.
    let msg = corrupt(&b, |x| {
        let mut l = vec![1u32; n];
        l[4] = 2;
        x.insert("vmf_levels", Tensor::from_u32(vec![n], &l));
    });
    assert!(msg.contains("vmf_lobes") && msg.contains("shape"), "{msg}");
    let lobes = |f: &dyn Fn(&mut Vec<f32>)| {
        let t = b.to_bundle().unwrap().tensors["vmf_lobes"].clone();
        let mut d = t.to_f32().unwrap();
        f(&mut d);
        Tensor::from_f32(t.shape, &d)
    };
    let msg = corrupt(&b, |x| {
        x.insert("vmf_lobes", lobes(&|d| d[10] = f32::NAN));
    });
    assert!(
        msg.contains("vmf_lobes") && msg.contains("non-finite"),
        "{msg}"
    );
    let msg = corrupt(&b, |x| {
        // Lobe 1 of slice 0: its kappa (float 3 of 7) negative.
        x.insert("vmf_lobes", lobes(&|d| d[7 + 3] = -1.0));
    });
    assert!(msg.contains("kappa"), "{msg}");
    let msg = corrupt(&b, |x| {
        x.insert("vmf_lobes", lobes(&|d| d[0] = 3.0));
    });
    assert!(msg.contains("axis"), "{msg}");
    let msg = corrupt(&b, |x| {
        x.insert("vmf_lobes", lobes(&|d| d[5] = -0.5));
    });
    assert!(msg.contains("amplitude"), "{msg}");
    let msg = corrupt(&b, |x| {
        x.tensors.remove("vmf_levels");
    });
    assert!(msg.contains("vmf_levels"), "{msg}");
}

#[test]
fn other_methods_bundles_are_refused_naming_the_method() {
    let v = baked(false, None);
    // A vmf bundle given to other methods, and read as another kind.
    for m in [MethodKind::Sg, MethodKind::Sh, MethodKind::Cuts] {
        let e = v
            .frame(&FrameSettings::default_for(m))
            .err()
            .expect("refused")
            .to_string();
        assert!(
            e.contains("`vmf` bake") && e.contains(&format!("--method {}", m.name())),
            "{e}"
        );
    }
    // Another method's bundle given to --method vmf.
    let sh: Baked = with_input(0.5, |input| {
        let s = relight_bake::sh::ShBakeSettings {
            order: 2,
            samples: 16,
            ..Default::default()
        };
        crate::sh::Sh::bake(input, &s, 0..input.scene.mesh.vertex_count(), &ctx(false))
            .unwrap()
            .into()
    });
    let e = sh
        .frame(&FrameSettings::default_for(MethodKind::Vmf))
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("`sh` bake")
            && e.contains("--method vmf")
            && e.contains("relight bake --method vmf"),
        "{e}"
    );
    let e = load(&sh.to_bundle().unwrap(), Path::new("s.relight"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("s.relight") && e.contains("'sh' bake"), "{e}");
}

#[test]
fn parts_merge_to_the_whole_bake_byte_for_byte() {
    let whole = baked(false, None);
    let parts: Vec<Result<(PathBuf, Baked), MethodError>> = (0..3)
        .map(|index| {
            let p = baked(false, Some(Shard { index, count: 3 }));
            Ok((PathBuf::from(format!("p{index}.relight")), p))
        })
        .collect();
    // A part cannot be rendered.
    let refused = parts[1]
        .as_ref()
        .unwrap()
        .1
        .frame(&FrameSettings::default_for(MethodKind::Vmf))
        .is_err();
    assert!(refused);
    // Any order.
    let merged = merge(parts.into_iter().rev()).unwrap();
    assert_eq!(
        merged.to_bundle().unwrap().to_bytes(),
        whole.to_bundle().unwrap().to_bytes()
    );
}

#[test]
fn a_frame_through_the_seam_renders() {
    let b = baked(false, None);
    let mut frame = b
        .frame(&FrameSettings::default_for(MethodKind::Vmf))
        .unwrap();
    assert_eq!(frame.method(), MethodKind::Vmf);
    let env =
        relight_scene::scene::Environment::new(relight_sphere::EnvMap::constant(glam::Vec3::ONE));
    frame.set_environment(&env).unwrap();
    let camera = b.scene().desc.camera;
    let out = frame.render(&camera, &FrameOptions::default());
    assert_eq!(out.image.width, camera.width as usize);
    assert!(out
        .image
        .pixels
        .iter()
        .all(|p| p.is_finite() && p.min_element() >= 0.0));
    // Lambert surfaces under a unit sky: at most the albedo (0.8 red, with 32 paths of
    // noise per slice) plus one bounce, and lit.
    let max = out
        .image
        .pixels
        .iter()
        .map(|p| p.max_element())
        .fold(0.0, f32::max);
    assert!(max > 0.3 && max < 1.2, "{max}");
    assert!(
        frame.summary().contains("17.0 views per vertex"),
        "{}",
        frame.summary()
    );
    let bad = FrameSettings::Vmf(VmfFrameSettings {
        prefilter_size: 100,
    });
    assert!(b.frame(&bad).is_err());
}

#[test]
fn a_spatially_refined_bake_stores_its_mesh_renders_and_is_not_split() {
    let s = VmfBakeSettings {
        spatial_threshold: 0.05,
        spatial_min_area: 0.25,
        paths: 128,
        ..settings()
    };
    let (b, input_vertices) = with_input(0.5, |input| {
        let b: Baked = Vmf::bake(input, &s, 0..input.scene.mesh.vertex_count(), &ctx(false))
            .unwrap()
            .into();
        (b, input.scene.mesh.vertex_count())
    });
    let v = vmf(&b);
    assert!(v.scene.mesh.vertex_count() > input_vertices);
    assert_eq!(v.bake.vertex_count(), v.scene.mesh.vertex_count());
    assert_eq!(b.record().range, None);
    let back = round_trip(&b).unwrap();
    assert_eq!(back.scene().mesh.indices, v.scene.mesh.indices);
    assert_eq!(vmf(&back).bake, v.bake);
    let mut frame = back
        .frame(&FrameSettings::default_for(MethodKind::Vmf))
        .unwrap();
    let env =
        relight_scene::scene::Environment::new(relight_sphere::EnvMap::constant(glam::Vec3::ONE));
    frame.set_environment(&env).unwrap();
    let out = frame.render(&back.scene().desc.camera, &FrameOptions::default());
    assert!(out.image.pixels.iter().all(|p| p.is_finite()));
    let e = with_input(0.5, |input| {
        bake_part::<Vmf>(input, &s, Shard { index: 0, count: 2 }, &ctx(false))
            .expect_err("refused")
            .to_string()
    });
    assert!(e.contains("spatial") && e.contains("whole"), "{e}");
}
