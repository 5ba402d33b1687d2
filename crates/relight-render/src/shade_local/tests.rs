//! Local lighting against closed forms and the path tracer on a small closed room.

use super::*;
use crate::compare::metrics;
use crate::image::Image;
use crate::pathtrace::{render_with_lights, PtSettings};
use relight_bake::cuts::{bake_range, CutsBakeSettings, LightSampleKind};
use relight_scene::accel::{build, Backend};
use relight_scene::scene::{Environment, Scene};
use relight_scene::shapes::{aabb_box, coloured_room, ground_plane, uv_sphere};
use relight_sphere::EnvMap;

/// Divisions of each room wall (quads per side).
const WALL_DIV: u32 = 6;

/// A closed 2 x 2 x 2 room (walls facing in: left red, right green, the rest white), a
/// sphere and a box inside; materials 0-2 are white, red, green.
fn room() -> (TriMesh, Vec<Material>) {
    let walls = coloured_room(
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 2.0, 1.0),
        WALL_DIV,
    );
    let mut mesh = walls;
    mesh.append(&uv_sphere(Vec3::new(-0.4, 0.35, -0.3), 0.35, 10, 20), 0);
    mesh.append(
        &aabb_box(Vec3::new(0.1, 0.0, -0.2), Vec3::new(0.6, 0.6, 0.3), 2),
        0,
    );
    let materials = vec![
        Material::Lambert {
            albedo: Vec3::splat(0.7),
        },
        Material::Lambert {
            albedo: Vec3::new(0.7, 0.15, 0.1),
        },
        Material::Lambert {
            albedo: Vec3::new(0.15, 0.6, 0.15),
        },
    ];
    (mesh, materials)
}

fn camera() -> Camera {
    Camera::look_at([0.0, 1.0, 0.95], [0.0, 0.8, -1.0], 70.0, 40, 30)
}

fn light_at(p: Vec3) -> PointLight {
    PointLight::new(p, Vec3::splat(1.5))
}

struct Fixture {
    mesh: TriMesh,
    materials: Vec<Material>,
    /// The path tracer's maps ([`reference`]).
    maps: SceneMaps,
    bake: CutsBake,
    caster: Box<dyn RayCaster>,
}

fn fixture(function: CutFunction) -> Fixture {
    let (mesh, materials) = room();
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let settings = CutsBakeSettings {
        lights: 4096,
        samples: LightSampleKind::Surface,
        function,
        ..Default::default()
    };
    let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count()).unwrap();
    bake.validate().unwrap();
    bake.surface.as_ref().unwrap().validate(&mesh).unwrap();
    Fixture {
        mesh,
        materials,
        maps: SceneMaps::default(),
        bake,
        caster,
    }
}

fn reference(f: &Fixture, light: PointLight, max_depth: i32, spp: u32) -> (Image, f64) {
    let scene = Scene {
        maps: f.maps.clone(),
        mesh: f.mesh.clone(),
        materials: f.materials.clone(),
        env: Environment::new(EnvMap::constant(Vec3::ZERO)),
        camera: camera(),
        objects: Vec::new(),
    };
    let s = PtSettings {
        spp,
        max_depth,
        seed: 7,
        threads: None,
        show_background: false,
        progress: false,
    };
    let (img, var) = render_with_lights(&scene, f.caster.as_ref(), &s, &[light]);
    // Relative noise of the mean image: sqrt(mean var) / sqrt(mean b^2), channels pooled.
    let v: f64 = var
        .pixels
        .iter()
        .map(|p| p.x as f64 + p.y as f64 + p.z as f64)
        .sum();
    let b2: f64 = img
        .pixels
        .iter()
        .map(|p| (p.x * p.x + p.y * p.y + p.z * p.z) as f64)
        .sum();
    (img, (v / b2).sqrt())
}

