//! The cuts frame (section "cuts-frame"; relight's target: a 512 x 512 frame at light cut
//! 256 at 6.4 fps, the paper's GPU figure for Hebe, on 2 cores).
//!
//! The whole mesh (`bunny.obj`, else a procedural sphere on a plane) is baked once with the
//! default settings (binary visibility) (32,768 lights; 4,096 with `quick`), then rendered at
//! 512 x 512, one sample per pixel, under a sky with a sun
//! (`super::cuts_bake::sky_with_sun`), for a Lambert, a GGX conductor and a GGX plastic
//! material (glossy ones with the frame's default cluster spread) at the light cuts
//! 128, 256 and 512 (256 only with `quick`). The default frame (`CutsShader::render`) first
//! merges every vertex's cut with the light cut (`CutsShader::prepare`: once per light cut,
//! timed apart, as a change of environment or rotation costs it), then each frame is split
//! into its stages ([`relight_render::shade_cuts::CutsStage`]): the G-buffer (rasterise and
//! group fragments by triangle) and the shading of every fragment (Lambert: its three
//! corners' lists summed; glossy: its triangle's merged cut, kept across frames,
//! `relight_render::shade_cuts` module `cache`). The frame is timed with the camera orbiting
//! by [`ORBIT_DEG`] per frame (each frame merges the triangles that came into view), then
//! with the environment also turning by [`ROTATE_DEG`] per frame (a new light cut every
//! frame, its frame from the kept visibility unions; the light cut's cost in its own
//! column), and again with nothing kept ("all merged": every visible triangle merged, as in
//! the very first frame of a shader). Measured in the same run: the previous default, the per-triangle merge
//! (`render_merged`: every visible triangle's three vertex cuts merged with the light cut
//! once per triangle and band of rows), and the **baseline**, the per-fragment merge
//! (`render_per_fragment`: the three cuts merged again at every fragment, the paper's
//! per-pixel algorithm as written).

use super::{median, process_cpu_ms, Section};
use crate::Result;
use glam::Vec3;
use relight_bake::cuts::light_cut::{LightCut, DEFAULT_LIGHT_SIGMA, LIGHT_CUT_BUDGETS};
use relight_bake::cuts::samples::{sample_power_with, NearestSample};
use relight_bake::cuts::visibility::CutFunction;
use relight_bake::cuts::{bake_range, CutsBakeSettings};
use relight_method::MethodError;
use relight_render::raster::{RasterOptions, Rendered};
use relight_render::shade_cuts::{CutsShader, CutsStage};
use relight_scene::accel;
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// The frame target, milliseconds (6.4 fps, module docs).
pub const TARGET_MS: f64 = 1e3 / 6.4;

/// Degrees the bench's camera orbits per frame (32 degrees per second at 6.4 fps: a brisk
/// turn of the model).
pub const ORBIT_DEG: f32 = 5.0;

/// Degrees the bench's environment turns per frame in the rotating run (every frame a new
/// light cut).
pub const ROTATE_DEG: f32 = 5.0;

