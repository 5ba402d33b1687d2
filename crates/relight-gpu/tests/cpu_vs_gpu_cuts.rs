//! The GPU `cuts` frame against the CPU's per-sample reference
//! (`CutsShader::render_per_fragment`: the merge of sec. 3.2 at every sample, the same light
//! cut, the same materials: Lambert, GGX conductor, GGX plastic; the cluster spread on as
//! the CPU frame's default), pixel by pixel, with negative controls that must fail the same
//! comparison. Skips with a printed
//! reason where no Vulkan adapter exists (fails under `RELIGHT_REQUIRE_REFERENCE=1`).
//!
//! # Tolerances, and where the differences come from
//! The GPU merges the same cuts in the same order, so the same clusters are summed; what
//! differs is f32 arithmetic: the perspective-correct barycentrics (the GPU's interpolator
//! against the CPU rasteriser's), hence the interpolated position, normal and view vector,
//! the BRDF's square roots and divisions (WGSL may fuse multiply-adds), and the order of
//! each product. Relative differences of order 1e-6 per cluster, summed over a few hundred
//! clusters; a GGX lobe amplifies a change of the half vector by its slope, so a fully
//! covered pixel is compared at `REL_TOL` = 1e-3 (pixels darker than `FLOOR` x the
//! brightest against that floor), as the other methods' tests. Coverage as in
//! `cpu_vs_gpu.rs` (silhouette samples on an edge may differ); visibility ties where the
//! sphere touches its plane are bounded by `MAX_OUTLIERS`.

use glam::Vec3;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::samples::sample_power;
use relight_bake::cuts::visibility::CutFunction;
use relight_bake::cuts::CutsBakeSettings;
use relight_gpu::{frame_of, Gpu, GpuError, GpuOutput};
use relight_method::cuts::{Cuts, CutsBaked, CutsFrameSettings};
use relight_method::{BakeContext, BakeInput, Baked, FrameOptions, FrameSettings, Method};
use relight_render::raster::RasterOptions;
use relight_render::shade_cuts::CutsShader;
use relight_render::Image;
use relight_scene::material::Material;
use relight_scene::scene::{Environment, Scene};
use relight_scene::scene_file::SceneDesc;
use std::path::Path;

/// Relative tolerance of a fully covered pixel (module docs).
const REL_TOL: f32 = 1e-3;
/// Pixels darker than this fraction of the brightest are compared against it.
const FLOOR: f32 = 1e-3;
/// Fully covered pixels allowed beyond `REL_TOL` (visibility ties): 0.5 %.
const MAX_OUTLIERS: f32 = 0.005;
/// Mean relative difference over the fully covered pixels.
const MEAN_TOL: f32 = 1e-4;
/// Pixels whose coverage differs (silhouette samples on edges): 0.5 %.
const MAX_COVERAGE_DIFF: f32 = 0.005;

fn gpu() -> Option<Gpu> {
    match Gpu::new() {
        Ok(g) => {
            eprintln!("GPU adapter: {}", g.adapter_name());
            Some(g)
        }
        Err(e @ GpuError::NoAdapter(_)) => {
            relight_testdata::skip(&format!("no Vulkan adapter: {e}"));
            None
        }
        Err(e) => panic!("{e}"),
    }
}

