//! Round trips and rejections of `sg` bundles on hand-made bakes (no baking needed), the
//! migration of bundles from before schema 2, and one small real bake through the seam.

use super::*;
use crate::store::BakeRecord;
use crate::{from_bundle, Baked, FrameSettings, MethodKind};
use relight_bake::sg::{SgFitStats, SgLobes};
use relight_bake::sh::{ShTransfer, ShTransferKind};
use relight_scene::scene_file::SceneDesc;
use relight_sphere::sg::SgLobe;
use relight_sphere::sg_kernel::LobeKernel;
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

const PLASTIC: Material = Material::GgxPlastic {
    diffuse: Vec3::splat(0.5),
    specular: Vec3::ONE,
    alpha: 0.3,
    ior: 1.5,
};

/// A random bake of a small sphere with 2 direct and 1 indirect lobes and per-vertex
/// materials.
fn baked(f16: bool) -> SgBaked {
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
    let materials = (0..v)
        .map(|x| match x % 3 {
            0 => PLASTIC,
            _ => Material::GgxPlastic {
                diffuse: Vec3::splat(0.5),
                specular: Vec3::ONE,
                alpha: 0.01 + x as f32 * 1e-3,
                ior: 1.5,
            },
        })
        .collect();
    let settings = SgSettings {
        bake: SgBakeSettings {
            direct_lobes: 2,
            indirect_lobes: 1,
            diffuse_order: 3,
            seed: 5,
            ..Default::default()
        },
        blend: Some(MaterialBlend {
            to: PLASTIC,
            axis: Vec3::Y,
        }),
    };
    SgBaked {
        part: None,
        scene: BakedScene {
            desc: scene(),
            mesh,
            materials: vec![PLASTIC],
            maps: Default::default(),
            objects: Vec::new(),
        },
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
            kernel: settings.bake.fit.lobe_kernel.kernel(),
            domain: settings.bake.fit.lobe_domain,
            horizon_deg: settings.bake.horizon_deg,
            lobe_order: settings.bake.fit.lobe_order,
        },
        settings,
        record: BakeRecord {
            backend: "bvh".into(),
            seconds: 0.0, // reported by the baker, never stored
            f16,
            range: None,
            shard: None,
        },
    }
}

/// Write to bytes and read back, as `write` + `read_any` do (minus the file).
fn round_trip(b: &Bundle) -> Result<SgBaked, MethodError> {
    let path = Path::new("mem.relight");
    let bytes = b.to_bytes();
    match from_bundle(&Bundle::from_bytes(path, &bytes)?, path)? {
        Baked::Sg(s) => Ok(s),
        other => panic!("read back as {:?}", other.kind()),
    }
}

#[test]
fn f32_bundle_round_trips_exactly() {
    let a = baked(false);
    let b = round_trip(&Sg::store(&a).unwrap()).unwrap();
    assert_eq!(a.bake.direct, b.bake.direct);
    assert_eq!(a.bake.indirect, b.bake.indirect);
    assert_eq!(a.bake.diffuse.data, b.bake.diffuse.data);
    assert_eq!(a.bake.materials, b.bake.materials);
    assert_eq!(a.bake.stats, b.bake.stats);
    assert_eq!(a.settings, b.settings);
    assert_eq!(a.record, b.record);
    assert_eq!(a.scene.materials, b.scene.materials);
    assert_eq!(a.scene.mesh.positions, b.scene.mesh.positions);
    assert_eq!(a.scene.mesh.indices, b.scene.mesh.indices);
    // 92 views x 3 lobes x 7 floats + 9 SH coefficients, 4 bytes each.
    assert_eq!(a.transfer_bytes_per_vertex(), 4 * (92 * 3 * 7 + 9));
    assert_eq!(b.bake.kernel, LobeKernel::Gaussian);
}

/// The lobe kernel is part of the bake's settings: a `--lobe-kernel ggx` bundle is read back
/// as one (its lobes are not Gaussians and must not be rendered as such).
#[test]
fn the_lobe_kernel_round_trips() {
    let mut a = baked(false);
    a.settings.bake.fit.lobe_kernel = relight_bake::sg::SgKernel::Ggx;
    a.bake.kernel = LobeKernel::Ggx;
    let b = round_trip(&Sg::store(&a).unwrap()).unwrap();
    assert_eq!(b.settings, a.settings);
    assert_eq!(b.bake.kernel, LobeKernel::Ggx);
}

/// So is the lobe domain: a `--lobe-domain half-vector` bundle is read back as one (its lobes
/// are functions of the half vector); older bundles read as the light domain.
#[test]
fn the_lobe_domain_round_trips() {
    let a = baked(false);
    assert_eq!(a.bake.domain, relight_bake::sg::SgDomain::Light);
    let mut a = a;
    a.settings.bake.fit.lobe_domain = relight_bake::sg::SgDomain::HalfVector;
    a.bake.domain = relight_bake::sg::SgDomain::HalfVector;
    let b = round_trip(&Sg::store(&a).unwrap()).unwrap();
    assert_eq!(b.settings, a.settings);
    assert_eq!(b.bake.domain, relight_bake::sg::SgDomain::HalfVector);
}

