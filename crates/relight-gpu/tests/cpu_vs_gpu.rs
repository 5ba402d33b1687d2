//! Every GPU frame against the CPU frame of the same bake, environment, camera and options,
//! pixel by pixel, with a negative control per method (a broken input must fail the same
//! comparison). Skips with a printed reason where no Vulkan adapter exists, and fails
//! instead under `RELIGHT_REQUIRE_REFERENCE=1` (CI installs lavapipe).
//!
//! # Tolerances, and where the differences come from
//! * **Silhouettes**: the GPU decides samples exactly on an edge by the top-left rule, the
//!   CPU by a `(-e, e^2)` nudge, and both evaluate edge functions in f32 in different
//!   orders, so a sample that grazes an edge can be covered by one and not the other. Only
//!   pixels fully covered in both images are compared; the pixels whose coverage differs
//!   are counted and bounded (`MAX_COVERAGE_DIFF`).
//! * **Arithmetic**: f32 on both sides, in different orders (the CPU's AVX2 SH dot product
//!   in 8-wide blocks of fused multiply-adds against the GPU's sequential loop; the
//!   rasteriser's interpolation), and the GPU's transcendental functions (exp, log, acos,
//!   tan) within a few ulp: relative differences of order 1e-6, bounded by `REL_TOL` =
//!   1e-3 (pixels darker than `FLOOR` x the image's brightest are compared in absolute
//!   terms against that floor).
//! * **SG lobe matching** runs once per triangle on the GPU with the CPU's distance and
//!   rules; a matching pass writing identities fails `sg_frame_matches_the_cpu_frame` (10 %
//!   of the pixels beyond `REL_TOL`, tried 2026-12-02).
//! * **Visibility ties**: where two surfaces are at nearly the same depth (the sphere
//!   touching its plane) the z-tests in different f32 forms may pick different triangles:
//!   a few pixels, inside `MAX_OUTLIERS`.
//! * **Shadow maps** (`hybrid`): the depth maps are rasterised by the GPU (top-left rule)
//!   instead of the CPU's inclusive rule, so texels on a triangle edge can differ, and with
//!   them the PCSS blocker depths and penumbra widths near such texels. Bounded separately,
//!   looser (`HYBRID_*`).

use glam::Vec3;
use relight_bake::sh::ShBakeSettings;
use relight_gpu::{frame_of, Gpu, GpuError, GpuOutput};
use relight_method::hybrid::HybridSettings;
use relight_method::sg::{Sg, SgSettings};
use relight_method::sh::Sh;
use relight_method::{
    BakeContext, BakeInput, Baked, FrameOptions, FrameSettings, Method, MethodKind,
};
use relight_render::raster::{self, RasterOptions};
use relight_render::Image;
use relight_scene::camera::Camera;
use relight_scene::scene::Scene;
use relight_scene::scene_file::SceneDesc;
use std::path::Path;

/// Relative tolerance of a fully covered pixel (module docs: f32 in different orders).
const REL_TOL: f32 = 1e-3;
/// Pixels darker than this fraction of the brightest are compared against it.
const FLOOR: f32 = 1e-3;
/// Fully covered pixels allowed beyond `REL_TOL` (visibility ties): 0.5 %.
const MAX_OUTLIERS: f32 = 0.005;
/// Pixels whose coverage differs (silhouette samples on edges): 0.5 % of the pixels; a
/// 96 x 64 image of these scenes has a few hundred silhouette pixels, of which only samples
/// within f32 rounding of an edge can differ (none did on lavapipe, 2026-12-02).
const MAX_COVERAGE_DIFF: f32 = 0.005;
/// Hybrid: the outliers' threshold, 1 %.
const HYBRID_TOL: f32 = 0.01;
/// Hybrid: pixels beyond `HYBRID_TOL` (shadow-map texels on triangle edges, and through them
/// blocker depths and penumbra widths), at most 1 % (lavapipe, 2026-12-02: none; largest
/// difference 4.8e-6 with the sun as a point light, 1.1e-3 with three discs as point lights,
/// 2.0e-3 and 7.6e-3 as area lights).
const HYBRID_OUTLIERS: f32 = 0.01;
/// Hybrid: mean relative error over fully covered pixels (measured: at most 1.0e-5). Tight
/// enough that a blocker search without the maps' pyramids fails it (three area lights:
/// mean 4.7e-4, tried 2026-12-02).
const HYBRID_MEAN: f32 = 1e-4;

/// The device, or `None` after a skip (a failure under `RELIGHT_REQUIRE_REFERENCE=1`).
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

