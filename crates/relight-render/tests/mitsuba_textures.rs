//! Textured materials (diffuse, specular, roughness, metallic-roughness and normal maps) in
//! relight's path tracer against Mitsuba 3 through the export's `bitmap` textures
//! (`relight_render::mitsuba`, "Texture and normal maps"); glTF materials against the
//! `gltf_pbr` plugin (`tools/mitsuba_gltf_bsdf.py`).
//!
//! Scenes: a ground square (mirrored UVs) and a UV sphere under a smooth one-lobe environment,
//! direct light only (max_depth 2), 48 x 48 pixels; the procedural textures are written to a
//! temporary folder as EXR and read back as a scene's maps are. The measure and its tolerance
//! are `mitsuba_agreement.rs`'s (`common`): `relRMSE <= 1.5 x` the noise floor of both
//! renders at their spp (a systematic difference of 1.1 x the floor fails), mean difference
//! within 4 standard errors. Each test also renders a control with relight (maps ignored, or
//! the texture placed as the export would place it without its conversion) that must FAIL
//! that tolerance against the same Mitsuba images, so the comparison sees the maps. SKIPS
//! with a printed reason without Mitsuba (`RELIGHT_REQUIRE_REFERENCE=1` makes that a failure).

use relight_render::pathtrace::{render_with_variance, PtSettings};
use relight_scene::accel::build_default;
use relight_scene::camera::Camera;
use relight_scene::material::maps::{MaterialMaps, SceneMaps};
use relight_scene::material::Material;
use relight_scene::scene::{Environment, Scene};
use relight_scene::shapes::{ground_plane, uv_sphere};
use relight_scene::texture::{Encoding, Texture};
use relight_scene::Vec3;
use relight_sphere::envmap::EnvMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

mod common;
use common::{agreement, mitsuba_render, object_mask, K};

/// A smooth environment: 0.15 everywhere plus a warm lobe `6 max(0, d.s)^6` from the upper
/// right front.
fn lobe_env() -> Environment {
    let s = Vec3::new(0.5, 1.0, 0.4).normalize();
    Environment::new(EnvMap::latlong_from_fn(128, 65, move |d| {
        Vec3::splat(0.15) + Vec3::new(6.0, 5.4, 4.8) * d.dot(s).max(0.0).powi(6)
    }))
}

/// A texture of `w x h` texels `f(x, y)` (from the top-left), written to a temporary EXR and
/// read back as a scene file's map is.
fn texture(name: &str, w: usize, h: usize, f: impl Fn(usize, usize) -> Vec3) -> Texture {
    // One folder per call: the tests run in parallel.
    static CALLS: AtomicUsize = AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("relight-mtex-{}-{call}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.exr"));
    let texels: Vec<Vec3> = (0..w * h).map(|i| f(i % w, i / w)).collect();
    relight_scene::io::write_exr(&path, w, h, &texels).unwrap();
    let t = Texture::read(&path, Encoding::Colour).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    t
}

/// 8 x 8: red grows with `u`, green with `v` (upwards), blue a checker (no symmetry a wrong
/// placement could keep).
fn colour_map() -> Texture {
    texture("colour", 8, 8, |x, y| {
        Vec3::new(
            (x as f32 + 0.5) / 8.0,
            1.0 - (y as f32 + 0.5) / 8.0,
            if (x + y) % 2 == 0 { 0.9 } else { 0.2 },
        )
    })
}

/// `t` with its rows in the opposite order (a texture placed with `v` not converted).
fn rows_flipped(t: &Texture) -> Texture {
    let (w, h) = (t.width(), t.height());
    let texels = (0..w * h)
        .map(|i| t.texels()[(h - 1 - i / w) * w + i % w])
        .collect();
    Texture::new(w, h, texels).unwrap()
}

/// 16 x 16 tangent-space ripples, tilting up to ~27 degrees along both `u` and `v`.
fn ripple_map() -> Texture {
    let tau = std::f32::consts::TAU;
    texture("normal", 16, 16, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / 16.0, (y as f32 + 0.5) / 16.0);
        let n = Vec3::new(0.5 * (2.0 * tau * u).sin(), 0.4 * (tau * v).cos(), 1.0).normalize();
        (n + Vec3::ONE) * 0.5
    })
}

