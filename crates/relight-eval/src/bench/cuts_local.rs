//! The cuts local-light frame (section "cuts-local": a point light moved at
//! run time with one bounce of indirect light, Cheslack-Postava et al. 2008 sec. 4.2).
//!
//! A closed 2 x 2 x 2 room built here (walls of 12 x 12 quads facing in, red and green side
//! walls, a sphere and a box; the geometry of `examples/cuts_room.json`), baked with the
//! default settings over 32,768 surface samples (4,096 with `quick`), rendered at 240 x 180
//! with 2 x 2 samples per pixel (the CLI's default) for two light positions. Per light: the
//! light's preparation (shadow rays to the samples, exitance, light cut of 256), the frame
//! (`LocalShader::render`: each triangle's cuts merged once with the light cut, the bounce
//! summed over lanes per fragment, the direct light with one shadow ray), and the
//! **baseline**, the per-fragment merge (`render_per_fragment`, the paper's per-pixel
//! algorithm as written) in the same run.

use super::{median, process_cpu_ms, Section};
use crate::Result;
use glam::Vec3;
use relight_bake::cuts::light_cut::DEFAULT_LIGHT_SIGMA;
use relight_bake::cuts::{bake_range, CutsBakeSettings, LightSampleKind};
use relight_method::MethodError;
use relight_render::light::PointLight;
use relight_render::raster::RasterOptions;
use relight_render::shade_local::{LocalShader, Terms};
use relight_scene::accel;
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::shapes::{aabb_box, coloured_room, uv_sphere};
use serde_json::json;
use std::time::Instant;

/// The room and its materials (white, red, green).
fn room() -> (TriMesh, Vec<Material>) {
    let mut m = coloured_room(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0), 12);
    m.append(&uv_sphere(Vec3::new(-0.4, 0.35, -0.3), 0.35, 24, 48), 0);
    m.append(
        &aabb_box(Vec3::new(0.1, 0.0, -0.2), Vec3::new(0.6, 0.6, 0.3), 2),
        0,
    );
    let lambert = |albedo: Vec3| Material::Lambert { albedo };
    let materials = vec![
        lambert(Vec3::splat(0.75)),
        lambert(Vec3::new(0.75, 0.15, 0.1)),
        lambert(Vec3::new(0.15, 0.6, 0.15)),
    ];
    (m, materials)
}

/// The section: bake, then per light position its preparation and the frame against the
/// per-fragment merge.
///
/// # Errors
/// A bake that fails.
pub(super) fn section(quick: bool) -> Result<Section> {
    let (mesh, materials) = room();
    let caster = accel::build_default(&mesh);
    let settings = CutsBakeSettings {
        lights: if quick { 4096 } else { 32_768 },
        samples: LightSampleKind::Surface,
        ..Default::default()
    };
    let t0 = Instant::now();
    let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count())
        .map_err(MethodError::from)?;
    let bake_s = t0.elapsed().as_secs_f64();
    let (w, h) = if quick { (60, 45) } else { (240, 180) };
    let camera = Camera::look_at([0.0, 1.0, 0.95], [0.0, 0.8, -1.0], 70.0, w, h);
    let opts = RasterOptions { supersample: 2 };
    let shader = LocalShader::new(&mesh, materials, &bake, settings.function, caster.as_ref())
        .map_err(|e| MethodError::Settings(e.to_string()))?;
    let threads = rayon::current_num_threads();
    let mut sec = Section::new(
        format!(
            "Cuts local-light frame {w} x {h}, 2 x 2 samples per pixel: procedural room ({} \
             vertices), {} surface samples, bake {bake_s:.1} s, mean cut {:.1}, light cut 256, \
             {threads} threads; per-fragment merge = baseline (same run)",
            mesh.vertex_count(),
            settings.lights,
            bake.cuts.mean_len()
        ),
        &[
            "light at",
            "prepare (ms)",
            "frame (ms)",
            "frame CPU (ms)",
            "per-fragment merge (ms)",
            "speed-up vs per-fragment",
        ],
    );
    let runs = if quick { 1 } else { 3 };
    for p in [Vec3::new(0.0, 1.7, 0.0), Vec3::new(0.6, 1.2, 0.5)] {
        let t0 = Instant::now();
        let lit = shader
            .prepare(
                PointLight::new(p, Vec3::splat(2.0)),
                DEFAULT_LIGHT_SIGMA,
                256,
            )
            .map_err(MethodError::Settings)?;
        let prepare = t0.elapsed().as_secs_f64() * 1e3;
        let (mut ms, mut cpu) = (vec![], 0.0);
        for i in 0..=runs {
            let (c0, t0) = (process_cpu_ms(), Instant::now());
            std::hint::black_box(shader.render(&lit, &camera, &opts, Terms::ALL));
            if i > 0 {
                ms.push(t0.elapsed().as_secs_f64() * 1e3);
                cpu += process_cpu_ms().zip(c0).map_or(f64::NAN, |(b, a)| b - a);
            }
        }
        let frame = median(ms);
        let t0 = Instant::now();
        std::hint::black_box(shader.render_per_fragment(&lit, &camera, &opts, Terms::ALL));
        let baseline = t0.elapsed().as_secs_f64() * 1e3;
        sec.row(vec![
            json!(format!("{}, {}, {}", p.x, p.y, p.z)),
            json!(prepare),
            json!(frame),
            json!(cpu / runs as f64),
            json!(baseline),
            json!(baseline / frame),
        ]);
    }
    Ok(sec)
}