/// A sphere on a plane under a sun and sky (a sun for hybrid's lights), 96 x 64.
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

fn bake<M: Method>(d: &SceneDesc, settings: &M::Settings) -> (M::Baked, Scene) {
    let scene = d.build(Path::new("<test>")).expect("scene");
    let input = BakeInput {
        desc: d,
        scene: &scene,
        origin: Path::new("<test>"),
    };
    let n = scene.mesh.vertex_count();
    let b = M::bake(input, settings, 0..n, &BakeContext::default()).expect("bake");
    (b, scene)
}

fn sh_bake() -> (Baked, Scene) {
    let (b, s) = bake::<Sh>(
        &desc(LAMBERT),
        &ShBakeSettings {
            order: 4,
            samples: 64,
            seed: 2,
            ..Default::default()
        },
    );
    (b.into(), s)
}

fn sg_bake() -> (Baked, Scene) {
    sg_bake_with(2, Default::default())
}

/// The conductor scene baked with `direct_lobes` lobes (6 x 8 x 8, no indirect lobe, SH
/// order 3) and the fit settings `fit`.
fn sg_bake_with(direct_lobes: usize, fit: relight_bake::sg::SgFitSettings) -> (Baked, Scene) {
    let settings = SgSettings {
        bake: relight_bake::sg::SgBakeSettings {
            direct_res: 8,
            indirect_lobes: 0,
            direct_lobes,
            diffuse_order: 3,
            fit,
            ..Default::default()
        },
        blend: None,
    };
    let (b, s) = bake::<Sg>(&desc(CONDUCTOR), &settings);
    (b.into(), s)
}

/// The CPU frame and its coverage (a coverage-only raster of the same mesh and options).
fn cpu(b: &Baked, fs: &FrameSettings, scene: &Scene, opts: &FrameOptions) -> (Image, Vec<f32>) {
    let mut f = b.frame(fs).expect("cpu frame");
    f.set_environment(&scene.env).expect("cpu env");
    let img = f.render(&scene.camera, opts).image;
    let mesh = &b.scene().mesh;
    let cov = raster::render_with(
        mesh,
        &scene.camera,
        &vec![Vec3::ONE; mesh.vertex_count()],
        None,
        &RasterOptions {
            supersample: opts.supersample,
        },
    )
    .coverage;
    (img, cov)
}

fn gpu_render(
    gpu: &Gpu,
    b: &Baked,
    fs: &FrameSettings,
    scene: &Scene,
    opts: &FrameOptions,
) -> GpuOutput {
    let mut f = frame_of(gpu, b, fs).expect("gpu frame");
    f.set_environment(&scene.env).expect("gpu env");
    f.render(&scene.camera, opts).expect("gpu render")
}

/// Differences of a GPU frame from the CPU frame (module docs).
#[derive(Debug)]
struct Diff {
    pixels: usize,
    /// Fully covered in both.
    compared: usize,
    coverage_diff: usize,
    /// Relative errors of the compared pixels.
    rel: Vec<f32>,
}

impl Diff {
    fn of(cpu: &(Image, Vec<f32>), gpu: &GpuOutput) -> Diff {
        let (img, cov) = cpu;
        assert_eq!((img.width, img.height), (gpu.image.width, gpu.image.height));
        let peak = img
            .pixels
            .iter()
            .fold(0.0f32, |m, p| m.max(p.max_element()));
        let floor = FLOOR * peak;
        let mut d = Diff {
            pixels: img.pixels.len(),
            compared: 0,
            coverage_diff: 0,
            rel: vec![],
        };
        for (k, (&cc, &gc)) in cov.iter().zip(&gpu.coverage).enumerate() {
            if (cc - gc).abs() > 1e-6 {
                d.coverage_diff += 1;
            }
            if cc >= 1.0 && gc >= 1.0 {
                d.compared += 1;
                let (c, g) = (img.pixels[k], gpu.image.pixels[k]);
                let e = (g - c).abs().max_element() / c.max_element().max(floor);
                d.rel.push(if e.is_finite() { e } else { f32::INFINITY });
            }
        }
        d
    }

    fn beyond(&self, tol: f32) -> f32 {
        self.rel.iter().filter(|&&e| e > tol).count() as f32 / self.compared.max(1) as f32
    }

    fn mean(&self) -> f32 {
        self.rel.iter().sum::<f32>() / self.compared.max(1) as f32
    }

