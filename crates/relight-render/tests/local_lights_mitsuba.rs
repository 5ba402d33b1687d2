//! relight's path tracer with a point and a spot light against Mitsuba 3 (`point` and
//! `spot` emitters, `path` integrator, max_depth 3: direct light and one bounce) in a small
//! closed room, black environment.
//!
//! The agreement measure and its bounds are the shared ones of `mitsuba_agreement.rs`
//! (`common::agreement`, `Agreement::holds`: `relRMSE <= 1.5 floor` and the mean difference
//! within 4 standard errors). Negative control: relight's render of the same room with a
//! slightly wrong light (moved 10 cm, or a spot's cone 5 degrees narrower) must fail that
//! check against the same Mitsuba render. SKIPS with a printed reason without Mitsuba
//! (`RELIGHT_MITSUBA_PYTHON`; `RELIGHT_REQUIRE_REFERENCE=1` makes that a failure).

mod common;
use common::{agreement, mitsuba_render_lit, object_mask};

use relight_render::light::{PointLight, Spot};
use relight_render::pathtrace::{render_with_lights, PtSettings};
use relight_scene::accel::build_default;
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::scene::{Environment, Scene};
use relight_scene::shapes::{aabb_box, coloured_room, uv_sphere};
use relight_scene::Vec3;
use relight_sphere::envmap::EnvMap;

/// A closed 2 x 2 x 2 room (walls facing in; left red, right green), a sphere and a box.
fn room() -> Scene {
    let div = 4;
    let mut mesh = coloured_room(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0), div);
    let mut sphere = uv_sphere(Vec3::new(-0.4, 0.35, -0.3), 0.35, 16, 32);
    sphere.material_ids = vec![0; sphere.indices.len()];
    mesh.append(&sphere, 0);
    let mut b = aabb_box(Vec3::new(0.1, 0.0, -0.2), Vec3::new(0.6, 0.6, 0.3), 1);
    b.material_ids = vec![0; b.indices.len()];
    mesh.append(&b, 0);
    Scene {
        maps: Default::default(),
        mesh,
        materials: vec![
            Material::Lambert {
                albedo: Vec3::splat(0.7),
            },
            Material::Lambert {
                albedo: Vec3::new(0.7, 0.15, 0.1),
            },
            Material::Lambert {
                albedo: Vec3::new(0.15, 0.6, 0.15),
            },
        ],
        env: Environment::new(EnvMap::constant(Vec3::ZERO)),
        camera: Camera::look_at([0.0, 1.0, 0.95], [0.0, 0.8, -1.0], 70.0, 32, 24),
        objects: Vec::new(),
    }
}

/// relight's path tracer with `light` agrees with Mitsuba's render of the room with it, and
/// with `wrong` it does not.
fn agree(name: &str, light: PointLight, wrong: PointLight) {
    let scene = room();
    let Some(m) = mitsuba_render_lit(name, &scene, 256, 3, &[light]) else {
        return;
    };
    let caster = build_default(&scene.mesh);
    let s = PtSettings {
        spp: 256,
        max_depth: 3,
        seed: 7,
        show_background: false,
        ..Default::default()
    };
    let mask = object_mask(&scene, caster.as_ref());
    assert!(
        mask.iter().all(|&m| m),
        "the room is closed: every pixel sees a wall"
    );
    let (r, var_r) = render_with_lights(&scene, caster.as_ref(), &s, &[light]);
    let ag = agreement(&r, &var_r, &m.mean, &m.var, &mask);
    println!(
        "{name}: relRMSE {:.4}, floor {:.4}, mean {:.2} sigma ({})",
        ag.rel_rmse, ag.floor, ag.bias_sigmas, m.report
    );
    assert!(
        ag.holds(),
        "{name}: relRMSE {} (floor {}), mean difference {} standard errors",
        ag.rel_rmse,
        ag.floor,
        ag.bias_sigmas
    );
    let (r, var_r) = render_with_lights(&scene, caster.as_ref(), &s, &[wrong]);
    let bad = agreement(&r, &var_r, &m.mean, &m.var, &mask);
    println!(
        "{name}, control (wrong light): relRMSE {:.4}, floor {:.4}, mean {:.2} sigma",
        bad.rel_rmse, bad.floor, bad.bias_sigmas
    );
    assert!(
        !bad.holds(),
        "{name}: the wrong light passes (relRMSE {}, floor {}, {} sigma): the check cannot see it",
        bad.rel_rmse,
        bad.floor,
        bad.bias_sigmas
    );
}

#[test]
fn point_light_one_bounce_matches_mitsuba() {
    let light = PointLight::new(Vec3::new(0.2, 1.7, 0.1), Vec3::splat(2.0));
    let wrong = PointLight {
        position: light.position + Vec3::new(0.1, 0.0, 0.0),
        ..light
    };
    agree("point", light, wrong);
}

#[test]
fn spot_light_one_bounce_matches_mitsuba() {
    let light = PointLight {
        position: Vec3::new(0.0, 1.9, 0.2),
        intensity: Vec3::new(6.0, 5.0, 4.0),
        spot: Some(Spot {
            direction: Vec3::new(0.1, -1.0, -0.4).normalize(),
            cutoff_deg: 35.0,
        }),
    };
    let wrong = PointLight {
        spot: Some(Spot {
            cutoff_deg: 30.0,
            ..light.spot.unwrap()
        }),
        ..light
    };
    agree("spot", light, wrong);
}