/// `t` with its green channel flipped (the bitangent reversed).
fn green_flipped(t: &Texture) -> Texture {
    let texels = t
        .texels()
        .iter()
        .map(|c| Vec3::new(c.x, 1.0 - c.y, c.z))
        .collect();
    Texture::new(t.width(), t.height(), texels).unwrap()
}

/// A 3 x 3 ground square (material 0, UVs mirrored: tangent handedness -1) and a sphere of
/// radius 0.6 on it (material 1), with `maps` per material.
fn scene(materials: [Material; 2], maps: [Option<MaterialMaps>; 2], sphere: bool) -> Scene {
    let mut mesh = ground_plane(Vec3::ZERO, 3.0, 2);
    if sphere {
        mesh.append(&uv_sphere(Vec3::new(0.0, 0.6, 0.0), 0.6, 24, 48), 1);
    }
    let maps = maps.into_iter().map(|m| m.map(Arc::new)).collect();
    Scene {
        maps: SceneMaps::new(&mesh, maps).unwrap(),
        mesh,
        materials: materials.to_vec(),
        env: lobe_env(),
        camera: Camera::look_at([0.0, 2.0, 2.6], [0.0, 0.35, 0.0], 52.0, 48, 48),
        objects: Vec::new(),
    }
}

/// `scene` without its maps.
fn unmapped(scene: &Scene) -> Scene {
    Scene {
        maps: SceneMaps::default(),
        ..scene.clone()
    }
}

/// `scene` with material `m`'s maps replaced.
fn remapped(scene: &Scene, m: usize, maps: MaterialMaps) -> Scene {
    let mut per: Vec<_> = (0..scene.materials.len())
        .map(|i| scene.maps.of(i as u32).cloned().map(Arc::new))
        .collect();
    per[m] = Some(Arc::new(maps));
    Scene {
        maps: SceneMaps::new(&scene.mesh, per).unwrap(),
        ..scene.clone()
    }
}

/// Render `scene` with relight (`spp`) and Mitsuba (`spp / 2`, two seeds), assert agreement;
/// then each control (relight, `spp / 4`) must fail the same tolerance against Mitsuba.
fn check(name: &str, scene: &Scene, spp: u32, controls: &[(&str, Scene)]) {
    let Some(m) = mitsuba_render(name, scene, spp / 2, 2) else {
        return;
    };
    let caster = build_default(&scene.mesh);
    let mask = object_mask(scene, caster.as_ref());
    let s = PtSettings {
        spp,
        max_depth: 2,
        seed: 7,
        ..Default::default()
    };
    let (img, var) = render_with_variance(scene, caster.as_ref(), &s);
    let ag = agreement(&img, &var, &m.mean, &m.var, &mask);
    println!(
        "{name}: relRMSE {:.4}, floor {:.4}, ratio {:.2}, mean {:.2} sigma ({})",
        ag.rel_rmse,
        ag.floor,
        ag.rel_rmse / ag.floor,
        ag.bias_sigmas,
        m.report
    );
    assert!(
        ag.rel_rmse <= K * ag.floor,
        "{name}: relRMSE {} > {K} x floor {}",
        ag.rel_rmse,
        ag.floor
    );
    assert!(
        ag.bias_sigmas < 4.0,
        "{name}: mean difference {} standard errors",
        ag.bias_sigmas
    );
    for (label, control) in controls {
        let s = PtSettings {
            spp: spp / 4,
            ..s.clone()
        };
        let (c, var_c) = render_with_variance(control, caster.as_ref(), &s);
        let ag = agreement(&c, &var_c, &m.mean, &m.var, &mask);
        println!(
            "{name}, control {label}: relRMSE {:.4}, floor {:.4}, ratio {:.2}",
            ag.rel_rmse,
            ag.floor,
            ag.rel_rmse / ag.floor
        );
        assert!(
            ag.rel_rmse > K * ag.floor,
            "{name}: control {label} passes the tolerance ({} <= {K} x {}): the test cannot see the maps",
            ag.rel_rmse,
            ag.floor
        );
    }
}

