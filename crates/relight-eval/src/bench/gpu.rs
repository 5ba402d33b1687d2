//! The GPU renderer (section "GPU", feature `gpu`): frames of `sh`, `hybrid`, `sg` at
//! 1280 x 720 and `cuts` at 320 x 180 on the Vulkan adapter relight-gpu picks (lavapipe on a machine without a GPU),
//! each next to the CPU frame of the same bake, environment and camera measured in the same
//! run; the CPU-side work a frame needs against a 2 ms budget; and the per-frame counts
//! (passes, draw calls, bytes uploaded) that carry over to a real GPU.
//!
//! Lavapipe is Mesa's CPU rasteriser: its frame times are those of a software renderer on
//! this machine's cores (shared with the CPU frame's threads), correctness-level figures
//! only. The counts are what a real GPU would see.

use super::{median, Section};
use relight_bake::sh::ShBakeSettings;
use relight_gpu::{frame_of, Gpu, GpuFrame};
use relight_method::hybrid::{decompose_env, HybridSettings};
use relight_method::sg::{Sg, SgSettings};
use relight_method::sh::{world_light, Sh};
use relight_method::{
    BakeContext, BakeInput, Baked, FrameOptions, FrameSettings, Method, MethodKind,
};
use relight_scene::scene::Scene;
use relight_scene::scene_file::SceneDesc;
use relight_sphere::sh::Window;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// Per-frame CPU budget of the viewer: the CPU-side work of one frame must leave room for
/// interactive rates.
const BUDGET_MS: f64 = 2.0;

