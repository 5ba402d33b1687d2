//! relight's path tracer with a point and a spot light against Mitsuba 3 (`point` and
//! `spot` emitters, `path` integrator, max_depth 3: direct light and one bounce) in a small
//! closed room, black environment.
//!
//! The agreement measure is that of `mitsuba_agreement.rs`: `relRMSE = sqrt(Σ (r - m)^2 /
//! Σ m^2)` against the noise floor `sqrt(Σ (var_r + var_m) / Σ m^2)` (relight's variance of
//! the mean, Mitsuba's from two seeds), asserted `relRMSE <= 1.5 floor` (room for the
//! variance estimates; a systematic difference of 1.1 x the floor fails), and the mean
//! difference within 4 standard errors. SKIPS with a printed reason without Mitsuba
//! (`RELIGHT_MITSUBA_PYTHON`; `RELIGHT_REQUIRE_REFERENCE=1` makes that a failure).

use relight_render::light::{PointLight, Spot};
use relight_render::mitsuba::{export_mitsuba_lit, mitsuba_python, render_mitsuba};
use relight_render::pathtrace::{render_with_lights, PtSettings};
use relight_render::Image;
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
    }
}

fn agree(name: &str, light: PointLight) {
    let python = match mitsuba_python() {
        Ok(p) => p,
        Err(e) => {
            relight_testdata::skip(&format!("Mitsuba comparison {name}: {e}"));
            return;
        }
    };
    let scene = room();
    let caster = build_default(&scene.mesh);
    let s = PtSettings {
        spp: 256,
        max_depth: 3,
        seed: 7,
        show_background: false,
        ..Default::default()
    };
    let (r, var_r) = render_with_lights(&scene, caster.as_ref(), &s, &[light]);
    let dir = std::env::temp_dir().join(format!("relight-local-{name}-{}", std::process::id()));
    let json = export_mitsuba_lit(&scene, &dir, 256, 3, &[light]).expect("export");
    let (imgs, report) =
        render_mitsuba(&python, &json, &dir.join("mitsuba"), &[1, 2], None).expect("mitsuba");
    let _ = std::fs::remove_dir_all(&dir);
    let (a, b): (&Image, &Image) = (&imgs[0], &imgs[1]);
    let (mut d2, mut m2, mut floor2, mut diff, mut var_sum) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for i in 0..r.pixels.len() {
        let m = (a.pixels[i] + b.pixels[i]) * 0.5;
        let vm = (a.pixels[i] - b.pixels[i]) * (a.pixels[i] - b.pixels[i]) * 0.25;
        for c in 0..3 {
            let (rc, mc) = (r.pixels[i][c] as f64, m[c] as f64);
            d2 += (rc - mc) * (rc - mc);
            m2 += mc * mc;
            floor2 += var_r.pixels[i][c] as f64 + vm[c] as f64;
            diff += rc - mc;
            var_sum += var_r.pixels[i][c] as f64 + vm[c] as f64;
        }
    }
    let (rel, floor) = ((d2 / m2).sqrt(), (floor2 / m2).sqrt());
    let sigmas = diff.abs() / var_sum.sqrt();
    println!("{name}: relRMSE {rel:.4}, floor {floor:.4}, mean {sigmas:.2} sigma ({report})");
    assert!(
        rel <= 1.5 * floor,
        "{name}: relRMSE {rel} > 1.5 x floor {floor}"
    );
    assert!(
        sigmas < 4.0,
        "{name}: mean difference {sigmas} standard errors"
    );
}

#[test]
fn point_light_one_bounce_matches_mitsuba() {
    agree(
        "point",
        PointLight::new(Vec3::new(0.2, 1.7, 0.1), Vec3::splat(2.0)),
    );
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
    agree("spot", light);
}
