//! The corner-list frame ([`CutsShader::render`], `shade_cuts::corners`) against the
//! per-triangle merge ([`CutsShader::render_merged`], itself tested equal to the per-fragment
//! merge) and against the path tracer.

use super::ward_tests::{bias, sky};
use super::*;
use crate::Image;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::samples::sample_power;
use relight_bake::cuts::{bake_range, CutsBake, CutsBakeSettings};
use relight_scene::accel::{build, Backend, RayCaster};
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Scene;
use relight_scene::shapes::{ground_plane, uv_sphere};
use relight_sphere::EnvMap;

/// A coarse sphere on a plane (neighbouring vertices' cuts differ: the sphere's shadow and
/// horizon) and its bake of `function` over 4096 lights.
pub(super) fn sphere_on_plane(function: CutFunction) -> (TriMesh, Box<dyn RayCaster>, CutsBake) {
    let mut mesh = ground_plane(Vec3::ZERO, 4.0, 10);
    mesh.append(&uv_sphere(Vec3::new(0.0, 0.8, 0.0), 0.8, 12, 18), 1);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let settings = CutsBakeSettings {
        lights: 4096,
        function,
        ..Default::default()
    };
    let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count()).unwrap();
    (mesh, caster, bake)
}

pub(super) fn camera() -> Camera {
    Camera::look_at([2.4, 2.4, 3.6], [0.0, 0.6, 0.0], 40.0, 64, 48)
}

/// With the cosine in the cuts, a Lambert BRDF is the same for every cluster, so summing by
/// corner is Eq. 5 exactly: the corner frame equals the per-triangle merge up to f32
/// rounding (as that one equals the per-fragment merge), whatever the light cut.
#[test]
fn corner_frame_equals_the_triangle_merge_for_lambert_over_cosine_cuts() {
    let (mesh, _, bake) = sphere_on_plane(CutFunction::VisibilityCosine);
    let env = Environment::new(EnvMap::latlong_from_fn(128, 64, sky));
    let power = sample_power(&bake.samples, &env).unwrap();
    let lambert = Material::Lambert {
        albedo: Vec3::new(0.2, 0.5, 0.8),
    };
    let shader = CutsShader::new(
        &mesh,
        vec![lambert; 2],
        &bake,
        CutFunction::VisibilityCosine,
    );
    for budget in [16, 256] {
        let light = LightCut::build(&bake.tree, &power, 2.0, budget).unwrap();
        let opts = RasterOptions { supersample: 2 };
        let fast = shader.render(&light, &camera(), None, &opts);
        let merged = shader.render_merged(&light, &camera(), None, &opts);
        assert_eq!(fast.coverage, merged.coverage);
        // The same terms regrouped.
        crate::compare::assert_same_up_to_rounding(
            &fast.image,
            &merged.image,
            &format!("light cut {budget}"),
        );
    }
}

/// The corner lists are rebuilt when the light cut changes (the shader caches them): a frame
/// under a second light cut equals a fresh shader's frame under it.
#[test]
fn corner_lists_follow_the_light_cut() {
    let (mesh, _, bake) = sphere_on_plane(CutFunction::Visibility);
    let lambert = Material::Lambert {
        albedo: Vec3::splat(0.5),
    };
    let lights = [
        Environment::new(EnvMap::latlong_from_fn(128, 64, sky)),
        Environment::new(EnvMap::latlong_from_fn(128, 64, |d| sky(-d))),
    ]
    .map(|env| {
        let power = sample_power(&bake.samples, &env).unwrap();
        LightCut::build(&bake.tree, &power, 2.0, 128).unwrap()
    });
    let opts = RasterOptions::default();
    let shader = CutsShader::new(&mesh, vec![lambert; 2], &bake, CutFunction::Visibility);
    let first = shader.render(&lights[0], &camera(), None, &opts);
    let second = shader.render(&lights[1], &camera(), None, &opts);
    let fresh = CutsShader::new(&mesh, vec![lambert; 2], &bake, CutFunction::Visibility).render(
        &lights[1],
        &camera(),
        None,
        &opts,
    );
    assert_eq!(second.image.pixels, fresh.image.pixels);
    assert_ne!(first.image.pixels, second.image.pixels);
}

/// The path tracer's direct-light image of `mesh` with `materials` under `env` from
/// [`camera`], and its per-pixel variance (the references of the tests below).
fn path_traced(
    mesh: &TriMesh,
    caster: &dyn RayCaster,
    materials: &[Material],
    env: &Environment,
    spp: u32,
) -> (Image, Image) {
    let scene = Scene {
        maps: Default::default(),
        mesh: mesh.clone(),
        materials: materials.to_vec(),
        env: env.clone(),
        camera: camera(),
        objects: Vec::new(),
    };
    let pts = crate::pathtrace::PtSettings {
        spp,
        max_depth: 2,
        seed: 11,
        ..Default::default()
    };
    crate::pathtrace::render_with_variance(&scene, caster, &pts)
}