/// The section: bake, then per function, material and light cut the corner lists and the
/// stages of the frame, against the per-triangle and the per-fragment merge.
///
/// # Errors
/// A mesh that cannot be read, or a bake that fails.
pub(super) fn section(
    bake_mesh: &Option<PathBuf>,
    data: &Option<PathBuf>,
    quick: bool,
) -> Result<Section> {
    let (name, mesh) = super::cuts_bake::bunny_or_sphere(bake_mesh, data)?;
    let (lo, hi) = mesh.bounds().expect("a non-empty mesh");
    let (centre, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    // The camera at `deg` degrees of an orbit about the vertical through the mesh's centre.
    let camera_at = |deg: f32| {
        let (s, c) = deg.to_radians().sin_cos();
        let d = Vec3::new(0.3, 0.4, 1.0).normalize();
        let eye = centre + Vec3::new(c * d.x + s * d.z, d.y, c * d.z - s * d.x) * radius * 2.6;
        Camera::look_at(eye.to_array(), centre.to_array(), 45.0, 512, 512)
    };
    let camera = camera_at(0.0);
    let env = super::cuts_bake::sky_with_sun();
    let caster = accel::build_default(&mesh);
    let lights = if quick {
        4096
    } else {
        CutsBakeSettings::default().lights
    };
    let bad = |e: relight_bake::cuts::CutsError| MethodError::Environment(e.to_string());
    let runs = if quick { 1 } else { 3 };
    let threads = rayon::current_num_threads();
    let mut sec = Section::new(
        format!(
            "Cuts frame 512 x 512, 1 spp: {name} ({} vertices), {lights} lights, sigma 2, \
             {threads} threads; per-fragment merge = baseline (same run)",
            mesh.vertex_count()
        ),
        &[
            "cut function",
            "mean cut",
            "material",
            "light cut",
            "corner lists (ms, per light cut)",
            "mean corner list",
            "lists (MiB)",
            "G-buffer (ms)",
            "shading (ms)",
            "frame (ms)",
            "frame CPU (ms)",
            "kept unions (MiB)",
            "first frame of a shader (ms)",
            "frame, environment rotating (ms)",
            "frame, environment rotating CPU (ms)",
            "light power (ms)",
            "light sample grid (ms, once per bake)",
            "new light cut (ms)",
            "frame, all merged (ms)",
            "frame, all merged CPU (ms)",
            "triangle merge frame (ms)",
            "triangle merge frame CPU (ms)",
            "per-fragment merge (ms)",
            "speed-up vs per-fragment",
            "target (ms)",
        ],
    );
    let materials = [
        Material::Lambert {
            albedo: Vec3::splat(0.7),
        },
        Material::GgxConductor {
            specular: Vec3::splat(0.9),
            alpha: 0.2,
        },
        Material::GgxPlastic {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::ONE,
            alpha: 0.1,
            ior: 1.5,
        },
    ];
    // The default cut function only (the other one's frame differs in the Lambert sum).
    for function in [CutFunction::default()] {
        let settings = CutsBakeSettings {
            lights,
            function,
            ..Default::default()
        };
        let t0 = Instant::now();
        let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count())
            .map_err(MethodError::from)?;
        eprintln!(
            "bench: cuts bake ({function:?}) {:.1} s",
            t0.elapsed().as_secs_f64()
        );
        // The light samples' nearest-sample grid, built once per bake as a frame does.
        let t0 = Instant::now();
        let grid = NearestSample::new(&bake.samples.dirs);
        let grid_ms = t0.elapsed().as_secs_f64() * 1e3;
        let power = sample_power_with(&bake.samples, &grid, &env).map_err(bad)?;
        for material in materials {
            let shader_materials = vec![
                material;
                mesh.material_ids
                    .iter()
                    .max()
                    .map_or(1, |&m| m as usize + 1)
            ];
            // The frame's default (glossy lobes averaged over each cluster's spread).
            let spread = relight_method::cuts::CutsFrameSettings::default().cluster_spread;
            let shader = CutsShader::new(&mesh, shader_materials.clone(), &bake, function)
                .with_cluster_spread(spread);
            // Nothing kept: every visible triangle merged at every frame, as in a shader's
            // very first frame.
            let uncached = CutsShader::new(&mesh, shader_materials.clone(), &bake, function)
                .with_cluster_spread(spread)
                .with_merge_cache(0);
            let budgets: &[usize] = if quick { &[256] } else { &LIGHT_CUT_BUDGETS };
            for &budget in budgets {
                let light = LightCut::build(&bake.tree, &power, DEFAULT_LIGHT_SIGMA, budget)
                    .map_err(bad)?;
                let opts = RasterOptions { supersample: 1 };
                let t0 = Instant::now();
                let lists = shader.prepare(&light);
                let prepare = t0.elapsed().as_secs_f64() * 1e3;
                // A warm-up frame, then the median wall and mean CPU time of `runs` frames.
                let time = |render: &dyn Fn() -> Rendered| {
                    std::hint::black_box(render());
                    let (mut ms, mut cpu) = (vec![], 0.0);
                    for _ in 0..runs {
                        timed_frame(&mut ms, &mut cpu, render);
                    }
                    (median(ms), cpu / runs as f64)
                };
                let stage = |stage: CutsStage| {
                    time(&|| shader.render_stage(&light, &camera, None, &opts, stage))
                };
                let (gbuffer, _) = stage(CutsStage::GBuffer);
                // The camera orbiting by ORBIT_DEG per frame under the light cut: each frame
                // merges only the triangles that came into view (the others' merges kept).
                shader.render(&light, &camera, None, &opts);
                let (mut ms, mut cpu) = (vec![], 0.0);
                let frames = if quick { 2 } else { 8 };
                for i in 1..=frames {
                    let cam = camera_at(ORBIT_DEG * i as f32);
                    timed_frame(&mut ms, &mut cpu, &|| {
                        shader.render(&light, &cam, None, &opts)
                    });
                }
                let (frame, frame_cpu) = (median(ms), cpu / frames as f64);
                let kept = shader.merge_cache_bytes();
                // The same orbit with the environment also turning by ROTATE_DEG per frame, on
                // a fresh shader (the same triangles come into view): a new light cut at
                // every frame (the light samples' power and the cut, each timed apart), its frame
                // from the kept visibility unions.
                let turning = CutsShader::new(&mesh, shader_materials.clone(), &bake, function)
                    .with_cluster_spread(spread);
                // Its first frame: every visible triangle's union recorded, then passed.
                let t0 = Instant::now();
                std::hint::black_box(turning.render(&light, &camera, None, &opts));
                let first = t0.elapsed().as_secs_f64() * 1e3;
                let (mut ms, mut cpu, mut power_ms, mut cut_ms) = (vec![], 0.0, vec![], vec![]);
                for i in 1..=frames {
                    let t0 = Instant::now();
                    let mut turned = env.clone();
                    turned.rotate_y_deg += ROTATE_DEG * i as f32;
                    let power = sample_power_with(&bake.samples, &grid, &turned).map_err(bad)?;
                    power_ms.push(t0.elapsed().as_secs_f64() * 1e3);
                    let t0 = Instant::now();
                    let light_i = LightCut::build(&bake.tree, &power, DEFAULT_LIGHT_SIGMA, budget)
                        .map_err(bad)?;
                    cut_ms.push(t0.elapsed().as_secs_f64() * 1e3);
                    let cam = camera_at(ORBIT_DEG * i as f32);
                    timed_frame(&mut ms, &mut cpu, &|| {
                        turning.render(&light_i, &cam, None, &opts)
                    });
                }
                let (rotating, rotating_cpu) = (median(ms), cpu / frames as f64);
                let (light_power, new_cut) = (median(power_ms), median(cut_ms));
                uncached.prepare(&light);
                let (all_merged, all_merged_cpu) =
                    time(&|| uncached.render(&light, &camera, None, &opts));
                let (merged, merged_cpu) =
                    time(&|| shader.render_merged(&light, &camera, None, &opts));
                let t0 = Instant::now();
                std::hint::black_box(shader.render_per_fragment(&light, &camera, None, &opts));
                let baseline = t0.elapsed().as_secs_f64() * 1e3;
                sec.row(vec![
                    json!(format!("{function:?}")),
                    json!(bake.cuts.mean_len()),
                    json!(match material {
                        Material::Lambert { .. } => "Lambert",
                        Material::GgxConductor { .. } => "GGX conductor a=0.2",
                        _ => "GGX plastic a=0.1",
                    }),
                    json!(budget),
                    json!(lists.map(|_| prepare)),
                    json!(lists.map(|l| l.mean_len)),
                    json!(lists.map(|l| l.bytes as f64 / (1 << 20) as f64)),
                    json!(gbuffer),
                    json!(frame - gbuffer),
                    json!(frame),
                    json!(frame_cpu),
                    json!(kept as f64 / (1 << 20) as f64),
                    json!(first),
                    json!(rotating),
                    json!(rotating_cpu),
                    json!(light_power),
                    json!(grid_ms),
                    json!(new_cut),
                    json!(all_merged),
                    json!(all_merged_cpu),
                    json!(merged),
                    json!(merged_cpu),
                    json!(baseline),
                    json!(baseline / frame),
                    json!(TARGET_MS),
                ]);
            }
        }
    }
    Ok(sec)
}

/// One frame of `render`: its wall time (ms) pushed onto `ms`, its process CPU time (ms)
/// added to `cpu`.
fn timed_frame(ms: &mut Vec<f64>, cpu: &mut f64, render: &dyn Fn() -> Rendered) {
    let (c0, t0) = (process_cpu_ms(), Instant::now());
    std::hint::black_box(render());
    ms.push(t0.elapsed().as_secs_f64() * 1e3);
    *cpu += process_cpu_ms().zip(c0).map_or(f64::NAN, |(b, a)| b - a);
}
