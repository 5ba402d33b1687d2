//! The hybrid method's per-frame costs (sections "Hybrid: environment decomposition" and
//! "Hybrid frame"): decomposing an environment into SH + cap lights against its per-frame
//! budget, and a hybrid frame (shadow maps + shading) against the PRT-only
//! frame of the same scene.

use super::{median, Section};
use glam::Vec3;
use relight_render::hybrid::{
    build_shadow_maps, render_hybrid_with_maps, HybridLight, ShadowSettings,
};
use relight_sphere::decompose::{sky_with_discs, DecomposeSettings, Decomposer};
use serde_json::json;
use std::time::Instant;

/// Mean milliseconds of one [`Decomposer::run`] with the default settings on a `6 x 64 x 64`
/// cube map (sky plus three discs), the tables built beforehand (50 runs after a warm-up).
///
/// # Panics
/// If the default decomposition settings stop being valid for that map.
pub fn bench_decompose() -> f64 {
    let discs = [
        (
            Vec3::new(0.3, 0.8, 0.2).normalize(),
            1.5,
            Vec3::splat(400.0),
        ),
        (
            Vec3::new(-0.6, 0.4, -0.5).normalize(),
            2.0,
            Vec3::new(80.0, 60.0, 40.0),
        ),
        (
            Vec3::new(0.1, 0.3, -0.9).normalize(),
            1.0,
            Vec3::splat(150.0),
        ),
    ];
    let map = sky_with_discs(64, &discs);
    let dec = Decomposer::new(&DecomposeSettings::default(), map.layout(), 64, 6 * 64)
        .expect("default settings are valid");
    let _ = dec.run(&map);
    let runs = 50;
    let t0 = Instant::now();
    for _ in 0..runs {
        std::hint::black_box(dec.run(std::hint::black_box(&map)).ok());
    }
    t0.elapsed().as_secs_f64() * 1e3 / runs as f64
}

/// Decomposition of a 6 x 64 x 64 cube map (median of 9 [`bench_decompose`]s), and a
/// 512 x 512 hybrid frame with 8 lights on a ~100K-triangle scene (best of 3, 1 with
/// `quick`), area and point lights, 2048 and 1024 maps, and with 16 (the render default) area
/// lights and 2048 maps.
pub(super) fn sections(quick: bool) -> Vec<Section> {
    let ms = median((0..9).map(|_| bench_decompose()).collect());
    let mut dec = Section::new(
        "Hybrid: environment decomposition, 6 x 64 x 64 cube map, 3 lights + sky",
        &[
            "ms per decomposition (median of 9)",
            "per-frame budget (ms)",
        ],
    );
    dec.row(vec![json!(ms), json!(5)]);
    let mut mesh = relight_scene::shapes::uv_sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, 150, 300);
    mesh.append(
        &relight_scene::shapes::ground_plane(Vec3::ZERO, 10.0, 70),
        0,
    );
    let prt = vec![Vec3::splat(0.1); mesh.vertex_count()];
    let albedo = vec![Vec3::splat(0.6); mesh.vertex_count()];
    let camera =
        relight_scene::camera::Camera::look_at([0.0, 3.0, 5.0], [0.0, 0.6, 0.0], 45.0, 512, 512);
    let lights_n = |n: usize| -> Vec<HybridLight> {
        (0..n)
            .map(|i| {
                let (phi, el) = (i as f32 * 2.4, 0.3 + 0.15 * i as f32);
                HybridLight {
                    dir: Vec3::new(el.cos() * phi.cos(), el.sin(), el.cos() * phi.sin()),
                    power: Vec3::ONE,
                    cap_radius: (2.0 + 0.5 * (i % 8) as f32).to_radians(),
                }
            })
            .collect()
    };
    let t0 = Instant::now();
    let opts = relight_render::raster::RasterOptions { supersample: 1 };
    std::hint::black_box(relight_render::raster::render_with(
        &mesh, &camera, &prt, None, &opts,
    ));
    let prt_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut frames = Section::new(
        format!(
            "Hybrid frame: 512 x 512, {} triangles, 8 and 16 lights (16 = the render default; best of {})",
            mesh.triangle_count(),
            if quick { 1 } else { 3 }
        ),
        &["lights", "shadow maps", "light model", "shadow maps (ms)", "shading (ms)", "frame (ms)", "PRT-only frame (ms)"],
    );
    for (count, map_size, area_light) in [
        (8, 2048, true),
        (8, 2048, false),
        (8, 1024, true),
        (8, 1024, false),
        (16, 2048, true),
    ] {
        let lights = lights_n(count);
        let s = ShadowSettings {
            map_size,
            area_light,
            ..Default::default()
        };
        let mut best = (f64::MAX, f64::MAX);
        for _ in 0..if quick { 1 } else { 3 } {
            let t0 = Instant::now();
            let maps = build_shadow_maps(&mesh, &lights, &s);
            let t1 = Instant::now();
            std::hint::black_box(render_hybrid_with_maps(
                &mesh, &camera, &prt, &albedo, &lights, &maps, &s, None, 1,
            ));
            let t2 = Instant::now();
            let (a, b) = ((t1 - t0).as_secs_f64() * 1e3, (t2 - t1).as_secs_f64() * 1e3);
            if a + b < best.0 + best.1 {
                best = (a, b);
            }
        }
        let model = if area_light {
            "area (PCSS)"
        } else {
            "point (PCF)"
        };
        frames.row(vec![
            json!(count),
            json!(map_size),
            json!(model),
            json!(best.0),
            json!(best.1),
            json!(best.0 + best.1),
            json!(prt_ms),
        ]);
    }
    vec![dec, frames]
}