    /// `Ok` when within the tolerances: `(tol, share beyond it, mean)`.
    fn check(&self, tol: f32, outliers: f32, mean: f32) -> Result<(), String> {
        let s = format!(
            "{} of {} pixels compared, {} coverage differences, {:.4} beyond {tol}, mean {:.2e}, max {:.2e}",
            self.compared,
            self.pixels,
            self.coverage_diff,
            self.beyond(tol),
            self.mean(),
            self.rel.iter().fold(0.0f32, |m, &e| m.max(e)),
        );
        eprintln!("{s}");
        // The objects must cover a good part of the image, or the test proves little.
        if (self.compared as f32) < 0.3 * self.pixels as f32 {
            return Err(format!("too few pixels compared: {s}"));
        }
        if self.coverage_diff as f32 > MAX_COVERAGE_DIFF * self.pixels as f32 {
            return Err(format!("coverage differs: {s}"));
        }
        if self.beyond(tol) > outliers || self.mean() > mean {
            return Err(format!("radiance differs: {s}"));
        }
        Ok(())
    }
}

fn opts() -> FrameOptions {
    FrameOptions {
        supersample: 2,
        background: false,
    }
}

/// A copy of an sh bake with all transfer coefficients zero (the negative control).
fn zero_transfer(b: &Baked) -> Baked {
    let mut z = b.clone();
    if let Baked::Sh(s) = &mut z {
        s.transfer.data.iter_mut().for_each(|t| *t = 0.0);
    }
    z
}

#[test]
fn sh_frame_matches_the_cpu_frame() {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = sh_bake();
    let fs = FrameSettings::default_for(MethodKind::Sh);
    let c = cpu(&b, &fs, &scene, &opts());
    let g = gpu_render(&gpu, &b, &fs, &scene, &opts());
    assert!(
        g.stats.adapter == gpu.adapter_name() && g.stats.draw_calls == 2 && g.stats.passes == 2
    );
    // Per frame only the camera and the resolve parameters are uploaded.
    assert_eq!(g.stats.bytes_uploaded, 80 + 16);
    Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .unwrap();
    // Negative control: zeroed coefficients render black, which the comparison refuses.
    let z = zero_transfer(&b);
    let g = gpu_render(&gpu, &z, &fs, &scene, &opts());
    assert!(Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .is_err());
}

#[test]
fn the_background_is_the_cpu_frames() {
    let Some(gpu) = gpu() else { return };
    let (b, mut scene) = sh_bake();
    // A rotated, scaled environment: the background must follow both.
    scene.env.rotate_y_deg = 70.0;
    scene.env.scale = 1.5;
    let fs = FrameSettings::default_for(MethodKind::Sh);
    let o = FrameOptions {
        supersample: 2,
        background: true,
    };
    let c = cpu(&b, &fs, &scene, &o);
    let g = gpu_render(&gpu, &b, &fs, &scene, &o);
    Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .unwrap();
    // Pixels that see only the environment (the sky above the plane's far edge): the same
    // bilinear fetch, with the direction's atan2 and acos in the GPU's f32, within 1e-3.
    let (img, cov) = &c;
    let mut n = 0;
    for (k, (&cc, &gc)) in cov.iter().zip(&g.coverage).enumerate() {
        if cc == 0.0 && gc == 0.0 {
            let (cp, gp) = (img.pixels[k], g.image.pixels[k]);
            let e = (gp - cp).abs().max_element() / cp.max_element();
            assert!(e < REL_TOL, "background pixel {k}: cpu {cp} gpu {gp}");
            n += 1;
        }
    }
    assert!(n > 300, "{n} background pixels");
    // Negative control: without the background those pixels are black.
    let g = gpu_render(&gpu, &b, &fs, &scene, &opts());
    let k = cov.iter().position(|&c| c == 0.0).unwrap();
    assert_eq!(g.image.pixels[k], Vec3::ZERO);
    assert!(img.pixels[k].min_element() > 0.0);
}

#[test]
fn sh_frame_matches_without_supersampling_and_at_a_lower_order() {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = sh_bake();
    let fs = FrameSettings::Sh(relight_method::sh::ShFrameSettings {
        window: relight_sphere::sh::Window::Hann,
        sh_order: Some(3),
    });
    let o = FrameOptions {
        supersample: 1,
        background: false,
    };
    let c = cpu(&b, &fs, &scene, &o);
    let g = gpu_render(&gpu, &b, &fs, &scene, &o);
    Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .unwrap();
}

fn hybrid_case(settings: HybridSettings) {
    let (b, scene) = sh_bake();
    hybrid_case_in(settings, b, scene);
}

