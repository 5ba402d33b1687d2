//! The SG frame (section "SG frame"): a 512 x 512 frame of the `sg` method on a synthetic bake
//! (so it needs no baking), against the SH PRT frame of the same mesh and camera measured in
//! the same run.

use super::{median, process_cpu_ms, Section};
use glam::Vec3;
use relight_bake::sg::{LobeSetting, SgBake, SgDomain};
use relight_render::raster::{self, RasterOptions};
use relight_render::shade_sg::{SgLighting, SgRenderer};
use relight_render::shade_sh;
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use relight_sphere::envmap::EnvMap;
use relight_sphere::sg::SgLobe;
use relight_sphere::sh;
use serde_json::json;
use std::time::Instant;

/// Result of [`bench_sg_frame`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SgFrameBench {
    /// Mesh vertices.
    pub vertices: usize,
    /// Lobes per vertex and view.
    pub lobes: usize,
    /// Their kernel, domain and order.
    pub setting: LobeSetting,
    /// Fraction of the image's pixels covered by the mesh.
    pub coverage: f64,
    /// Median SG frame (per-vertex pass + raster + per-pixel shading), milliseconds.
    pub ms_per_frame: f64,
    /// Median per-vertex pass of the SG frame, milliseconds.
    pub vertex_ms: f64,
    /// Mean CPU time of an SG frame summed over all threads ([`process_cpu_ms`]; `None` where
    /// that does not exist), milliseconds: what the frame costs whatever else runs on the
    /// machine; `cpu_ms_per_frame / threads` is the wall time of an otherwise idle machine
    /// with perfect scaling.
    pub cpu_ms_per_frame: Option<f64>,
    /// Mean CPU time of the SH PRT frame, all threads, milliseconds (as `cpu_ms_per_frame`).
    pub sh_cpu_ms_per_frame: Option<f64>,
    /// Median SH PRT frame of the same mesh and camera (per-vertex order-5 dot products +
    /// Gouraud raster), milliseconds.
    pub sh_ms_per_frame: f64,
    /// Rayon threads.
    pub threads: usize,
}

/// A synthetic SG bake of a UV sphere with `rings x 2 rings` quads (`~2 rings^2` vertices):
/// per view, `lobes` lobes about the mirror direction of the view (sharpness 20 to 500),
/// order-5 diffuse transfer `y_i(n)` (smooth, not physical), GGX plastic.
pub fn synthetic_sphere_bake(rings: u32, lobes: usize) -> (TriMesh, SgBake) {
    synthetic_sphere_bake_with(rings, lobes, LobeSetting::LIGHT_GAUSSIAN)
}

/// [`synthetic_sphere_bake`] with the lobes of `setting`: in the half-vector domain the axes
/// are about the normal (the half vector of the mirror direction) instead.
pub fn synthetic_sphere_bake_with(
    rings: u32,
    lobes: usize,
    setting: LobeSetting,
) -> (TriMesh, SgBake) {
    let half = setting.domain == SgDomain::HalfVector;
    let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, rings, 2 * rings);
    let order = 5;
    let bake = SgBake::from_fn(
        &mesh,
        lobes,
        |x, n, v, k| {
            let r = if half {
                n
            } else {
                (2.0 * n.dot(v) * n - v).normalize_or(n)
            };
            SgLobe {
                axis: (r + 0.2 * k as f32 * n.any_orthonormal_vector()).normalize(),
                sharpness: 20.0 + 480.0 * ((x * 7 + k * 3) % 11) as f32 / 10.0,
                amplitude: Vec3::new(1.0, 0.8, 0.6) * (10.0 / (1 + k) as f32),
            }
        },
        order,
        |n| {
            let mut y = vec![0.0; sh::sh_count(order)];
            sh::eval_sh(order, n, &mut y);
            y
        },
        Material::GgxPlastic {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::ONE,
            alpha: 0.1,
            ior: 1.49,
        },
    );
    let bake = SgBake {
        kernel: setting.kernel.kernel(),
        domain: setting.domain,
        lobe_order: setting.order,
        ..bake
    };
    (mesh, bake)
}

