//! A bake of surface samples through the seam: round trip, the layout version, and the
//! frame's refusals (environment bundle with a point light and the reverse, a lit
//! environment, a light inside geometry) and a light moved at run time.

use super::local::PointLightArgs;
use super::*;
use crate::test_scene::with_input;
use crate::{Frame, FrameOptions, MethodError};
use glam::Vec3;
use relight_bake::cuts::bake_range;
use relight_bundle::Bundle;
use relight_render::light::PointLight;
use relight_scene::accel::{build, Backend};
use relight_scene::scene::Environment;
use relight_sphere::EnvMap;
use std::path::Path;

fn baked(samples: LightSampleKind) -> CutsBaked {
    with_input(0.5, |input| {
        let caster = build(&input.scene.mesh, Backend::Bvh).unwrap();
        let settings = CutsBakeSettings {
            lights: 512,
            samples,
            seed: 2,
            ..Default::default()
        };
        let n = input.scene.mesh.vertex_count();
        let bake = bake_range(&input.scene.mesh, caster.as_ref(), &settings, 0..n).unwrap();
        CutsBaked {
            scene: BakedScene::of(&input),
            bake,
            settings,
            record: BakeRecord::new("bvh", 0.0, false, &(0..n), n),
        }
    })
}

fn load_bytes(bytes: &[u8]) -> Result<CutsBaked, MethodError> {
    load(
        &Bundle::from_bytes(Path::new("x.relight"), bytes)?,
        Path::new("x.relight"),
    )
}

fn light_settings(p: Vec3) -> CutsFrameSettings {
    CutsFrameSettings {
        light: PointLightArgs {
            point_light: Some(p),
            light_intensity: Some(Vec3::splat(3.0)),
            ..Default::default()
        },
        ..Default::default()
    }
}

fn black() -> Environment {
    Environment::new(EnvMap::constant(Vec3::ZERO))
}

/// A point above the scene's objects (the test scene: objects around the origin).
fn above(b: &CutsBaked) -> Vec3 {
    let (lo, hi) = b.scene.mesh.bounds().unwrap();
    Vec3::new(
        (lo.x + hi.x) * 0.5 + 0.1,
        hi.y + 1.0,
        (lo.z + hi.z) * 0.5 - 0.1,
    )
}

#[test]
fn surface_bake_round_trips_exactly_with_its_version() {
    let b = baked(LightSampleKind::Surface);
    b.validate().unwrap();
    let bundle = store(&b).unwrap();
    assert_eq!(bundle.metadata["cuts_version"], "2");
    assert!(bundle.tensors.contains_key("cuts_positions"));
    assert!(!bundle.tensors.contains_key("cuts_dirs"));
    let back = load_bytes(&bundle.to_bytes()).unwrap();
    assert_eq!(back.bake, b.bake);
    assert_eq!(back.settings, b.settings);
}

#[test]
fn layout_versions_are_checked() {
    // A bundle of an older relight (no version key, no `samples` in the settings) loads as
    // an environment bake.
    let env = baked(LightSampleKind::Environment);
    let mut old = store(&env).unwrap();
    old.metadata.remove("cuts_version");
    let settings = old.metadata["settings"].replace("\"samples\":\"environment\",", "");
    assert!(!settings.contains("samples"), "{settings}");
    old.metadata.insert("settings".into(), settings);
    let back = load_bytes(&old.to_bytes()).unwrap();
    assert_eq!(back.settings.samples, LightSampleKind::Environment);
    // A newer layout is refused by name.
    let mut newer = store(&env).unwrap();
    newer.metadata.insert("cuts_version".into(), "3".into());
    let e = load_bytes(&newer.to_bytes()).unwrap_err().to_string();
    assert!(e.contains("x.relight") && e.contains("version 3"), "{e}");
    // Surface settings without the surface tensors: the missing tensor is named.
    let mut broken = store(&baked(LightSampleKind::Surface)).unwrap();
    broken.tensors.remove("cuts_areas");
    let e = load_bytes(&broken.to_bytes()).unwrap_err().to_string();
    assert!(e.contains("cuts_areas"), "{e}");
}

#[test]
fn frames_refuse_mismatched_lighting_by_name() {
    let env = baked(LightSampleKind::Environment);
    let local = baked(LightSampleKind::Surface);
    let p = above(&local);
    let e = CutsFrame::new(&env, &light_settings(p))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("--point-light needs a bake of surface samples"),
        "{e}"
    );
    let e = CutsFrame::new(&local, &CutsFrameSettings::default())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("give --point-light"), "{e}");
    let mut frame = CutsFrame::new(&local, &light_settings(p)).unwrap();
    let lit = Environment::new(EnvMap::constant(Vec3::ONE));
    let e = frame.set_environment(&lit).unwrap_err().to_string();
    assert!(e.contains("must be black"), "{e}");
    // Far below everything and inside nothing is fine; at a NaN it is not.
    let nan = PointLight::new(Vec3::new(0.0, f32::NAN, 0.0), Vec3::ONE);
    let e = frame.set_point_light(nan).unwrap_err().to_string();
    assert!(e.contains("position"), "{e}");
    let zero = CutsFrameSettings {
        light: PointLightArgs {
            light_intensity: Some(Vec3::ZERO),
            ..light_settings(p).light
        },
        ..Default::default()
    };
    assert!(CutsFrame::new(&local, &zero).is_err());
}

#[test]
fn moving_the_light_changes_the_frame() {
    let local = baked(LightSampleKind::Surface);
    let p = above(&local);
    let mut frame = CutsFrame::new(&local, &light_settings(p)).unwrap();
    frame.set_environment(&black()).unwrap();
    let (lo, hi) = local.scene.mesh.bounds().unwrap();
    let (c, size) = ((lo + hi) * 0.5, (hi - lo).length());
    let cam = relight_scene::camera::Camera::look_at(
        (c + Vec3::new(0.2, 0.8, 1.2) * size).to_array(),
        c.to_array(),
        40.0,
        32,
        24,
    );
    let opts = FrameOptions {
        supersample: 1,
        background: false,
    };
    let a = frame.render(&cam, &opts).image;
    frame
        .set_point_light(PointLight::new(
            p + Vec3::new(1.5, 0.0, 1.0),
            Vec3::splat(3.0),
        ))
        .unwrap();
    let b = frame.render(&cam, &opts).image;
    let sum = |i: &relight_render::Image| i.pixels.iter().map(|p| p.x as f64).sum::<f64>();
    assert!(sum(&a) > 0.0 && sum(&b) > 0.0);
    let diff: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(x, y)| (x.x - y.x).abs() as f64)
        .sum();
    assert!(
        diff > 0.05 * sum(&a),
        "moving the light changed {diff} of {}",
        sum(&a)
    );
    assert!(frame.summary().contains("local light"));
}