/// A sphere of `material` on a Lambert plane under a sun and sky, 96 x 64.
fn desc(material: &str) -> SceneDesc {
    serde_json::from_str(&format!(
        r#"{{"shapes": [
              {{"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 12,
               "material": {material}}},
              {{"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 6,
               "material": {{"type": "lambert", "albedo": [0.6, 0.6, 0.6]}}}}],
            "environment": {{"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 30,
                            "turbidity": 3, "ground_albedo": [0.3, 0.3, 0.3]}},
            "camera": {{"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 96, "height": 64}}}}"#
    ))
    .expect("test scene")
}

const LAMBERT: &str = r#"{"type": "lambert", "albedo": [0.8, 0.3, 0.2]}"#;
const CONDUCTOR: &str = r#"{"type": "ggx_conductor", "specular": [0.9, 0.7, 0.4], "alpha": 0.2}"#;
const PLASTIC: &str = r#"{"type": "ggx_plastic", "diffuse": [0.2, 0.4, 0.7], "specular": [1, 1, 1], "alpha": 0.15, "ior": 1.5}"#;
const GLTF: &str =
    r#"{"type": "gltf", "base_color": [0.9, 0.5, 0.2], "metallic": 0.4, "roughness": 0.45}"#;

/// A cuts bake of 2048 environment lights (binary visibility, the default).
fn bake(material: &str) -> (Baked, Scene) {
    bake_with(material, CutFunction::Visibility)
}

/// A cuts bake of 2048 environment lights whose cuts approximate `function`.
fn bake_with(material: &str, function: CutFunction) -> (Baked, Scene) {
    let d = desc(material);
    let scene = d.build(Path::new("<test>")).expect("scene");
    let input = BakeInput {
        desc: &d,
        scene: &scene,
        origin: Path::new("<test>"),
    };
    let settings = CutsBakeSettings {
        lights: 2048,
        function,
        ..Default::default()
    };
    let n = scene.mesh.vertex_count();
    let b = Cuts::bake(input, &settings, 0..n, &BakeContext::default()).expect("bake");
    (b.into(), scene)
}

fn cuts_of(b: &Baked) -> &CutsBaked {
    match b {
        Baked::Cuts(c) => c,
        _ => unreachable!("a cuts bake"),
    }
}

fn opts() -> FrameOptions {
    FrameOptions {
        supersample: 2,
        background: false,
    }
}

/// The CPU reference: the CPU frame's light cut (`CutsFrame::set_environment`'s calls) and
/// the per-sample merge, with the scene's materials and the cluster spread on.
fn cpu(b: &Baked, s: &CutsFrameSettings, scene: &Scene) -> (Image, Vec<f32>) {
    let c = cuts_of(b);
    let power = sample_power(&c.bake.samples, &scene.env).expect("power");
    let light =
        LightCut::build(&c.bake.tree, &power, s.light_sigma, s.light_cut).expect("light cut");
    let shader = CutsShader::new(
        &c.scene.mesh,
        c.scene.materials.clone(),
        &c.bake,
        c.settings.function,
    )
    .with_cluster_spread(s.cluster_spread);
    let r = shader.render_per_fragment(
        &light,
        &scene.camera,
        None,
        &RasterOptions {
            supersample: opts().supersample,
        },
    );
    (r.image, r.coverage)
}

fn gpu_render(
    gpu: &Gpu,
    b: &Baked,
    s: &CutsFrameSettings,
    env: &Environment,
    scene: &Scene,
) -> GpuOutput {
    let mut f = frame_of(gpu, b, &FrameSettings::Cuts(s.clone())).expect("gpu frame");
    f.set_environment(env).expect("gpu env");
    eprintln!("{}", f.summary());
    f.render(&scene.camera, &opts()).expect("gpu render")
}

/// Compare: `Ok` with a line of the measured differences when within the tolerances.
fn compare(cpu: &(Image, Vec<f32>), gpu: &GpuOutput) -> Result<String, String> {
    let (img, cov) = cpu;
    assert_eq!((img.width, img.height), (gpu.image.width, gpu.image.height));
    let peak = img
        .pixels
        .iter()
        .fold(0.0f32, |m, p| m.max(p.max_element()));
    let floor = FLOOR * peak;
    let (mut coverage_diff, mut rel) = (0usize, Vec::new());
    for (k, (&cc, &gc)) in cov.iter().zip(&gpu.coverage).enumerate() {
        if (cc - gc).abs() > 1e-6 {
            coverage_diff += 1;
        }
        if cc >= 1.0 && gc >= 1.0 {
            let (c, g) = (img.pixels[k], gpu.image.pixels[k]);
            let e = (g - c).abs().max_element() / c.max_element().max(floor);
            rel.push(if e.is_finite() { e } else { f32::INFINITY });
        }
    }
    let n = rel.len().max(1) as f32;
    let beyond = rel.iter().filter(|&&e| e > REL_TOL).count() as f32 / n;
    let mean = rel.iter().sum::<f32>() / n;
    let max = rel.iter().fold(0.0f32, |m, &e| m.max(e));
    let s = format!(
        "{} of {} pixels compared, {coverage_diff} coverage differences, {beyond:.4} beyond {REL_TOL}, mean {mean:.2e}, max {max:.2e}",
        rel.len(),
        img.pixels.len()
    );
    eprintln!("{s}");
    if (rel.len() as f32) < 0.3 * img.pixels.len() as f32 {
        return Err(format!("too few pixels compared: {s}"));
    }
    if coverage_diff as f32 > MAX_COVERAGE_DIFF * img.pixels.len() as f32 {
        return Err(format!("coverage differs: {s}"));
    }
    if beyond > MAX_OUTLIERS || mean > MEAN_TOL {
        return Err(format!("radiance differs: {s}"));
    }
    Ok(s)
}

/// The environment rotated by 90 degrees about y (another light cut).
fn rotated(env: &Environment) -> Environment {
    let mut e = env.clone();
    e.rotate_y_deg += 90.0;
    e
}

#[test]
fn cuts_frame_lambert_matches_the_per_sample_merge() {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = bake(LAMBERT);
    let s = CutsFrameSettings::default();
    let c = cpu(&b, &s, &scene);
    let g = gpu_render(&gpu, &b, &s, &scene.env, &scene);
    assert!(g.stats.draw_calls == 2 && g.stats.passes == 2);
    compare(&c, &g).unwrap();
    // Negative control: the light cut of another rotation.
    let g = gpu_render(&gpu, &b, &s, &rotated(&scene.env), &scene);
    assert!(compare(&c, &g).is_err());
}

/// The GPU frame of `material` against the CPU frame, with two negative controls that must
/// fail the comparison: the light cut of another rotation, and the frame without the cluster
/// spread (the five-point rule must be what the GPU evaluates).
fn matches_with_controls(material: &str) {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = bake(material);
    let s = CutsFrameSettings::default();
    assert!(s.cluster_spread, "the CPU frame's default");
    let c = cpu(&b, &s, &scene);
    let g = gpu_render(&gpu, &b, &s, &scene.env, &scene);
    compare(&c, &g).unwrap();
    let g = gpu_render(&gpu, &b, &s, &rotated(&scene.env), &scene);
    assert!(compare(&c, &g).is_err());
    let off = CutsFrameSettings {
        cluster_spread: false,
        ..s
    };
    let g = gpu_render(&gpu, &b, &off, &scene.env, &scene);
    assert!(compare(&c, &g).is_err());
}

#[test]
fn cuts_frame_ggx_conductor_matches_the_per_sample_merge() {
    matches_with_controls(CONDUCTOR);
}

#[test]
fn cuts_frame_ggx_plastic_matches_the_per_sample_merge() {
    matches_with_controls(PLASTIC);
}

/// The glTF BRDF (Appendix B, `gltf_pbr`) ported to WGSL, against the CPU frame.
#[test]
fn cuts_frame_gltf_matches_the_per_sample_merge() {
    matches_with_controls(GLTF);
}

#[test]
fn cuts_frame_over_visibility_cosine_cuts_matches() {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = bake_with(CONDUCTOR, CutFunction::VisibilityCosine);
    let s = CutsFrameSettings::default();
    let c = cpu(&b, &s, &scene);
    let g = gpu_render(&gpu, &b, &s, &scene.env, &scene);
    compare(&c, &g).unwrap();
    // Negative control: the same cuts read as binary visibility (the cosine counted twice).
    let mut as_visibility = b.clone();
    if let Baked::Cuts(c) = &mut as_visibility {
        c.settings.function = CutFunction::Visibility;
    }
    let g = gpu_render(&gpu, &as_visibility, &s, &scene.env, &scene);
    assert!(compare(&c, &g).is_err());
}

#[test]
fn unsupported_materials_are_refused_by_name() {
    let Some(gpu) = gpu() else { return };
    let (b, _) = bake(LAMBERT);
    let phong = Material::BlinnPhong {
        diffuse: Vec3::splat(0.5),
        specular: Vec3::splat(0.3),
        exponent: 20.0,
    };
    let s = CutsFrameSettings {
        material: Some(phong.into()),
        ..Default::default()
    };
    let e = frame_of(&gpu, &b, &FrameSettings::Cuts(s))
        .err()
        .expect("Blinn-Phong is refused")
        .to_string();
    assert!(
        e.contains("BlinnPhong") && e.contains("not supported on the GPU"),
        "{e}"
    );
}

/// A bundle whose material has a texture map is refused by the GPU frame, naming the
/// material and the map with its non-default sampler and texture transform (which the GPU
/// does not read).
#[test]
fn textured_materials_are_refused_with_their_sampling() {
    use relight_scene::material::maps::{MaterialMaps, SceneMaps};
    use relight_scene::texture::{Filter, Sampler, Texture, UvTransform, Wrap};
    use std::sync::Arc;
    let Some(gpu) = gpu() else { return };
    let (mut b, _) = bake(LAMBERT);
    let Baked::Cuts(c) = &mut b else {
        unreachable!("a cuts bake")
    };
    let n = c.scene.mesh.vertex_count();
    c.scene.mesh.uvs = Some(vec![glam::Vec2::splat(0.5); n]);
    let tex = Texture::constant(Vec3::splat(0.5))
        .expect("texture")
        .with_sampler(Sampler {
            wrap_s: Wrap::ClampToEdge,
            wrap_t: Wrap::Repeat,
            filter: Filter::Nearest,
        })
        .with_transform(Some(UvTransform {
            rotation: 0.5,
            ..UvTransform::default()
        }));
    let maps = MaterialMaps {
        diffuse: Some(tex),
        ..MaterialMaps::default()
    };
    let per = vec![Some(Arc::new(maps)), None];
    c.scene.maps = SceneMaps::new(&c.scene.mesh, per).expect("maps");
    let e = frame_of(&gpu, &b, &FrameSettings::Cuts(CutsFrameSettings::default()))
        .err()
        .expect("a textured material is refused")
        .to_string();
    assert!(
        e.contains("material 0 (lambert)")
            && e.contains(
                "diffuse (wrap clamp-to-edge x repeat, nearest filter, KHR_texture_transform)"
            )
            && e.contains("not supported by --method cuts --gpu"),
        "{e}"
    );
}
