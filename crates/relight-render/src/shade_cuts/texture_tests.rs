//! Texture and normal maps chosen at render time on a `cuts` bake (Cheslack-Postava et al.
//! 2008, sec. 4.2: per-pixel BRDF parameters from textures, normals from a normal map),
//! against relight's path tracer with the same maps. Both look the material up with
//! `relight_scene::material::maps::shading_at`; what this checks is that the deferred
//! buffer feeds it the same points and uses its answer as the path tracer does.

use super::ward_tests::{bias, sky};
use super::*;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::samples::sample_power;
use relight_bake::cuts::{bake_range, CutsBake, CutsBakeSettings};
use relight_scene::accel::{build, Backend, RayCaster};
use relight_scene::io::{write_png_srgb8, PathPolicy};
use relight_scene::material::maps::{MapsDesc, MaterialMaps};
use relight_scene::scene::Scene;
use relight_scene::shapes::{ground_plane, uv_sphere};
use relight_sphere::EnvMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A fresh temporary folder.
pub(crate) fn temp_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("relight-cuts-textures-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Write the test's maps into `dir`: `checker.png`, an 8 x 4 checker of two colours over
/// 64 x 32 texels (sRGB-encoded: the loader decodes it), and `ripples.png` / `flipped.png`,
/// a normal map of six ripples around `u` (tilting the normal by up to 27 degrees along the
/// tangent) and the same with its tangent component negated (the control).
pub(crate) fn write_maps(dir: &Path) {
    let (w, h) = (64usize, 32usize);
    let checker: Vec<[u8; 3]> = (0..w * h)
        .map(|i| {
            if ((i % w) / 8 + (i / w) / 8) % 2 == 0 {
                [235, 120, 40]
            } else {
                [40, 110, 230]
            }
        })
        .collect();
    write_png_srgb8(&dir.join("checker.png"), w, h, &checker).unwrap();
    for (name, sign) in [("ripples.png", 1.0f32), ("flipped.png", -1.0)] {
        let px: Vec<[u8; 3]> = (0..w * h)
            .map(|i| {
                let u = ((i % w) as f32 + 0.5) / w as f32;
                let slope = 0.5 * (std::f32::consts::TAU * 6.0 * u).sin();
                let n = Vec3::new(-slope * sign, 0.0, 1.0).normalize();
                let c = (n + Vec3::ONE) * 0.5 * 255.0;
                [c.x.round() as u8, c.y.round() as u8, c.z.round() as u8]
            })
            .collect();
        write_png_srgb8(&dir.join(name), w, h, &px).unwrap();
    }
}

/// The maps of `desc` read from `dir` for `material`.
pub(crate) fn load(dir: &Path, desc: MapsDesc, material: &Material) -> Arc<MaterialMaps> {
    let origin = dir.join("material.json");
    Arc::new(MaterialMaps::load(&desc, material, &origin, &PathPolicy::default()).unwrap())
}

struct Setup {
    mesh: TriMesh,
    caster: Box<dyn RayCaster>,
    bake: CutsBake,
    env: Environment,
    light: LightCut,
    camera: Camera,
    materials: Vec<Material>,
}

fn setup() -> Setup {
    let mut mesh = uv_sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, 24, 48);
    mesh.append(&ground_plane(Vec3::ZERO, 8.0, 16), 1);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    // Binary visibility: the cosine follows the per-pixel (mapped) normal, as the path
    // tracer's does (with cosine-weighted cuts it would stay the vertex normals').
    let settings = CutsBakeSettings {
        lights: 8192,
        function: CutFunction::Visibility,
        ..Default::default()
    };
    let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count()).unwrap();
    let env = Environment::new(EnvMap::latlong_from_fn(256, 128, sky));
    let power = sample_power(&bake.samples, &env).unwrap();
    let light = LightCut::build(&bake.tree, &power, 2.0, 1024).unwrap();
    let camera = Camera::look_at([2.6, 2.2, 3.4], [0.0, 0.9, 0.0], 34.0, 48, 40);
    let materials = vec![
        Material::GgxPlastic {
            diffuse: Vec3::splat(0.9),
            specular: Vec3::ONE,
            alpha: 0.25,
            ior: 1.5,
        },
        Material::Lambert {
            albedo: Vec3::splat(0.8),
        },
    ];
    Setup {
        mesh,
        caster,
        bake,
        env,
        light,
        camera,
        materials,
    }
}

