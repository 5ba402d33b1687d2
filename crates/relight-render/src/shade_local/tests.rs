//! Local lighting against closed forms and the path tracer on a small closed room.

use super::*;
use crate::compare::metrics;
use crate::pathtrace::{render_with_lights, PtSettings};
use relight_bake::cuts::{bake_range, CutsBakeSettings, LightSampleKind};
use relight_scene::accel::{build, Backend};
use relight_scene::scene::{Environment, Scene};
use relight_scene::shapes::{aabb_box, ground_plane, uv_sphere};
use relight_sphere::EnvMap;

/// Divisions of each room wall (quads per side).
const WALL_DIV: u32 = 6;

/// A closed 2 x 2 x 2 room (walls facing in: left red, right green, the rest white), a
/// sphere and a box inside; materials 0-2 are white, red, green.
fn room() -> (TriMesh, Vec<Material>) {
    let mut walls = aabb_box(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0), WALL_DIV);
    for t in &mut walls.indices {
        t.swap(1, 2);
    }
    for n in &mut walls.normals {
        *n = -*n;
    }
    // aabb_box's faces in order -x, +x, -y, +y, -z, +z, 2 div^2 triangles each.
    let per_face = (2 * WALL_DIV * WALL_DIV) as usize;
    walls.material_ids = (0..walls.indices.len())
        .map(|t| match t / per_face {
            0 => 1,
            1 => 2,
            _ => 0,
        })
        .collect();
    let mut mesh = walls;
    mesh.append(&uv_sphere(Vec3::new(-0.4, 0.35, -0.3), 0.35, 10, 20), 0);
    mesh.append(&aabb_box(Vec3::new(0.1, 0.0, -0.2), Vec3::new(0.6, 0.6, 0.3), 2), 0);
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
        bake,
        caster,
    }
}

fn reference(f: &Fixture, light: PointLight, max_depth: i32, spp: u32) -> (Image, f64) {
    let scene = Scene {
        mesh: f.mesh.clone(),
        materials: f.materials.clone(),
        env: Environment::new(EnvMap::constant(Vec3::ZERO)),
        camera: camera(),
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
    let v: f64 = var.pixels.iter().map(|p| p.x as f64 + p.y as f64 + p.z as f64).sum();
    let b2: f64 = img
        .pixels
        .iter()
        .map(|p| (p.x * p.x + p.y * p.y + p.z * p.z) as f64)
        .sum();
    (img, (v / b2).sqrt())
}

use crate::image::Image;

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
    for x in [Vec3::ZERO, Vec3::new(1.2, 0.0, 0.9), Vec3::new(-1.7, 0.0, -1.1)] {
        let f = Fragment {
            tri: 0,
            bary: [1.0, 0.0, 0.0],
            position: x,
            shading_normal: Vec3::Y,
            geometric_normal: Vec3::Y,
        };
        let got = shader.shade_fragment(&l, &f, eye, Terms::ALL);
        let to = light.position - x;
        let expect =
            albedo * std::f32::consts::FRAC_1_PI * light.intensity * (to.y / to.length())
                / to.length_squared();
        // The plane lights nothing of itself (every sample is coplanar): direct only, f32.
        assert!((got - expect).abs().max_element() < 1e-5 * expect.max_element(), "{got} vs {expect}");
    }
}

#[test]
fn measure_room() {
    for function in [CutFunction::Visibility, CutFunction::VisibilityCosine] {
        let f = fixture(function);
        let shader = LocalShader::new(&f.mesh, f.materials.clone(), &f.bake, function, f.caster.as_ref()).unwrap();
        let opts = RasterOptions { supersample: 4 };
        for p in [Vec3::new(0.0, 1.7, 0.0), Vec3::new(0.6, 1.2, 0.5)] {
            let l = shader.prepare(light_at(p), 2.0, 256).unwrap();
            let (d2, n2) = reference(&f, light_at(p), 2, 64);
            let (d3, n3) = reference(&f, light_at(p), 3, 64);
            let direct = shader.render(&l, &camera(), &opts, Terms { direct: true, indirect: false });
            let all = shader.render(&l, &camera(), &opts, Terms::ALL);
            eprintln!("{function:?} {p}: noise2 {n2:.4} noise3 {n3:.4} direct vs d2 {:.4}, direct vs d3 {:.4}, all vs d3 {:.4}",
                metrics(&direct.image, &d2, None).rel_rmse,
                metrics(&direct.image, &d3, None).rel_rmse,
                metrics(&all.image, &d3, None).rel_rmse);
        }
    }
}
