//! relight's reference path tracer against Mitsuba 3 (and against closed forms).
//!
//! Each comparison renders a small scene with relight (per-pixel variance of the mean from
//! the sample variance) and with Mitsuba 3 twice (seeds 1 and 2, same spp; Mitsuba's estimate
//! is their mean, its per-pixel variance `(A - B)^2 / 4`). Over the object pixels (pixel
//! centre hits geometry) and all channels:
//!
//! * `relRMSE = sqrt(Σ (r - m)^2 / Σ m^2)`,
//! * noise floor `sqrt(Σ (var_r + var_m) / Σ m^2)`: the relRMSE two independent unbiased
//!   estimates of the same image have in expectation.
//!
//! With thousands of terms the sum of squared differences concentrates within a few percent
//! of its expectation, so for unbiased renderers `relRMSE / floor` is close to 1. We assert
//! `relRMSE <= K * floor` with `K = 1.5`: it leaves room for the per-pixel variance estimates
//! (heavy-tailed for environment lighting, so the floor is itself uncertain by ~10-20%) and
//! fails on a systematic difference as small as `1.1 x` the noise floor (`sqrt(1.5^2 - 1)`).
//! A second check is on the mean: `|Σ(r - m)| / Σ m` within 4 standard errors.
//!
//! Mitsuba comparisons SKIP (with a printed reason) when no Python with `mitsuba` is found
//! (`RELIGHT_MITSUBA_PYTHON` or `/root/.cache/relight/venv/bin/python`); tests on shared data
//! skip when `../shared` is absent. `RELIGHT_RESULTS_TABLE=path` appends each comparison as a
//! markdown table row (used to write docs/RESULTS-pathtracer.md).

use relight_render::pathtrace::{render_with_variance, PtSettings};
use relight_render::Image;
use relight_scene::accel::{build_default, Ray};
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::{Environment, Scene};
use relight_scene::shapes::{ground_plane, uv_sphere};
use relight_scene::Vec3;
use relight_sphere::envmap::{EnvLayout, EnvMap};
use std::io::Write;
use std::path::PathBuf;

mod common;
use common::{agreement, mitsuba_render, object_mask, MitsubaResult, K};

/// A smooth unit-radius sphere (UV sphere, exact normals) with material `mat`.
fn sphere(center: Vec3, radius: f32, mat: u32) -> TriMesh {
    let mut m = uv_sphere(center, radius, 48, 96);
    m.material_ids = vec![mat; m.indices.len()];
    m
}

fn camera(origin: [f32; 3], target: [f32; 3], fov: f32, size: u32) -> Camera {
    Camera {
        origin,
        target,
        up: [0.0, 1.0, 0.0],
        fov_deg: fov,
        width: size,
        height: size,
    }
}

/// One sphere at the origin seen from +Z.
fn sphere_scene(material: Material, env: EnvMap, size: u32) -> Scene {
    Scene {
        maps: Default::default(),
        mesh: sphere(Vec3::ZERO, 1.0, 0),
        materials: vec![material],
        env: Environment::new(env),
        camera: camera([0.0, 0.0, 3.2], [0.0; 3], 45.0, size),
        objects: Vec::new(),
    }
}

/// A sphere (material 0) resting on a ground square (material 1), seen from above the front.
fn sphere_on_ground(
    sphere_mat: Material,
    ground_mat: Material,
    env: Environment,
    size: u32,
) -> Scene {
    let mut mesh = sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, 0);
    let mut ground = ground_plane(Vec3::ZERO, 6.0, 4);
    ground.material_ids = vec![1; ground.indices.len()];
    mesh.append(&ground, 0);
    Scene {
        maps: Default::default(),
        mesh,
        materials: vec![sphere_mat, ground_mat],
        env,
        camera: camera([0.0, 2.6, 4.6], [0.0, 0.7, 0.0], 50.0, size),
        objects: Vec::new(),
    }
}

/// Append a result row to `$RELIGHT_RESULTS_TABLE` if set.
fn record(row: &str) {
    if let Some(path) = std::env::var_os("RELIGHT_RESULTS_TABLE") {
        if let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(PathBuf::from(path))
        {
            let _ = writeln!(f, "{row}");
        }
    }
}