#[test]
fn f16_bundle_round_trips_within_half_precision() {
    let a = baked(true);
    let b = round_trip(&Sg::store(&a).unwrap()).unwrap();
    assert_eq!(a.transfer_bytes_per_vertex(), 2 * (92 * 3 * 7 + 9));
    // f16 keeps 11 significant bits: relative rounding error at most 2^-11.
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
fn bundles_from_before_the_seam_still_load() {
    // The layout written before schema 2: no `schema` or `record` keys; the settings flat,
    // with the fit's fields prefixed `fit_`, the record's fields mixed in and the blend as a
    // description. Tensor names and shapes are unchanged.
    let a = baked(false);
    let mut b = Sg::store(&a).unwrap();
    b.metadata.remove("schema");
    b.metadata.remove("record");
    b.metadata.insert(
        "settings".into(),
        r#"{"view_frequency":3,"direct_res":32,"indirect_res":8,"indirect_paths":64,
            "max_depth":3,"diffuse_order":3,"horizon_deg":5.0,"visibility":true,
            "direct_lobes":2,"indirect_lobes":1,"fit_max_iterations":30,"fit_mean_weight":0.01,
            "fit_width_weight":0.01,"fit_spatial_weight":0.01,"fit_relax_sweeps":0,
            "fit_regions":0,"fit_energy":true,"seed":5,
            "blend":"{\"type\": \"ggx_plastic\"} along 0,1,0","f16":false,"backend":"bvh",
            "seconds":1.5}"#
            .into(),
    );
    let old = round_trip(&b).unwrap();
    assert_eq!(old.settings.bake, a.settings.bake);
    assert_eq!(old.settings.blend, None, "the old description is dropped");
    // The old record's wall time is read (new bundles do not store it).
    assert_eq!(
        old.record,
        BakeRecord {
            seconds: 1.5,
            ..a.record.clone()
        }
    );
    assert_eq!(old.bake.direct, a.bake.direct);
    assert_eq!(old.bake.materials, a.bake.materials);
}

#[test]
fn corrupt_sg_bundles_are_rejected_with_a_clear_error() {
    let path = Path::new("bad.relight");
    let a = baked(false);
    // A flipped byte in the data section: the checksum says so.
    let mut bytes = Sg::store(&a).unwrap().to_bytes();
    let k = bytes.len() - 100;
    bytes[k] ^= 0x40;
    let e = Bundle::from_bytes(path, &bytes).unwrap_err().to_string();
    assert!(e.contains("bad.relight") && e.contains("checksum"), "{e}");
    // Valid checksums but inconsistent content: each error names the file and the problem.
    let check = |edit: &dyn Fn(&mut Bundle), want: &str| {
        let mut b = Sg::store(&a).unwrap();
        edit(&mut b);
        let e = from_bundle(&b, path).expect_err("rejected").to_string();
        assert!(e.contains("bad.relight") && e.contains(want), "{want}: {e}");
    };
    let put = |b: &mut Bundle, name: &str, at: usize, x: f32| {
        let t = b.tensors.get_mut(name).unwrap();
        t.bytes[4 * at..4 * at + 4].copy_from_slice(&x.to_le_bytes());
    };
    check(&|b| drop(b.tensors.remove("sg_direct")), "sg_direct");
    check(
        &|b| {
            let t = b.tensors.get_mut("sg_direct").unwrap();
            t.shape[2] = 1;
            t.bytes.truncate(t.bytes.len() / 2);
        },
        "shape",
    );
    check(&|b| put(b, "sg_indirect", 3, f32::NAN), "non-finite");
    check(&|b| put(b, "sg_direct", 3, -1.0), "sharpness");
    check(&|b| put(b, "sg_direct", 5, -2.0), "amplitude");
    check(&|b| put(b, "sg_direct", 0, 3.0), "axis length");
    check(
        &|b| drop(b.metadata.insert("sg_materials".into(), "[]".into())),
        "vertex material",
    );
    check(
        &|b| drop(b.metadata.insert("method".into(), "nonesuch".into())),
        "unknown bake method 'nonesuch'",
    );
}

#[test]
fn a_small_bake_through_the_seam_renders_and_refuses_other_methods() {
    let desc = scene();
    let s = desc.build(Path::new("<test>")).unwrap();
    let settings = SgSettings {
        bake: SgBakeSettings {
            direct_res: 4,
            indirect_lobes: 0,
            diffuse_order: 2,
            ..Default::default()
        },
        blend: None,
    };
    let input = crate::BakeInput {
        desc: &desc,
        scene: &s,
        origin: Path::new("<test>"),
    };
    let ctx = crate::BakeContext::default();
    let n = s.mesh.vertex_count();
    let e = Sg::bake(input, &settings, 0..n / 2, &ctx)
        .unwrap_err()
        .to_string();
    assert!(e.contains("whole mesh"), "{e}");
    let b: Baked = Sg::bake(input, &settings, 0..n, &ctx).unwrap().into();
    let mut frame = b
        .frame(&FrameSettings::default_for(MethodKind::Sg))
        .unwrap();
    frame.set_environment(&s.env).unwrap();
    let out = frame.render(&s.camera, &crate::FrameOptions::default());
    assert_eq!((out.image.width, out.image.height), (8, 8));
    // The centre pixel sees the sphere: lit, finite.
    let c = out.image.get(4, 4);
    assert!(c.is_finite() && c.max_element() > 0.0, "{c}");
    for m in [MethodKind::Sh, MethodKind::Hybrid] {
        let e = b
            .frame_of(&FrameSettings::default_for(m), Path::new("x.relight"))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("x.relight") && e.contains("holds a `sg` bake") && e.contains("--method sh"),
            "{e}"
        );
    }
}