/// Over binary visibility cuts the corner frame samples each corner's cosine at that
/// corner's clusters instead of the triangle's merged ones: against the path tracer (direct
/// light, its noise removed by `bias`) the default frame is no further than the per-triangle
/// merge, for a Lambert sphere and plane and for a Lambert plane under a GGX conductor or
/// plastic sphere (those triangles merged per triangle), at coarse and fine light cuts.
#[test]
fn corner_frame_matches_the_path_tracer_as_the_triangle_merge_does() {
    let (mesh, caster, bake) = sphere_on_plane(CutFunction::Visibility);
    let env = Environment::new(EnvMap::latlong_from_fn(256, 128, sky));
    let power = sample_power(&bake.samples, &env).unwrap();
    let plane = Material::Lambert {
        albedo: Vec3::splat(0.5),
    };
    let spheres = [
        Material::Lambert {
            albedo: Vec3::new(0.7, 0.5, 0.3),
        },
        Material::GgxConductor {
            specular: Vec3::new(0.9, 0.7, 0.5),
            alpha: 0.2,
        },
        Material::GgxPlastic {
            diffuse: Vec3::new(0.5, 0.2, 0.2),
            specular: Vec3::ONE,
            alpha: 0.1,
            ior: 1.49,
        },
        Material::Gltf {
            base_color: Vec3::new(0.9, 0.6, 0.3),
            metallic: 0.5,
            roughness: 0.45,
        },
    ];
    // The wrong sky (upside down): a control the tolerance must reject.
    let wrong = {
        let env = Environment::new(EnvMap::latlong_from_fn(256, 128, |d| sky(-d)));
        let power = sample_power(&bake.samples, &env).unwrap();
        LightCut::build(&bake.tree, &power, 2.0, 256).unwrap()
    };
    let opts = RasterOptions { supersample: 2 };
    for sphere in spheres {
        let materials = vec![plane, sphere];
        let (pt, var) = path_traced(&mesh, caster.as_ref(), &materials, &env, 256);
        let shader = CutsShader::new(&mesh, materials, &bake, CutFunction::Visibility);
        for budget in [16, 64, 256] {
            let light = LightCut::build(&bake.tree, &power, 2.0, budget).unwrap();
            let corners = shader.render(&light, &camera(), None, &opts);
            let merged = shader.render_merged(&light, &camera(), None, &opts);
            let mask = merged.full_coverage_mask();
            let b_corners = bias(&corners.image, &pt, &var, &mask);
            let b_merged = bias(&merged.image, &pt, &var, &mask);
            let b_wrong = bias(
                &shader.render(&wrong, &camera(), None, &opts).image,
                &pt,
                &var,
                &mask,
            );
            println!(
                "{sphere:?}, light cut {budget}: bias against the path tracer, corners \
                 {b_corners:.5}, triangle merge {b_merged:.5}; control (wrong sky) {b_wrong:.4}"
            );
            // Measured (2026-12-02): Lambert sphere 0.0236 against 0.0258 at 64 nodes,
            // 0.0230 against 0.0230 at 256; with a glossy sphere only the plane's share
            // changes. Bound: the triangle merge's error plus 2 % of it (the cosine sampled at
            // other directions can land either side).
            let tolerance = 1.02 * b_merged;
            assert!(
                b_corners <= tolerance,
                "{sphere:?}, light cut {budget}: corners {b_corners} vs merge {b_merged}"
            );
            // The control must fail the bound, or the test could not fail.
            assert!(b_wrong > 5.0 * tolerance, "control {b_wrong}");
        }
    }
}

/// The cluster spread averages only a material's glossy lobe (`LightCut::spread_lobes`); a
/// GGX plastic's diffuse base stays at each cluster's direction. Against the path tracer
/// (direct light, 1024 spp, noise removed by `bias`), spreading the glossy lobe makes a sharp
/// plastic closer and a rough one no further, at coarse and fine light cuts. Spreading the
/// diffuse base too (as an earlier frame did) was 5 % further than no spread at all for
/// the rough plastic at 16 nodes (0.0347 against 0.0330), which this bound rejects.
#[test]
fn spreading_the_glossy_lobe_alone_is_never_further_from_the_path_tracer() {
    let (mesh, caster, bake) = sphere_on_plane(CutFunction::Visibility);
    let env = Environment::new(EnvMap::latlong_from_fn(256, 128, sky));
    let power = sample_power(&bake.samples, &env).unwrap();
    let plane = Material::Lambert {
        albedo: Vec3::splat(0.5),
    };
    let plastic = |diffuse, alpha| Material::GgxPlastic {
        diffuse,
        specular: Vec3::ONE,
        alpha,
        ior: 1.49,
    };
    let opts = RasterOptions { supersample: 2 };
    for (sphere, sharp) in [
        (plastic(Vec3::new(0.5, 0.2, 0.2), 0.1), true),
        (plastic(Vec3::splat(0.8), 0.3), false),
    ] {
        let materials = vec![plane, sphere];
        let (pt, var) = path_traced(&mesh, caster.as_ref(), &materials, &env, 1024);
        let shader = |spread| {
            CutsShader::new(&mesh, materials.clone(), &bake, CutFunction::Visibility)
                .with_cluster_spread(spread)
        };
        let (on, off) = (shader(true), shader(false));
        for budget in [16, 64, 256] {
            let light = LightCut::build(&bake.tree, &power, 2.0, budget).unwrap();
            let render = |s: &CutsShader| s.render(&light, &camera(), None, &opts);
            let (r_on, r_off) = (render(&on), render(&off));
            let mask = r_on.full_coverage_mask();
            let (b_on, b_off) = (
                bias(&r_on.image, &pt, &var, &mask),
                bias(&r_off.image, &pt, &var, &mask),
            );
            println!(
                "{sphere:?}, light cut {budget}: bias spread {b_on:.5}, not spread {b_off:.5}"
            );
            // Measured (2026-12-04): alpha 0.1 0.0419 / 0.0297 / 0.0278 against 0.0509 /
            // 0.0379 / 0.0300; alpha 0.3 0.0331 / 0.0226 / 0.0221 against 0.0330 / 0.0225 /
            // 0.0221. Bound: 2 % of the unspread error (as the corner test's).
            assert!(
                b_on <= 1.02 * b_off,
                "{sphere:?}, {budget}: {b_on} vs {b_off}"
            );
            if sharp && budget < 256 {
                assert!(b_on < 0.9 * b_off, "sharp, {budget}: {b_on} vs {b_off}");
            }
        }
    }
}