#[test]
fn direct_light_on_an_open_plane_is_the_closed_form() {
    // A white Lambert plane, nothing above: radiance albedo / pi * I cos / d^2 exactly.
    let mesh = ground_plane(Vec3::ZERO, 4.0, 4);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let settings = CutsBakeSettings {
        lights: 256,
        samples: LightSampleKind::Surface,
        ..Default::default()
    };
    let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count()).unwrap();
    let albedo = Vec3::new(0.8, 0.5, 0.2);
    let shader = LocalShader::new(
        &mesh,
        vec![Material::Lambert { albedo }],
        &bake,
        CutFunction::Visibility,
        caster.as_ref(),
    )
    .unwrap();
    let light = PointLight::new(Vec3::new(0.4, 1.5, -0.2), Vec3::new(2.0, 1.0, 3.0));
    let l = shader.prepare(light, 2.0, 64).unwrap();
    let eye = Vec3::new(0.0, 3.0, 3.0);
    for x in [
        Vec3::ZERO,
        Vec3::new(1.2, 0.0, 0.9),
        Vec3::new(-1.7, 0.0, -1.1),
    ] {
        let f = Fragment {
            tri: 0,
            bary: [1.0, 0.0, 0.0],
            position: x,
            shading_normal: Vec3::Y,
            geometric_normal: Vec3::Y,
        };
        let got = shader.shade_fragment(&l, &f, eye, Terms::ALL);
        let to = light.position - x;
        let expect = albedo * std::f32::consts::FRAC_1_PI * light.intensity * (to.y / to.length())
            / to.length_squared();
        // The plane lights nothing of itself (every sample is coplanar): direct only, f32.
        assert!(
            (got - expect).abs().max_element() < 1e-5 * expect.max_element(),
            "{got} vs {expect}"
        );
    }
}

/// Allowance for the cut approximation (4096 samples, vertex cuts with sigma 2 on `g / <g>`,
/// light cut 256, per-vertex interpolation over walls of 6 x 6 quads) in relative RMSE: the
/// full frame measured 3.0-4.4 % against a 1024-spp path tracer whose own noise was 1.6-2.5 %
/// at both light positions of these tests (so about 2.5-3.7 % of it is the approximation,
/// mostly a 2-3 % darker indirect term); 5 % leaves a margin without hiding a missing term
/// (the indirect light is 37-42 % of the image).
const CUT_ALLOWANCE: f64 = 0.05;

/// Two light positions inside the room (the ceiling's centre, and off-centre near the box).
const POSITIONS: [Vec3; 2] = [Vec3::new(0.0, 1.7, 0.0), Vec3::new(0.6, 1.2, 0.5)];

#[test]
fn direct_light_matches_the_path_tracer_direct_only() {
    let f = fixture(CutFunction::Visibility);
    let shader = LocalShader::new(
        &f.mesh,
        f.materials.clone(),
        &f.bake,
        CutFunction::Visibility,
        f.caster.as_ref(),
    )
    .unwrap();
    let opts = RasterOptions { supersample: 4 };
    for p in POSITIONS {
        let l = shader.prepare(light_at(p), 2.0, 256).unwrap();
        let direct = Terms {
            direct: true,
            indirect: false,
        };
        let img = shader.render(&l, &camera(), &opts, direct);
        let (pt, noise) = reference(&f, light_at(p), 2, 64);
        let e = metrics(&img.image, &pt, None).rel_rmse;
        // The same estimator up to the reference's noise and pixel sampling (a 4 x 4 grid
        // against 64 jittered points: shadow and silhouette edges), measured 0.3-0.5 % above
        // the noise: 2 % for the sampling.
        assert!(
            e < noise + 0.02,
            "light at {p}: direct {e:.4}, noise {noise:.4}"
        );
    }
}