#[test]
fn frame_settings_map_onto_the_renderers_interpolation() {
    use relight_render::shade_sg::{LobeBlend, ShadeOptions};
    // The default settings are the renderer's default, so `relight render` and the library
    // agree, in both lobe domains, for both lobe orders and any lobe count.
    use relight_bake::sg::{LobeOrder, SgBake, SgDomain};
    let bake = |domain, lobe_order, lobes| {
        let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 2, 4);
        let b = SgBake::from_fn(
            &mesh,
            lobes,
            |_, n, _, _| SgLobe {
                axis: n,
                sharpness: 10.0,
                amplitude: Vec3::ONE,
            },
            1,
            |_| vec![0.0],
            PLASTIC,
        );
        SgBake {
            domain,
            lobe_order,
            ..b
        }
    };
    for domain in [SgDomain::Light, SgDomain::HalfVector] {
        for order in [LobeOrder::Joint, LobeOrder::Nested, LobeOrder::Additive] {
            for lobes in [1, 2] {
                let b = bake(domain, order, lobes);
                assert_eq!(
                    SgFrameSettings::default().shade_options(&b),
                    ShadeOptions::default_for(domain, order, lobes)
                );
                assert_eq!(
                    ShadeOptions::for_bake(&b),
                    ShadeOptions::default_for(domain, order, lobes)
                );
            }
        }
    }
    for order in [LobeOrder::Joint, LobeOrder::Nested, LobeOrder::Additive] {
        assert_eq!(
            ShadeOptions::default_for(SgDomain::Light, order, 2),
            ShadeOptions::default()
        );
    }
    let joint = ShadeOptions::default_for(SgDomain::HalfVector, LobeOrder::Joint, 1);
    assert_eq!(
        (joint.corners, joint.match_views, joint.match_corners),
        (LobeBlend::Linear, true, true)
    );
    // One half-vector lobe: linear blends; nested ones: views by energy, slot by slot.
    assert_eq!(
        ShadeOptions::default_for(SgDomain::HalfVector, LobeOrder::Nested, 1),
        ShadeOptions::PAPER
    );
    assert_eq!(
        ShadeOptions::default_for(SgDomain::HalfVector, LobeOrder::Nested, 3),
        ShadeOptions::NESTED_HALF_VECTOR
    );
    // Additive ones: the first slot as one lobe is, the later ones' views by energy.
    let additive = ShadeOptions::default_for(SgDomain::HalfVector, LobeOrder::Additive, 2);
    assert_eq!(additive, ShadeOptions::ADDITIVE_HALF_VECTOR);
    assert_eq!(
        (
            additive.view_blend(0),
            additive.view_blend(1),
            additive.view_blend(2)
        ),
        (LobeBlend::Linear, LobeBlend::Energy, LobeBlend::Energy)
    );
    assert_eq!(
        ShadeOptions::default_for(SgDomain::HalfVector, LobeOrder::Additive, 1),
        ShadeOptions::PAPER
    );
    let paper = SgFrameSettings {
        view_blend: Some(SgViewBlend::Linear),
        corner_blend: Some(SgBlend::Linear),
        matching: Some(SgMatch::None),
        ..Default::default()
    };
    assert_eq!(
        paper.shade_options(&bake(SgDomain::Light, LobeOrder::Joint, 2)),
        ShadeOptions::PAPER
    );
    let o = SgFrameSettings {
        view_blend: Some(SgViewBlend::Energy),
        corner_blend: Some(SgBlend::Linear),
        matching: Some(SgMatch::Corners),
        ..Default::default()
    }
    .shade_options(&bake(SgDomain::HalfVector, LobeOrder::Nested, 2));
    assert_eq!(
        (
            o.views,
            o.later_views,
            o.match_views,
            o.corners,
            o.match_corners
        ),
        (
            LobeBlend::Energy,
            LobeBlend::Energy,
            false,
            LobeBlend::Linear,
            true
        )
    );
    let split = SgFrameSettings {
        view_blend: Some(SgViewBlend::Split),
        ..Default::default()
    }
    .shade_options(&bake(SgDomain::HalfVector, LobeOrder::Nested, 2));
    assert_eq!(
        (split.views, split.later_views),
        (LobeBlend::Linear, LobeBlend::Energy)
    );
}