/// Three discs over a sky (a cube map): three lights, three shadow-map layers.
fn three_suns(scene: &mut Scene) {
    let discs = [
        (
            Vec3::new(0.3, 0.8, 0.2).normalize(),
            2.0,
            Vec3::splat(300.0),
        ),
        (
            Vec3::new(-0.6, 0.5, -0.3).normalize(),
            3.0,
            Vec3::new(120.0, 90.0, 60.0),
        ),
        (
            Vec3::new(0.1, 0.6, 0.9).normalize(),
            2.5,
            Vec3::splat(150.0),
        ),
    ];
    scene.env = relight_scene::scene::Environment::new(relight_sphere::decompose::sky_with_discs(
        64, &discs,
    ));
}

#[test]
fn hybrid_frame_with_three_point_lights_matches_the_cpu_frame() {
    let (b, mut scene) = sh_bake();
    three_suns(&mut scene);
    hybrid_case_in(
        HybridSettings {
            shadow_map_size: 512,
            thesis: true,
            ..Default::default()
        },
        b,
        scene,
    );
}

#[test]
fn hybrid_frame_with_three_area_lights_matches_the_cpu_frame() {
    let (b, mut scene) = sh_bake();
    three_suns(&mut scene);
    hybrid_case_in(
        HybridSettings {
            shadow_map_size: 512,
            ..Default::default()
        },
        b,
        scene,
    );
}

fn hybrid_case_in(settings: HybridSettings, b: Baked, scene: Scene) {
    let Some(gpu) = gpu() else { return };
    let fs = FrameSettings::Hybrid(settings);
    // The sky's sun must give at least one light, or shadows are not tested.
    let d = settings.resolve(4).unwrap().0;
    let lights = relight_method::hybrid::decompose_env(&scene.env, &d)
        .unwrap()
        .lights
        .len();
    assert!(lights >= 1, "no light extracted");
    eprintln!("{lights} lights");
    let c = cpu(&b, &fs, &scene, &opts());
    let mut f = frame_of(&gpu, &b, &fs).unwrap();
    f.set_environment(&scene.env).unwrap();
    let g = f.render(&scene.camera, &opts()).unwrap();
    assert_eq!(g.stats.shadow_maps_rendered as usize, lights);
    // One depth pass per light, the pyramids (compute), shading, resolve.
    assert_eq!(g.stats.passes as usize, lights + 3);
    Diff::of(&c, &g)
        .check(HYBRID_TOL, HYBRID_OUTLIERS, HYBRID_MEAN)
        .unwrap();
    // The shadow maps are cached: the next frame renders none, and the same image.
    let g2 = f.render(&scene.camera, &opts()).unwrap();
    assert_eq!((g2.stats.shadow_maps_rendered, g2.stats.passes), (0, 2));
    assert_eq!(g2.image.pixels, g.image.pixels);
    // The same lights again (a new scale moves no light): still cached.
    let mut brighter = scene.env.clone();
    brighter.scale *= 2.0;
    f.set_environment(&brighter).unwrap();
    let g2 = f.render(&scene.camera, &opts()).unwrap();
    assert_eq!(g2.stats.shadow_maps_rendered, 0);
    // ... and the kept maps and pyramids still give the CPU frame.
    let bright = Scene {
        maps: Default::default(),
        env: brighter.clone(),
        ..scene.clone()
    };
    Diff::of(&cpu(&b, &fs, &bright, &opts()), &g2)
        .check(HYBRID_TOL, HYBRID_OUTLIERS, HYBRID_MEAN)
        .unwrap();
    // A rotated environment moves the lights: rendered again.
    let mut turned = scene.env.clone();
    turned.rotate_y_deg += 40.0;
    f.set_environment(&turned).unwrap();
    let g3 = f.render(&scene.camera, &opts()).unwrap();
    assert_eq!(g3.stats.shadow_maps_rendered as usize, lights);
    // Negative control: without the SH part the comparison fails.
    let z = zero_transfer(&b);
    let g = gpu_render(&gpu, &z, &fs, &scene, &opts());
    assert!(Diff::of(&c, &g)
        .check(HYBRID_TOL, HYBRID_OUTLIERS, HYBRID_MEAN)
        .is_err());
}

#[test]
fn hybrid_frame_with_the_thesis_point_lights_matches_the_cpu_frame() {
    hybrid_case(HybridSettings {
        shadow_map_size: 512,
        thesis: true,
        ..Default::default()
    });
}

#[test]
fn hybrid_frame_with_area_lights_matches_the_cpu_frame() {
    hybrid_case(HybridSettings {
        shadow_map_size: 512,
        ..Default::default()
    });
}