/// Render `scene` with relight and Mitsuba, report and assert agreement. Returns relight's
/// image, its variance and Mitsuba's result (for extra checks), or `None` when skipped.
fn compare(
    name: &str,
    scene: &Scene,
    spp_relight: u32,
    spp_mitsuba: u32,
    max_depth: i32,
) -> Option<(Image, Image, MitsubaResult)> {
    let caster = build_default(&scene.mesh);
    let t0 = std::time::Instant::now();
    let s = PtSettings {
        spp: spp_relight,
        max_depth,
        seed: 7,
        ..Default::default()
    };
    let (img, var) = render_with_variance(scene, caster.as_ref(), &s);
    let t_relight = t0.elapsed().as_secs_f64();
    let m = mitsuba_render(name, scene, spp_mitsuba, max_depth)?;
    let mask = object_mask(scene, caster.as_ref());
    let ag = agreement(&img, &var, &m.mean, &m.var, &mask);
    // Separate floors: each renderer's own relative noise.
    let zero = Image::new(img.width, img.height);
    let floor_r = agreement(&img, &var, &m.mean, &zero, &mask).floor;
    let floor_m = agreement(&m.mean, &m.var, &m.mean, &zero, &mask).floor;
    let row = format!(
        "| {name} | {}x{} | {max_depth} | {spp_relight} | {} x2 | {:.4} | {:.4} | {:.4} | {:.4} | {:.2} | {:.1} | {t_relight:.1} s / {} |",
        img.width, img.height, spp_mitsuba, ag.rel_rmse, floor_r, floor_m, ag.floor, ag.rel_rmse / ag.floor, ag.bias_sigmas, m.report
    );
    println!("{row}");
    record(&row);
    assert!(
        ag.rel_rmse <= K * ag.floor,
        "{name}: relRMSE {} > {K} x floor {}",
        ag.rel_rmse,
        ag.floor
    );
    // The mean difference over all object pixels: 4 standard errors (1 in 15 000 by chance).
    assert!(
        ag.bias_sigmas < 4.0,
        "{name}: mean difference {} standard errors",
        ag.bias_sigmas
    );
    Some((img, var, m))
}

/// Radiance 8 inside the octant x > 0, y > 0, z < 0 and 0.05 elsewhere.
fn octant_env(sx: f32, sy: f32, sz: f32) -> EnvMap {
    EnvMap::latlong_from_fn(128, 65, move |d| {
        if sx * d.x > 0.0 && sy * d.y > 0.0 && sz * d.z < 0.0 {
            Vec3::new(8.0, 6.0, 4.0)
        } else {
            Vec3::splat(0.05)
        }
    })
}

#[test]
fn octant_environment_orientation_matches_mitsuba() {
    // Camera on +Z looking at a diffuse sphere: the upper right of the sphere faces the octant
    // partly (normals with x > 0, y > 0 see directions with z < 0 near the silhouette).
    let mat = Material::Lambert {
        albedo: Vec3::splat(0.8),
    };
    let mut scene = sphere_scene(mat, octant_env(1.0, 1.0, 1.0), 64);
    // View from the side of the octant so that it lights most of the visible hemisphere.
    scene.camera.origin = [2.0, 1.2, -2.0];
    let Some((_, _, m)) = compare("octant diffuse", &scene, 512, 256, 2) else {
        return;
    };
    // The same comparison must fail for mirrored environments (the test can fail).
    let caster = build_default(&scene.mesh);
    let mask = object_mask(&scene, caster.as_ref());
    for (label, env) in [
        ("mirror x", octant_env(-1.0, 1.0, 1.0)),
        ("mirror z", octant_env(1.0, 1.0, -1.0)),
        ("rotated 90", octant_env(1.0, 1.0, 1.0)),
    ] {
        let mut mirrored = scene.clone();
        mirrored.env = Environment::new(env);
        if label == "rotated 90" {
            mirrored.env.rotate_y_deg = 90.0;
        }
        let s = PtSettings {
            spp: 64,
            max_depth: 2,
            seed: 7,
            ..Default::default()
        };
        let (img, var_m) = render_with_variance(&mirrored, caster.as_ref(), &s);
        let ag = agreement(&img, &var_m, &m.mean, &m.var, &mask);
        println!("{label}: relRMSE {:.3} floor {:.4}", ag.rel_rmse, ag.floor);
        assert!(
            ag.rel_rmse > 10.0 * ag.floor && ag.rel_rmse > 0.2,
            "{label} is not distinguished: {} vs floor {}",
            ag.rel_rmse,
            ag.floor
        );
    }
}