#[test]
fn one_bounce_matches_the_path_tracer_and_the_controls_fail() {
    let f = fixture(CutFunction::Visibility);
    let shader = LocalShader::new(
        &f.mesh,
        f.materials.clone(),
        &f.bake,
        CutFunction::Visibility,
        f.caster.as_ref(),
    )
    .unwrap();
    let opts = RasterOptions { supersample: 4 };
    let cam = camera();
    let lit: Vec<LocalLighting> = POSITIONS
        .iter()
        .map(|&p| shader.prepare(light_at(p), 2.0, 256).unwrap())
        .collect();
    let images: Vec<Image> = lit
        .iter()
        .map(|l| shader.render(l, &cam, &opts, Terms::ALL).image)
        .collect();
    for (k, &p) in POSITIONS.iter().enumerate() {
        let (pt, noise) = reference(&f, light_at(p), 3, 256);
        let tol = (noise * noise + CUT_ALLOWANCE * CUT_ALLOWANCE).sqrt();
        let e = metrics(&images[k], &pt, None).rel_rmse;
        assert!(
            e < tol,
            "light at {p}: {e:.4} (noise {noise:.4}, tolerance {tol:.4})"
        );
        // Control 1: without the bounce the image is far off.
        let direct = Terms {
            direct: true,
            indirect: false,
        };
        let d = shader.render(&lit[k], &cam, &opts, direct).image;
        let e_direct = metrics(&d, &pt, None).rel_rmse;
        assert!(
            e_direct > 2.0 * tol,
            "direct only {e_direct:.4} should fail {tol:.4}"
        );
        // Control 2: the light moved, its direct light follows, but the light cut (and the
        // samples' lighting) is the other position's.
        let stale = LocalLighting {
            light: lit[k].light,
            ..lit[1 - k].clone()
        };
        let s = shader.render(&stale, &cam, &opts, Terms::ALL).image;
        let e_stale = metrics(&s, &pt, None).rel_rmse;
        assert!(
            e_stale > tol,
            "stale light cut {e_stale:.4} should fail {tol:.4}"
        );
        eprintln!("light at {p}: {e:.4} (noise {noise:.4}), direct only {e_direct:.4}, stale {e_stale:.4}");
    }
    // Moving the light changes the image.
    let moved = metrics(&images[0], &images[1], None).rel_rmse;
    assert!(
        moved > 0.2,
        "moving the light changed the image by {moved:.4} only"
    );
}

#[test]
fn bad_lights_and_bakes_are_refused() {
    let f = fixture(CutFunction::Visibility);
    let shader = LocalShader::new(
        &f.mesh,
        f.materials.clone(),
        &f.bake,
        CutFunction::Visibility,
        f.caster.as_ref(),
    )
    .unwrap();
    // Inside the sphere (centre -0.4, 0.35, -0.3).
    let inside = shader.prepare(light_at(Vec3::new(-0.4, 0.35, -0.3)), 2.0, 256);
    assert!(inside.unwrap_err().contains("inside geometry"));
    // Outside the closed room: every wall shows it its back.
    let outside = shader.prepare(light_at(Vec3::new(0.0, 5.0, 0.0)), 2.0, 256);
    assert!(outside.unwrap_err().contains("inside geometry"));
    let nan = shader.prepare(light_at(Vec3::new(f32::NAN, 1.0, 0.0)), 2.0, 256);
    assert!(nan.unwrap_err().contains("position"));
    let zero = PointLight::new(Vec3::new(0.0, 1.0, 0.0), Vec3::ZERO);
    assert!(shader
        .prepare(zero, 2.0, 256)
        .unwrap_err()
        .contains("intensity"));
    // An environment bake has no surface samples.
    let env_bake = bake_range(
        &f.mesh,
        f.caster.as_ref(),
        &CutsBakeSettings {
            lights: 64,
            ..Default::default()
        },
        0..f.mesh.vertex_count(),
    )
    .unwrap();
    let err = LocalShader::new(
        &f.mesh,
        f.materials.clone(),
        &env_bake,
        CutFunction::Visibility,
        f.caster.as_ref(),
    )
    .err()
    .unwrap();
    assert!(err.to_string().contains("environment"), "{err}");
}

