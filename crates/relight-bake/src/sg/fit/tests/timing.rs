//! Timings of the fit (ignored by default; run with `--ignored --nocapture`).

use super::*;

/// CPU time of this process (user + system) in seconds, from `/proc/self/stat` (10 ms
/// ticks): wall time is meaningless on a machine shared by several jobs.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = rest
        .split_whitespace()
        .map(|x| x.parse().unwrap_or(0.0))
        .collect();
    (f.get(11).unwrap_or(&0.0) + f.get(12).unwrap_or(&0.0)) / 100.0
}

#[test]
#[ignore]
fn fit_timing() {
    // Realistic glossy transport on a 4x4 grid of vertices with slowly turning normals, half
    // of each hemisphere masked; time per (vertex, view) of the whole flood fill.
    let brdfs = [
        (true, 20.0),
        (true, 100.0),
        (true, 500.0),
        (false, 0.05),
        (false, 0.2),
        (false, 0.5),
    ];
    for brdf in brdfs {
        for lobes in [1, 2] {
            let src = Synthetic::new(16, 32, move |x, v, w| {
                let n = Vec3::new(0.05 * (x % 4) as f32, 1.0, 0.05 * (x / 4) as f32).normalize();
                let d = clamped_view(n, views().vertices()[v]);
                glossy(
                    n,
                    d,
                    w,
                    Vec3::new(-1.0, 0.0, 0.3 + 0.02 * x as f32).normalize(),
                    brdf,
                )
            });
            let mut buf = VertexTransport::default();
            let t0 = cpu_seconds();
            for x in 0..16 {
                src.compute(x, &mut buf);
            }
            let tab = cpu_seconds() - t0;
            let mut c = config(lobes);
            c.fit.relax_sweeps = 0;
            let t0 = cpu_seconds();
            let fit = crate::transport::with_threads(Some(1), || {
                fit_mesh(&src, &grid(4, 4), &c, &ProgressBar::hidden())
            })
            .unwrap();
            let t = cpu_seconds() - t0 - tab;
            eprintln!(
                "{brdf:?} {lobes} lobes: {:.3} ms CPU per (vertex, view), {:.1} iterations, rel. error {:.3}, flips {} -> {}",
                t * 1e3 / (16.0 * 92.0),
                fit.stats.iterations as f64 / (16.0 * 92.0),
                fit.stats.mean_relative_error[0],
                fit.stats.flips,
                fit.stats.flips_after_relaxation
            );
        }
    }
}

#[test]
#[ignore]
fn bake_timing() {
    // The default bake (6x32x32 direct, 6x8x8 indirect, 64 paths) of a glossy sphere on one
    // thread, 2 direct lobes and 1 indirect: CPU time of the tabulation and of the fit per
    // vertex, extrapolated to the armadillo (14.6K vertices) on 2 cores.
    use crate::sg::transport::{vertex_materials, TransportContext};
    use crate::sg::SgBakeSettings;
    use relight_scene::material::Material;
    let mut mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 8, 12);
    mesh.material_ids = vec![0; mesh.triangle_count()];
    let mats = [Material::BlinnPhong {
        diffuse: Vec3::splat(0.2),
        specular: Vec3::splat(0.5),
        exponent: 100.0,
    }];
    let caster = relight_scene::accel::build_default(&mesh);
    let settings = SgBakeSettings {
        direct_lobes: 2,
        indirect_lobes: 1,
        threads: Some(1),
        ..SgBakeSettings::default()
    };
    let nv = mesh.vertex_count();
    let ctx = TransportContext::new(
        &mesh,
        vertex_materials(&mesh, &mats),
        caster.as_ref(),
        &settings,
    )
    .unwrap();
    let mut buf = VertexTransport::default();
    let t0 = cpu_seconds();
    for x in 0..nv {
        ctx.compute(x, &mut buf);
    }
    let tab = (cpu_seconds() - t0) / nv as f64;
    for relax_sweeps in [0, 1] {
        let mut settings = settings;
        settings.fit.relax_sweeps = relax_sweeps;
        let t0 = cpu_seconds();
        let b = crate::sg::bake(&mesh, &mats, None, caster.as_ref(), &settings).unwrap();
        let total = (cpu_seconds() - t0) / nv as f64;
        let fit = total - tab;
        assert!(b
            .direct
            .lobes
            .iter()
            .all(|g| { g.axis.is_finite() && g.sharpness.is_finite() && g.amplitude.is_finite() }));
        eprintln!(
            "{nv} vertices, {relax_sweeps} relaxation sweeps: tabulation {:.1} ms, fit {:.1} ms \
             per vertex ({:.3} ms per (vertex, view)); armadillo on 2 cores ~{:.0} s; {:?}",
            tab * 1e3,
            fit * 1e3,
            fit * 1e3 / 92.0,
            14_600.0 * total / 2.0,
            b.stats
        );
    }
}