#[test]
fn rotated_environment_matches_mitsuba() {
    // Same octant map, rotated about +Y and scaled: checks `rotate_y_deg` and `scale`.
    let mat = Material::Lambert {
        albedo: Vec3::splat(0.8),
    };
    let mut scene = sphere_scene(mat, octant_env(1.0, 1.0, 1.0), 48);
    scene.env.rotate_y_deg = 130.0;
    scene.env.scale = 0.5;
    compare("octant rotated 130 deg, scale 0.5", &scene, 256, 128, 2);
}

#[test]
fn furnace_diffuse_sphere_is_albedo_times_radiance() {
    // Convex sphere, constant environment L, direct only: every pixel covered by the sphere is
    // exactly a * L (closed form), whatever the sampling.
    let (a, l) = (Vec3::new(0.9, 0.7, 0.5), 1.5f32);
    let scene = sphere_scene(
        Material::Lambert { albedo: a },
        EnvMap::constant(Vec3::splat(l)),
        48,
    );
    let caster = build_default(&scene.mesh);
    let s = PtSettings {
        spp: 64,
        max_depth: 2,
        seed: 1,
        ..Default::default()
    };
    let (img, var) = render_with_variance(&scene, caster.as_ref(), &s);
    // Interior pixels: the whole pixel square is on the sphere (corners and centre hit).
    let f = scene.camera.frame();
    let hits = |x: f32, y: f32| {
        caster
            .intersect(&Ray::new(f.origin, f.dir_at(x, y), 0.0, f32::INFINITY))
            .is_some()
    };
    let (mut n, mut worst) = (0, 0.0f32);
    for y in 0..img.height {
        for x in 0..img.width {
            let (xf, yf) = (x as f32, y as f32);
            if ![(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
                .iter()
                .all(|(dx, dy)| hits(xf + dx, yf + dy))
            {
                continue;
            }
            n += 1;
            let p = img.get(x, y);
            let sd = var.get(x, y).powf(0.5);
            // 5 standard errors per pixel and channel, plus float rounding.
            let err = ((p - a * l).abs() - sd * 5.0).max_element();
            worst = worst.max(err);
            assert!(
                err <= 1e-4 * l,
                "pixel ({x}, {y}) = {p}, want {} +- {}",
                a * l,
                sd
            );
        }
    }
    assert!(n > 500, "only {n} interior pixels");
    println!("furnace: {n} interior pixels within 5 sigma of a*L (worst excess {worst:e})");
    compare("furnace diffuse (constant env)", &scene, 64, 64, 2);
}

/// `OrientationLatLong.exr` from the shared data, as a latlong map (`None`: skip).
fn orientation_env() -> Option<EnvMap> {
    let p = relight_testdata::shared_file("data/envmaps/exr/OrientationLatLong.exr")?;
    Some(
        relight_scene::io::env::load_env(&p, Some(EnvLayout::LatLong))
            .expect("load OrientationLatLong"),
    )
}

#[test]
fn orientation_map_diffuse_matches_mitsuba() {
    let Some(env) = orientation_env() else { return };
    let scene = sphere_scene(
        Material::Lambert {
            albedo: Vec3::splat(0.8),
        },
        env,
        64,
    );
    compare("OrientationLatLong diffuse", &scene, 256, 128, 2);
}

#[test]
fn orientation_map_mirror_like_conductor_matches_mitsuba() {
    let Some(env) = orientation_env() else { return };
    let scene = sphere_scene(
        Material::GgxConductor {
            specular: Vec3::splat(0.9),
            alpha: 0.05,
        },
        env,
        64,
    );
    compare(
        "OrientationLatLong GGX conductor a=0.05",
        &scene,
        256,
        128,
        2,
    );
}

/// The Grace Cathedral probe (256 x 128 latlong) from the shared data (`None`: skip).
fn grace() -> Option<Environment> {
    let p = relight_testdata::shared_file("data/envmaps/debevec_latlong_256x128/grace.hdr")?;
    Some(Environment::new(
        relight_scene::io::env::load_env(&p, Some(EnvLayout::LatLong)).expect("load grace"),
    ))
}

fn grace_diffuse_scene() -> Option<Scene> {
    let env = grace()?;
    let d = Material::Lambert {
        albedo: Vec3::new(0.8, 0.7, 0.6),
    };
    Some(sphere_on_ground(
        d,
        Material::Lambert {
            albedo: Vec3::splat(0.5),
        },
        env,
        64,
    ))
}

#[test]
fn grace_diffuse_direct_matches_mitsuba() {
    let Some(scene) = grace_diffuse_scene() else {
        return;
    };
    compare("grace diffuse, direct", &scene, 512, 256, 2);
}

#[test]
fn grace_diffuse_interreflections_match_mitsuba() {
    let Some(scene) = grace_diffuse_scene() else {
        return;
    };
    let Some((_, _, m)) = compare("grace diffuse, max_depth 4", &scene, 512, 256, 4) else {
        return;
    };
    // The comparison sees the interreflections: relight's direct-only image is darker than
    // Mitsuba's max_depth-4 image by many standard errors of the mean difference (per pixel
    // the bounce light is below the noise of these small renders, in the mean it is not).
    let caster = build_default(&scene.mesh);
    let s = PtSettings {
        spp: 128,
        max_depth: 2,
        seed: 9,
        ..Default::default()
    };
    let (direct, var) = render_with_variance(&scene, caster.as_ref(), &s);
    let ag = agreement(
        &direct,
        &var,
        &m.mean,
        &m.var,
        &object_mask(&scene, caster.as_ref()),
    );
    println!(
        "direct-only vs max_depth 4: relRMSE {:.4} = {:.1} x floor, mean difference {:.1} standard errors",
        ag.rel_rmse,
        ag.rel_rmse / ag.floor,
        ag.bias_sigmas
    );
    assert!(
        ag.bias_sigmas > 10.0,
        "interreflections are lost in the noise: {}",
        ag.bias_sigmas
    );
    // Unlimited depth: Russian roulette (from depth 5, as Mitsuba) in both renderers.
    compare("grace diffuse, max_depth -1", &scene, 512, 256, -1);
}

#[test]
fn grace_glossy_matches_mitsuba() {
    let Some(env) = grace() else { return };
    let g = Material::GgxConductor {
        specular: Vec3::new(0.95, 0.8, 0.5),
        alpha: 0.2,
    };
    let p = Material::GgxPlastic {
        diffuse: Vec3::new(0.2, 0.4, 0.6),
        specular: Vec3::ONE,
        alpha: 0.3,
        ior: 1.49,
    };
    let scene = sphere_on_ground(g, p, env, 64);
    compare(
        "grace GGX conductor a=0.2 on GGX plastic a=0.3, max_depth 3",
        &scene,
        512,
        256,
        3,
    );
}

#[test]
fn variance_images_predict_seed_to_seed_differences() {
    // The noise floors above come from the variance images: check them against the actual
    // difference of two independent relight renders (no Mitsuba needed). Expected ratio 1;
    // the sum over ~12 000 terms concentrates within a few percent, the variance estimates
    // themselves are heavy-tailed under a high-contrast environment: accept [0.8, 1.25].
    let mat = Material::GgxPlastic {
        diffuse: Vec3::new(0.6, 0.4, 0.2),
        specular: Vec3::ONE,
        alpha: 0.15,
        ior: 1.49,
    };
    let scene = sphere_scene(mat, octant_env(1.0, 1.0, 1.0), 64);
    let caster = build_default(&scene.mesh);
    let mask = object_mask(&scene, caster.as_ref());
    let s = PtSettings {
        spp: 256,
        max_depth: 3,
        seed: 1,
        ..Default::default()
    };
    let (a, va) = render_with_variance(&scene, caster.as_ref(), &s);
    let (b, vb) = render_with_variance(&scene, caster.as_ref(), &PtSettings { seed: 1 + 1, ..s });
    let ag = agreement(&a, &va, &b, &vb, &mask);
    println!(
        "seed 1 vs seed 2: relRMSE {:.4}, floor {:.4}, ratio {:.3}",
        ag.rel_rmse,
        ag.floor,
        ag.rel_rmse / ag.floor
    );
    assert!(
        (0.8..1.25).contains(&(ag.rel_rmse / ag.floor)),
        "{}",
        ag.rel_rmse / ag.floor
    );
    assert!(ag.bias_sigmas < 4.0);
}