/// A textured GGX plastic sphere (checker diffuse map, rippled normal map) on a Lambert
/// plane with the checker, baked once with no materials: the cuts frame with those maps
/// matches the path tracer with them about as well as the untextured frame matches the
/// untextured path tracer, while the frame without the maps, or with the normal map's
/// tangent component flipped, does not.
#[test]
fn textured_materials_chosen_after_the_bake_match_the_path_tracer() {
    let s = setup();
    let dir = temp_dir();
    write_maps(&dir);
    let desc = |normal: Option<&str>| MapsDesc {
        diffuse: Some("checker.png".into()),
        normal: normal.map(String::from),
        ..Default::default()
    };
    let maps = |normal: &str| {
        SceneMaps::new(
            &s.mesh,
            vec![
                Some(load(&dir, desc(Some(normal)), &s.materials[0])),
                Some(load(&dir, desc(None), &s.materials[1])),
            ],
        )
        .unwrap()
    };
    let cuts = |maps: SceneMaps| {
        CutsShader::new(
            &s.mesh,
            s.materials.clone(),
            &s.bake,
            CutFunction::Visibility,
        )
        .with_maps(maps)
        .render(&s.light, &s.camera, None, &RasterOptions { supersample: 2 })
    };
    let reference = |maps: SceneMaps| {
        let scene = Scene {
            mesh: s.mesh.clone(),
            materials: s.materials.clone(),
            maps,
            env: s.env.clone(),
            camera: s.camera,
            objects: Vec::new(),
        };
        let pts = crate::pathtrace::PtSettings {
            spp: 256,
            max_depth: 2,
            seed: 5,
            ..Default::default()
        };
        crate::pathtrace::render_with_variance(&scene, s.caster.as_ref(), &pts)
    };
    let plain = cuts(SceneMaps::default());
    let textured = cuts(maps("ripples.png"));
    let flipped = cuts(maps("flipped.png"));
    let (pt_plain, var_plain) = reference(SceneMaps::default());
    let (pt_tex, var_tex) = reference(maps("ripples.png"));
    let mask = textured.full_coverage_mask();
    assert!(
        mask.iter().filter(|&&k| k).count() > 1000,
        "the scene is in view"
    );
    let b_plain = bias(&plain.image, &pt_plain, &var_plain, &mask);
    let b_tex = bias(&textured.image, &pt_tex, &var_tex, &mask);
    let b_ignored = bias(&plain.image, &pt_tex, &var_tex, &mask);
    let b_flipped = bias(&flipped.image, &pt_tex, &var_tex, &mask);
    println!(
        "cuts vs path tracer, relative RMSE of the bias: untextured {b_plain:.4}, textured \
         {b_tex:.4}; controls: maps ignored {b_ignored:.4}, normal map flipped {b_flipped:.4}"
    );
    // The textured frame's error is the untextured one's (the cut approximation, 8192 light
    // samples, per-pixel interpolation of vertex visibility: the noise of the 256-spp
    // reference is removed by `bias`) plus what the maps add where they vary faster than
    // the vertex cuts: a checker edge or a ripple inside a triangle sees its corners'
    // visibility. Bound: 1.5 x the untextured error plus 1 % of the image's RMS.
    let tolerance = 1.5 * b_plain + 0.01;
    assert!(
        b_tex < tolerance,
        "textured {b_tex} vs untextured {b_plain}"
    );
    // The controls must fail that bound by a margin, or the test could not fail.
    assert!(b_ignored > 2.0 * tolerance, "maps ignored: {b_ignored}");
    assert!(
        b_flipped > 1.5 * tolerance,
        "normal map flipped: {b_flipped}"
    );
}