#[test]
fn sg_frame_matches_the_cpu_frame() {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = sg_bake();
    let fs = FrameSettings::Sg(relight_method::sg::SgFrameSettings {
        prefilter_size: 64,
        ..Default::default()
    });
    let c = cpu(&b, &fs, &scene, &opts());
    let g = gpu_render(&gpu, &b, &fs, &scene, &opts());
    // Per frame: the blended lobes (32 bytes each) and diffuse radiance (16) of every vertex.
    let v = b.scene().mesh.vertex_count() as u64;
    assert_eq!(g.stats.bytes_uploaded, v * (2 * 32 + 16) + 80 + 16);
    // The matching pass (compute), the shading pass, the resolve pass.
    assert_eq!((g.stats.passes, g.stats.draw_calls), (3, 2));
    Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .unwrap();
    // Negative control: lobes without amplitude leave the diffuse part only.
    let mut z = b.clone();
    if let Baked::Sg(s) = &mut z {
        s.bake
            .direct
            .lobes
            .iter_mut()
            .for_each(|l| l.amplitude = Vec3::ZERO);
    }
    let g = gpu_render(&gpu, &z, &fs, &scene, &opts());
    assert!(Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .is_err());
}

/// The GGX-shaped lobe kernel (`relight_sphere::sg_kernel`, four Gaussian terms per lobe in
/// the corner blend's energies and in the prefiltered fetches): the same lobes read with that
/// kernel on both sides. Control: the GPU reading them as Gaussians is off.
#[test]
fn sg_frame_with_the_ggx_kernel_matches_the_cpu_frame() {
    let Some(gpu) = gpu() else { return };
    let (mut b, scene) = sg_bake();
    let fs = FrameSettings::Sg(relight_method::sg::SgFrameSettings {
        prefilter_size: 64,
        ..Default::default()
    });
    let gaussian = b.clone();
    if let Baked::Sg(s) = &mut b {
        s.bake.kernel = relight_sphere::sg_kernel::LobeKernel::Ggx;
    }
    let c = cpu(&b, &fs, &scene, &opts());
    let g = gpu_render(&gpu, &b, &fs, &scene, &opts());
    Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .unwrap();
    let g = gpu_render(&gpu, &gaussian, &fs, &scene, &opts());
    assert!(Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .is_err());
}

#[test]
fn what_the_gpu_does_not_render_is_refused_by_name() {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = sh_bake();
    let fs = FrameSettings::default_for(MethodKind::Sh);
    let mut f = frame_of(&gpu, &b, &fs).unwrap();
    let e = f.render(&scene.camera, &opts()).err().unwrap().to_string();
    assert!(e.contains("set_environment"), "{e}");
    f.set_environment(&scene.env).unwrap();
    let e = frame_of(&gpu, &b, &FrameSettings::default_for(MethodKind::Sg))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("holds a `sh` bake"), "{e}");
    let huge = Camera {
        width: 100_000,
        ..scene.camera
    };
    assert!(f.render(&huge, &opts()).is_err());
}

/// Lobes in the half-vector domain (`--lobe-domain half-vector`, one GGX-kernel lobe): the
/// warp table's five fetches per Gaussian term (`sg_half.wgsl`) and the blends' kept
/// integrals (`keep_mass`, each vertex's unit mass uploaded in the lobe's fourth amplitude
/// component) against the CPU frame. Control: the GPU reading the same lobes in the light
/// domain is off.
#[test]
fn sg_frame_with_half_vector_lobes_matches_the_cpu_frame() {
    let Some(gpu) = gpu() else { return };
    let (b, scene) = sg_bake_with(
        1,
        relight_bake::sg::SgFitSettings {
            lobe_kernel: relight_bake::sg::SgKernel::Ggx,
            lobe_domain: relight_bake::sg::SgDomain::HalfVector,
            ..Default::default()
        },
    );
    let fs = FrameSettings::Sg(relight_method::sg::SgFrameSettings {
        prefilter_size: 64,
        ..Default::default()
    });
    let c = cpu(&b, &fs, &scene, &opts());
    let g = gpu_render(&gpu, &b, &fs, &scene, &opts());
    Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .unwrap();
    let mut light = b.clone();
    if let Baked::Sg(s) = &mut light {
        s.bake.domain = relight_bake::sg::SgDomain::Light;
    }
    let g = gpu_render(&gpu, &light, &fs, &scene, &opts());
    assert!(Diff::of(&c, &g)
        .check(REL_TOL, MAX_OUTLIERS, REL_TOL)
        .is_err());
}