#[test]
fn diffuse_map_on_lambert_matches_mitsuba() {
    let lambert = |a: Vec3| Material::Lambert { albedo: a };
    let maps = || MaterialMaps {
        diffuse: Some(colour_map()),
        ..Default::default()
    };
    let sc = scene(
        [lambert(Vec3::splat(0.9)), lambert(Vec3::new(0.8, 0.7, 0.6))],
        [Some(maps()), Some(maps())],
        true,
    );
    let flipped = MaterialMaps {
        diffuse: Some(rows_flipped(&colour_map())),
        ..Default::default()
    };
    let controls = [
        ("maps ignored", unmapped(&sc)),
        (
            "v not flipped",
            remapped(&remapped(&sc, 0, flipped.clone()), 1, flipped),
        ),
    ];
    check("diffuse map on Lambert", &sc, 256, &controls);
}

/// Samplers and `KHR_texture_transform` through the export's `wrap_mode`, `filter_type` and
/// `to_uv`: the ground's map clamped and read through a scale and offset that reach past the
/// image on every side (so the clamp is seen), the sphere's mirrored, nearest-filtered and
/// rotated. Controls: the transforms dropped; the ground's map repeated instead of clamped.
#[test]
fn samplers_and_texture_transforms_match_mitsuba() {
    use glam::Vec2;
    use relight_scene::texture::{Filter, Sampler, UvTransform, Wrap};
    let lambert = |a: Vec3| Material::Lambert { albedo: a };
    let sampler = |wrap, filter| Sampler {
        wrap_s: wrap,
        wrap_t: wrap,
        filter,
    };
    let clamped = |wrap| {
        colour_map()
            .with_sampler(sampler(wrap, Filter::Linear))
            .with_transform(Some(UvTransform {
                offset: Vec2::new(-0.35, -0.3),
                rotation: 0.0,
                scale: Vec2::new(1.7, 1.6),
            }))
    };
    let mirrored = colour_map()
        .with_sampler(sampler(Wrap::MirroredRepeat, Filter::Nearest))
        .with_transform(Some(UvTransform {
            offset: Vec2::new(0.2, -0.1),
            rotation: 0.6,
            scale: Vec2::new(1.5, 2.5),
        }));
    let diffuse = |t: Texture| MaterialMaps {
        diffuse: Some(t),
        ..Default::default()
    };
    let sc = scene(
        [lambert(Vec3::splat(0.9)), lambert(Vec3::new(0.8, 0.7, 0.6))],
        [
            Some(diffuse(clamped(Wrap::ClampToEdge))),
            Some(diffuse(mirrored.clone())),
        ],
        true,
    );
    let controls = [
        (
            "transforms dropped",
            remapped(
                &remapped(
                    &sc,
                    0,
                    diffuse(clamped(Wrap::ClampToEdge).with_transform(None)),
                ),
                1,
                diffuse(mirrored.with_transform(None)),
            ),
        ),
        (
            "ground repeated, not clamped",
            remapped(&sc, 0, diffuse(clamped(Wrap::Repeat))),
        ),
    ];
    check("samplers and texture transforms", &sc, 256, &controls);
}

#[test]
fn specular_and_roughness_maps_on_conductor_match_mitsuba() {
    let conductor = Material::GgxConductor {
        specular: Vec3::new(0.95, 0.85, 0.6),
        // Replaced by the roughness map (a control renders it without the map).
        alpha: 0.7,
    };
    let checker = texture("roughness", 4, 4, |x, y| {
        Vec3::splat(if (x + y) % 2 == 0 { 0.05 } else { 0.3 })
    });
    let maps = MaterialMaps {
        specular: Some(colour_map()),
        roughness: Some(checker),
        ..Default::default()
    };
    let ground = Material::Lambert {
        albedo: Vec3::splat(0.5),
    };
    let sc = scene([ground, conductor], [None, Some(maps.clone())], true);
    let controls = [
        ("maps ignored", unmapped(&sc)),
        (
            "roughness map ignored",
            remapped(
                &sc,
                1,
                MaterialMaps {
                    roughness: None,
                    ..maps
                },
            ),
        ),
    ];
    check(
        "specular + roughness maps on GGX conductor",
        &sc,
        256,
        &controls,
    );
}