/// A GGX conductor sphere whose roughness map alternates alpha 0.08 and 0.45 in a checker,
/// with a specular map (the checker's colours): the cuts frame matches the path tracer with
/// the same maps, and the frame with the constant roughness (map ignored) does not.
#[test]
fn roughness_and_specular_maps_match_the_path_tracer() {
    let mut s = setup();
    s.materials[0] = Material::GgxConductor {
        specular: Vec3::splat(0.95),
        alpha: 0.25,
    };
    let dir = temp_dir().join("rough");
    std::fs::create_dir_all(&dir).unwrap();
    write_maps(&dir);
    // Roughness: PNG data maps are linear (value / 255): 20 -> 0.078, 115 -> 0.451.
    let (w, h) = (64usize, 32usize);
    let rough: Vec<[u8; 3]> = (0..w * h)
        .map(|i| {
            [if ((i % w) / 8 + (i / w) / 8) % 2 == 0 {
                20
            } else {
                115
            }; 3]
        })
        .collect();
    write_png_srgb8(&dir.join("rough.png"), w, h, &rough).unwrap();
    let desc = MapsDesc {
        specular: Some("checker.png".into()),
        roughness: Some("rough.png".into()),
        ..Default::default()
    };
    let sphere = load(&dir, desc, &s.materials[0]);
    let maps =
        |sphere: Option<Arc<MaterialMaps>>| SceneMaps::new(&s.mesh, vec![sphere, None]).unwrap();
    let mut ignored = (*sphere).clone();
    ignored.roughness = None;
    let cuts = |maps: SceneMaps| {
        CutsShader::new(
            &s.mesh,
            s.materials.clone(),
            &s.bake,
            CutFunction::Visibility,
        )
        .with_maps(maps)
        .render(&s.light, &s.camera, None, &RasterOptions { supersample: 2 })
    };
    let plain = cuts(SceneMaps::default());
    let mapped = cuts(maps(Some(sphere.clone())));
    let no_roughness = cuts(maps(Some(Arc::new(ignored))));
    let reference = |maps: SceneMaps| {
        let scene = Scene {
            mesh: s.mesh.clone(),
            materials: s.materials.clone(),
            maps,
            env: s.env.clone(),
            camera: s.camera,
            objects: Vec::new(),
        };
        let pts = crate::pathtrace::PtSettings {
            spp: 256,
            max_depth: 2,
            seed: 9,
            ..Default::default()
        };
        crate::pathtrace::render_with_variance(&scene, s.caster.as_ref(), &pts)
    };
    let (pt_plain, var_plain) = reference(SceneMaps::default());
    let (pt, var) = reference(maps(Some(sphere)));
    let mask = mapped.full_coverage_mask();
    let b_plain = bias(&plain.image, &pt_plain, &var_plain, &mask);
    let b_mapped = bias(&mapped.image, &pt, &var, &mask);
    let b_ignored = bias(&no_roughness.image, &pt, &var, &mask);
    println!(
        "conductor, cuts vs path tracer, relative RMSE of the bias: constant {b_plain:.4}, \
         roughness + specular maps {b_mapped:.4}; control: roughness map ignored {b_ignored:.4}"
    );
    // As in the test above: 1.5 x the constant material's error plus 1 % (the alpha 0.08
    // squares are sharper than the constant's 0.25 lobe, which 8192 light samples resolve
    // less well).
    let tolerance = 1.5 * b_plain + 0.01;
    assert!(
        b_mapped < tolerance,
        "mapped {b_mapped} vs constant {b_plain}"
    );
    assert!(
        b_ignored > 1.5 * tolerance,
        "roughness ignored: {b_ignored}"
    );
}