#[test]
fn batched_render_equals_the_per_fragment_merge() {
    for function in [CutFunction::Visibility, CutFunction::VisibilityCosine] {
        let f = fixture(function);
        let mut materials = f.materials.clone();
        // A glossy material too, for the general path.
        materials[0] = Material::GgxPlastic {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::ONE,
            alpha: 0.3,
            ior: 1.5,
        };
        for m in [f.materials.clone(), materials] {
            let shader =
                LocalShader::new(&f.mesh, m, &f.bake, function, f.caster.as_ref()).unwrap();
            let l = shader.prepare(light_at(POSITIONS[1]), 2.0, 256).unwrap();
            let cam = Camera::look_at([0.0, 1.0, 0.95], [0.0, 0.8, -1.0], 70.0, 24, 18);
            let opts = RasterOptions { supersample: 2 };
            let fast = shader.render(&l, &cam, &opts, Terms::ALL);
            let slow = shader.render_per_fragment(&l, &cam, &opts, Terms::ALL);
            // The same terms summed in another order.
            crate::compare::assert_same_up_to_rounding(
                &fast.image,
                &slow.image,
                &format!("{function:?}"),
            );
        }
    }
}

/// The room with a checker diffuse map on its white material (walls, floor, ceiling, sphere
/// and box; planar texture coordinates from x and z): the direct light and the bounce (each
/// surface sample re-emits with the albedo at its point) follow the map as the path tracer
/// does, and the frame without the maps does not.
#[test]
fn diffuse_maps_light_and_bounce_as_the_path_tracer() {
    use crate::shade_cuts::texture_tests::{load, temp_dir, write_maps};
    use relight_scene::material::maps::MapsDesc;
    let mut f = fixture(CutFunction::Visibility);
    f.mesh.uvs = Some(
        f.mesh
            .positions
            .iter()
            .map(|p| glam::Vec2::new(0.5 + 0.5 * p.x, 0.5 + 0.5 * p.z))
            .collect(),
    );
    let dir = temp_dir().join("local");
    std::fs::create_dir_all(&dir).unwrap();
    write_maps(&dir);
    let desc = MapsDesc {
        diffuse: Some("checker.png".into()),
        ..Default::default()
    };
    let maps = SceneMaps::new(
        &f.mesh,
        vec![Some(load(&dir, desc, &f.materials[0])), None, None],
    )
    .unwrap();
    let shader = |maps: SceneMaps| {
        LocalShader::new(
            &f.mesh,
            f.materials.clone(),
            &f.bake,
            CutFunction::Visibility,
            f.caster.as_ref(),
        )
        .unwrap()
        .with_maps(maps)
    };
    let light = light_at(POSITIONS[0]);
    let opts = RasterOptions { supersample: 4 };
    let render = |s: &LocalShader<'_>| {
        let l = s.prepare(light, 2.0, 256).unwrap();
        s.render(&l, &camera(), &opts, Terms::ALL).image
    };
    let textured = render(&shader(maps.clone()));
    let plain = render(&shader(SceneMaps::default()));
    f.maps = maps;
    let (pt, noise) = reference(&f, light, 3, 256);
    // The untextured room's tolerance (`one_bounce_matches_the_path_tracer_and_the_controls_fail`).
    let tol = (noise * noise + CUT_ALLOWANCE * CUT_ALLOWANCE).sqrt();
    let e = metrics(&textured, &pt, None).rel_rmse;
    let e_plain = metrics(&plain, &pt, None).rel_rmse;
    eprintln!(
        "textured room: {e:.4} (noise {noise:.4}, tolerance {tol:.4}); maps ignored {e_plain:.4}"
    );
    assert!(e < tol, "textured {e:.4} >= {tol:.4}");
    assert!(
        e_plain > 2.0 * tol,
        "maps ignored {e_plain:.4} should fail {tol:.4}"
    );
}