/// Times a 512 x 512 SG frame (1 sample per pixel) of a ~15K-vertex sphere filling most of
/// the image with `lobes` lobes, under a prefiltered 6 x 128 x 128 environment, against the
/// SH PRT frame of the same mesh and camera; medians of `runs` frames after a warm-up; lobes
/// of `setting` (the frame's options by the bake, `ShadeOptions::default_for`).
pub fn bench_sg_frame(lobes: usize, runs: usize, setting: LobeSetting) -> SgFrameBench {
    let (mesh, bake) = synthetic_sphere_bake_with(87, lobes, setting);
    let env = Environment::new(EnvMap::cube_from_fn(128, |d| {
        Vec3::new(0.2, 0.3, 0.5) * (1.2 + d.y)
            + Vec3::splat(40.0) * (d.dot(Vec3::new(0.3, 0.8, 0.5).normalize()) > 0.995) as u8 as f32
    }));
    let lighting = SgLighting::new(&env, bake.diffuse.order, 128);
    let renderer = SgRenderer::new(&mesh, &bake);
    let camera = Camera::look_at([0.0, 0.4, 2.9], [0.0, 0.0, 0.0], 45.0, 512, 512);
    let opts = RasterOptions { supersample: 1 };
    let runs = runs.max(1);
    let mut sg = vec![];
    let mut vert = vec![];
    let mut coverage = 0.0;
    let mut cpu0 = None;
    for i in 0..=runs {
        if i == 1 {
            cpu0 = process_cpu_ms();
        }
        let t0 = Instant::now();
        let (r, t) = renderer.render(&lighting, &camera, None, &opts);
        if i > 0 {
            sg.push(t0.elapsed().as_secs_f64() * 1e3);
            vert.push(t.vertex_ms);
        }
        coverage = r.coverage.iter().map(|&c| c as f64).sum::<f64>() / r.coverage.len() as f64;
    }
    let cpu_ms_per_frame = cpu0
        .zip(process_cpu_ms())
        .map(|(a, b)| (b - a) / runs as f64);
    let albedo = vec![Vec3::splat(0.5); mesh.vertex_count()];
    let mut shf = vec![];
    let mut sh_cpu0 = None;
    for i in 0..=runs {
        if i == 1 {
            sh_cpu0 = process_cpu_ms();
        }
        let t0 = Instant::now();
        let rad = shade_sh::shade(&bake.diffuse, Some(&albedo), lighting.world_sh());
        std::hint::black_box(raster::render_with(&mesh, &camera, &rad, None, &opts));
        if i > 0 {
            shf.push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    let sh_cpu_ms_per_frame = sh_cpu0
        .zip(process_cpu_ms())
        .map(|(a, b)| (b - a) / runs as f64);
    SgFrameBench {
        vertices: mesh.vertex_count(),
        lobes,
        setting,
        coverage,
        ms_per_frame: median(sg),
        vertex_ms: median(vert),
        cpu_ms_per_frame,
        sh_cpu_ms_per_frame,
        sh_ms_per_frame: median(shf),
        threads: rayon::current_num_threads(),
    }
}

/// The section: 1, 2 and 3 lobes of the light-domain Gaussians and of the half-vector GGX
/// lobes (the setting `relight bake` chooses for a GGX conductor), median of 9 frames (1
/// lobe of each, median of 3 with `quick`). "SG / SH" is each row's ratio to the SH frame of
/// its own run; the half-vector rows also give their ratio to the Gaussian row of the same
/// lobe count.
pub(super) fn section(quick: bool) -> Section {
    let runs = if quick { 3 } else { 9 };
    let mut sec = Section::new(
        format!("SG frame: 512 x 512, ~15K-vertex sphere, one sample per pixel (median of {runs})"),
        &[
            "lobes",
            "kernel, domain, order",
            "vertices",
            "coverage",
            "SG frame (ms)",
            "of which per-vertex (ms)",
            "SG CPU time, all threads (ms)",
            "SH frame (ms)",
            "SH CPU time (ms)",
            "SG / SH",
            "over the Gaussian row",
            "fps",
        ],
    );
    for lobes in if quick { 1..=1 } else { 1..=3 } {
        let mut gaussian_ms = None;
        for setting in [LobeSetting::LIGHT_GAUSSIAN, LobeSetting::HALF_VECTOR_GGX] {
            let b = bench_sg_frame(lobes, runs, setting);
            // The Gaussian row's ratio to itself is 1.
            let over = b.ms_per_frame / *gaussian_ms.get_or_insert(b.ms_per_frame);
            sec.row(vec![
                json!(lobes),
                json!(setting.describe()),
                json!(b.vertices),
                json!(b.coverage),
                json!(b.ms_per_frame),
                json!(b.vertex_ms),
                json!(b.cpu_ms_per_frame),
                json!(b.sh_ms_per_frame),
                json!(b.sh_cpu_ms_per_frame),
                json!(b.ms_per_frame / b.sh_ms_per_frame),
                json!(over),
                json!(1e3 / b.ms_per_frame),
            ]);
        }
    }
    sec
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_reports_consistent_figures() {
        let b = bench_sg_frame(1, 1, LobeSetting::HALF_VECTOR_GGX);
        assert!(b.ms_per_frame > 0.0 && b.sh_ms_per_frame > 0.0 && b.vertex_ms > 0.0);
        assert!((10_000..20_000).contains(&b.vertices), "{}", b.vertices);
        assert!(b.coverage > 0.3 && b.coverage < 1.0, "{}", b.coverage);
    }
}