/// A sphere of `rings` rings on a plane under a sun and sky, camera 1280 x 720.
fn desc(rings: u32, material: &str) -> SceneDesc {
    serde_json::from_str(&format!(
        r#"{{"shapes": [
              {{"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": {rings},
               "material": {material}}},
              {{"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 32,
               "material": {{"type": "lambert", "albedo": [0.6, 0.6, 0.6]}}}}],
            "environment": {{"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 30,
                            "turbidity": 3, "ground_albedo": [0.3, 0.3, 0.3]}},
            "camera": {{"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 1280, "height": 720}}}}"#
    ))
    .expect("bench scene")
}

fn bake<M: Method>(d: &SceneDesc, s: &M::Settings) -> crate::Result<(Baked, Scene)>
where
    Baked: From<M::Baked>,
{
    let scene = d.build(Path::new("<bench>"))?;
    let input = BakeInput {
        desc: d,
        scene: &scene,
        origin: Path::new("<bench>"),
    };
    let n = scene.mesh.vertex_count();
    let b = M::bake(input, s, 0..n, &BakeContext::default())
        .map_err(|e| crate::EvalError::Options(format!("bench gpu: bake: {e}")))?;
    Ok((b.into(), scene))
}

/// Median milliseconds of `runs` calls after a warm-up.
fn med(runs: usize, mut f: impl FnMut()) -> f64 {
    f();
    median(
        (0..runs.max(1))
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

/// The two tables of the section, or one line saying why there is no GPU.
pub(super) fn sections(quick: bool) -> crate::Result<Vec<Section>> {
    let gpu = match Gpu::new() {
        Ok(g) => g,
        Err(e) => {
            let mut s = Section::new("GPU renderer: no adapter", &["reason"]);
            s.row(vec![json!(e.to_string())]);
            return Ok(vec![s]);
        }
    };
    let runs = if quick { 2 } else { 5 };
    let opts = FrameOptions {
        supersample: 1,
        background: false,
    };
    let (sh, sh_scene) = bake::<Sh>(
        &desc(
            if quick { 32 } else { 96 },
            r#"{"type": "lambert", "albedo": [0.8, 0.3, 0.2]}"#,
        ),
        &ShBakeSettings {
            order: 5,
            samples: 64,
            seed: 2,
            ..Default::default()
        },
    )?;
    let sg_settings = SgSettings {
        bake: relight_bake::sg::SgBakeSettings {
            direct_res: 8,
            indirect_lobes: 0,
            direct_lobes: 2,
            ..Default::default()
        },
        blend: None,
    };
    let (sg, sg_scene) = bake::<Sg>(
        &desc(
            if quick { 8 } else { 16 },
            r#"{"type": "ggx_conductor", "specular": [0.9, 0.7, 0.4], "alpha": 0.2}"#,
        ),
        &sg_settings,
    )?;
    // cuts: 4096 environment lights (the paper's 32K would bake for minutes on 2 cores), at
    // 320 x 180: lavapipe runs the per-sample merge on the CPU's cores (a 320 x 240 frame of
    // a 1514-vertex sphere and plane took 12.7 s, 2026-12-02), so 1280 x 720 would take
    // minutes per frame.
    let (cuts, mut cuts_scene) = bake::<relight_method::cuts::Cuts>(
        &desc(
            if quick { 8 } else { 16 },
            r#"{"type": "ggx_conductor", "specular": [0.9, 0.7, 0.4], "alpha": 0.2}"#,
        ),
        &relight_bake::cuts::CutsBakeSettings {
            lights: 4096,
            ..Default::default()
        },
    )?;
    (cuts_scene.camera.width, cuts_scene.camera.height) = (320, 180);
    let title = format!(
        "GPU renderer: frames at 1280 x 720 (cuts: 320 x 180), 1 sample per pixel, on {} (lavapipe is a CPU rasteriser: correctness-level times; the counts carry over to a GPU)",
        gpu.adapter_name()
    );
    let mut frames = Section::new(
        title,
        &[
            "method",
            "pixels",
            "vertices",
            "CPU frame ms (median)",
            "GPU frame ms (median, read-back included)",
            "GPU / CPU",
            "GPU frame: CPU-side ms",
            "passes",
            "draw calls",
            "bytes uploaded",
            "shadow maps rendered (first frame / next)",
        ],
    );
    let cases = [
        (&sh, &sh_scene, FrameSettings::default_for(MethodKind::Sh)),
        (
            &sh,
            &sh_scene,
            FrameSettings::Hybrid(HybridSettings::default()),
        ),
        (&sg, &sg_scene, FrameSettings::default_for(MethodKind::Sg)),
        (
            &cuts,
            &cuts_scene,
            FrameSettings::default_for(MethodKind::Cuts),
        ),
    ];
    for (b, scene, fs) in &cases {
        let camera = scene.camera;
        let mut cpu = b
            .frame(fs)
            .map_err(|e| crate::EvalError::Options(e.to_string()))?;
        cpu.set_environment(&scene.env)
            .map_err(|e| crate::EvalError::Options(e.to_string()))?;
        let cpu_ms = med(runs, || drop(cpu.render(&camera, &opts)));
        let err = |e: relight_gpu::GpuError| crate::EvalError::Options(format!("bench gpu: {e}"));
        let mut g: Box<dyn GpuFrame> = frame_of(&gpu, b, fs).map_err(err)?;
        g.set_environment(&scene.env).map_err(err)?;
        let first = g.render(&camera, &opts).map_err(err)?.stats;
        let mut last = first.clone();
        let mut times = vec![];
        for _ in 0..runs {
            let t = Instant::now();
            last = g.render(&camera, &opts).map_err(err)?.stats;
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let gpu_ms = median(times);
        frames.row(vec![
            json!(fs.method().name()),
            json!(format!("{} x {}", camera.width, camera.height)),
            json!(b.scene().mesh.vertex_count()),
            json!(cpu_ms),
            json!(gpu_ms),
            json!(gpu_ms / cpu_ms),
            json!(last.cpu_ms),
            json!(last.passes),
            json!(last.draw_calls),
            json!(last.bytes_uploaded),
            json!(format!(
                "{} / {}",
                first.shadow_maps_rendered, last.shadow_maps_rendered
            )),
        ]);
    }

    // The CPU-side work of a frame when the environment turns (a viewer's rotation slider).
    let mut cpu = Section::new(
        format!("GPU renderer: CPU-side work per frame against a {BUDGET_MS} ms budget"),
        &["work", "ms (median)", "budget ms", "within"],
    );
    let mut row = |what: &str, ms: f64| {
        cpu.row(vec![
            json!(what),
            json!(ms),
            json!(BUDGET_MS),
            json!(if ms <= BUDGET_MS { "yes" } else { "no" }),
        ])
    };
    let env = &sh_scene.env;
    // SH rotation alone: the map's SH is kept, a rotation re-rotates it (order 5, 25 RGB).
    let c = relight_sphere::sh::project_env(&env.map, 5);
    let rot = env.world_from_env();
    row(
        "SH rotation, order 5 (sh: new lighting per rotation)",
        med(runs * 20, || {
            std::hint::black_box(relight_sphere::sh_rotate::ShRotation::new(5, rot).apply(&c));
        }),
    );
    row(
        "SH projection + rotation of the map, order 5 (sh: new environment)",
        med(runs, || drop(world_light(env, 5, Window::None))),
    );
    let d = HybridSettings::default()
        .resolve(5)
        .map_err(|e| crate::EvalError::Options(e.to_string()))?
        .0;
    row(
        &format!(
            "environment decomposition (hybrid; {} x {} map)",
            env.map.width(),
            env.map.height()
        ),
        med(runs, || drop(decompose_env(env, &d))),
    );
    row(
        "environment decomposition (hybrid; 6 x 64 x 64 cube map, sky + 3 discs)",
        median(
            (0..runs)
                .map(|_| super::hybrid::bench_decompose())
                .collect(),
        ),
    );
    if let Baked::Sg(b) = &sg {
        let r = relight_render::shade_sg::SgRenderer::new(&b.scene.mesh, &b.bake);
        let l = relight_render::shade_sg::SgLighting::new(&sg_scene.env, b.bake.diffuse.order, 128);
        let eye = glam::Vec3::from(sg_scene.camera.origin);
        row(
            &format!(
                "SG per-vertex view blend ({} vertices; per camera move)",
                b.scene.mesh.vertex_count()
            ),
            med(runs, || drop(r.prepare(&l, eye))),
        );
    }
    if let Baked::Cuts(b) = &cuts {
        let s = relight_method::cuts::CutsFrameSettings::default();
        let bk = &b.bake;
        let light_cut = || {
            relight_bake::cuts::samples::sample_power(&bk.samples, &cuts_scene.env).and_then(|p| {
                relight_bake::cuts::light_cut::LightCut::build(
                    &bk.tree,
                    &p,
                    s.light_sigma,
                    s.light_cut,
                )
            })
        };
        light_cut().map_err(|e| crate::EvalError::Options(format!("bench gpu: {e}")))?;
        row(
            &format!(
                "light samples' power + illumination cut (cuts; {} lights, {} nodes; per environment or rotation)",
                b.settings.lights, s.light_cut
            ),
            med(runs, || drop(light_cut())),
        );
    }
    Ok(vec![frames, cpu])
}