#[test]
fn normal_and_diffuse_maps_on_a_plastic_quad_match_mitsuba() {
    // A planar square with affine UVs: the per-vertex tangents are the triangles' dp/du, so
    // Mitsuba's normalmap frame is relight's (exact case); its UVs are mirrored, so the export
    // flips the map's green channel.
    let plastic = Material::GgxPlastic {
        diffuse: Vec3::new(0.6, 0.5, 0.4),
        specular: Vec3::ONE,
        alpha: 0.3,
        ior: 1.5,
    };
    let maps = MaterialMaps {
        diffuse: Some(colour_map()),
        normal: Some(ripple_map()),
        ..Default::default()
    };
    let sc = scene([plastic, plastic], [Some(maps.clone()), None], false);
    let controls = [
        (
            "normal map ignored",
            remapped(
                &sc,
                0,
                MaterialMaps {
                    normal: None,
                    ..maps.clone()
                },
            ),
        ),
        (
            "green not flipped",
            remapped(
                &sc,
                0,
                MaterialMaps {
                    normal: Some(green_flipped(&ripple_map())),
                    ..maps
                },
            ),
        ),
    ];
    check(
        "normal + diffuse maps on GGX plastic quad",
        &sc,
        256,
        &controls,
    );
}

/// The glTF metallic-roughness BRDF (Appendix B) against Mitsuba's `gltf_pbr` plugin
/// (`tools/mitsuba_gltf_bsdf.py`, an independent Dr.Jit implementation), with two metallic
/// values, a base-colour map and a metallic-roughness map: a dielectric ground (metallic 0,
/// base colour map, green = roughness ramp) and a metallic sphere (metallic 1, checker of
/// roughness 0.35 / 0.7 and metallic 1 / 0.5 through green and blue).
#[test]
fn gltf_base_colour_and_metallic_roughness_maps_match_mitsuba() {
    let ground = Material::Gltf {
        base_color: Vec3::splat(0.9),
        metallic: 0.0,
        roughness: 0.9,
    };
    let sphere = Material::Gltf {
        base_color: Vec3::new(0.95, 0.8, 0.5),
        metallic: 1.0,
        roughness: 1.0,
    };
    let ramp = texture("mr_ramp", 8, 1, |x, _| {
        Vec3::new(0.0, 0.4 + 0.6 * (x as f32 + 0.5) / 8.0, 0.0)
    });
    let checker = texture("mr_checker", 4, 4, |x, y| {
        if (x + y) % 2 == 0 {
            Vec3::new(0.0, 0.35, 1.0)
        } else {
            Vec3::new(0.0, 0.7, 0.5)
        }
    });
    let ground_maps = MaterialMaps {
        diffuse: Some(colour_map()),
        metallic_roughness: Some(ramp),
        ..Default::default()
    };
    let sphere_maps = MaterialMaps {
        metallic_roughness: Some(checker),
        ..Default::default()
    };
    let sc = scene(
        [ground, sphere],
        [Some(ground_maps), Some(sphere_maps)],
        true,
    );
    let controls = [
        ("maps ignored", unmapped(&sc)),
        (
            "sphere's metallic-roughness map ignored",
            remapped(&sc, 1, MaterialMaps::default()),
        ),
    ];
    check(
        "base colour + metallic-roughness maps on glTF materials",
        &sc,
        256,
        &controls,
    );
}

/// A normal map with `normal_scale` (glTF's `normalTexture.scale`) on a glTF quad: the export
/// writes the scaled normals (`mitsuba/maps.rs`); a control rendering the map at scale 1 must
/// fail.
#[test]
fn scaled_normal_map_on_a_gltf_quad_matches_mitsuba() {
    let gltf = Material::Gltf {
        base_color: Vec3::new(0.7, 0.55, 0.4),
        metallic: 0.3,
        roughness: 0.5,
    };
    let maps = MaterialMaps {
        normal: Some(ripple_map()),
        normal_scale: 2.0,
        ..Default::default()
    };
    let sc = scene([gltf, gltf], [Some(maps.clone()), None], false);
    let controls = [(
        "normal_scale ignored",
        remapped(
            &sc,
            0,
            MaterialMaps {
                normal_scale: 1.0,
                ..maps
            },
        ),
    )];
    check("scaled normal map on a glTF quad", &sc, 256, &controls);
}
