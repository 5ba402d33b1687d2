//! `relight bench`: the three measurements, each against a baseline measured in the
//! same run (never asserted in tests; figures go to docs/RESULTS.md).
//!
//! 1. Ray throughput of every back-end on incoherent occlusion (and closest-hit) rays from the
//!    surface of a ~100K-triangle mesh, as a ratio to Embree 3.
//! 2. SH bake time of bunny_watertight.obj (order 4, 1024 samples, shadowed + 1 bounce), and
//!    its overhead over casting the same rays with nothing else done.
//! 3. SH relight time per frame for 1M vertices at order 5, against a STREAM-like copy.
//!
//! Then the later methods: hybrid frames, the Gaussian-prefiltered environment, and the SG
//! frame (512 x 512, ~15K vertices) against the SH frame of the same scene.

use anyhow::{anyhow, Result};
use rayon::prelude::*;
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_bake::transport::{surface_ray, vertex_geometric_normals, VertexSamples};
use relight_scene::accel::{self, bench::bench_occlusion, RayCaster};
use relight_scene::mesh::TriMesh;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `relight bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Rays per throughput measurement.
    #[arg(long, default_value_t = 2_000_000)]
    pub rays: usize,
    /// Mesh for the ray benchmark (default: ../shared/data/meshes/dragon.obj, 100K triangles,
    /// else a procedural 100K-triangle sphere).
    #[arg(long)]
    pub ray_mesh: Option<PathBuf>,
    /// Mesh for the bake benchmark (default: ../shared/data/meshes/bunny_watertight.obj, else a
    /// procedural sphere on a plane).
    #[arg(long)]
    pub bake_mesh: Option<PathBuf>,
    /// Vertices of the relight benchmark.
    #[arg(long, default_value_t = 1_000_000)]
    pub relight_vertices: usize,
    /// Fewer rays and samples (a quick smoke run).
    #[arg(long)]
    pub quick: bool,
}

fn shared_mesh(explicit: &Option<PathBuf>, rel: &str) -> Result<Option<(String, TriMesh)>> {
    let path = match explicit {
        Some(p) => Some(p.clone()),
        None => relight_scene::testdata::shared_dir()
            .map(|d| d.join(rel))
            .filter(|p| p.is_file()),
    };
    match path {
        Some(p) => {
            let m = relight_scene::io::load_mesh(&p)?.mesh;
            Ok(Some((p.display().to_string(), m)))
        }
        None => Ok(None),
    }
}

/// Run the benchmarks and print a report.
pub fn run(a: Args) -> Result<()> {
    let threads = rayon::current_num_threads();
    let rays = if a.quick { a.rays.min(200_000) } else { a.rays };
    println!(
        "# relight bench ({} threads, {})",
        threads,
        std::env::consts::ARCH
    );

    // 1. Ray throughput.
    let (name, mesh) = match shared_mesh(&a.ray_mesh, "data/meshes/dragon.obj")? {
        Some(x) => x,
        None => {
            eprintln!(
                "bench: ../shared/data/meshes/dragon.obj not found: using a procedural sphere"
            );
            (
                "procedural sphere".into(),
                relight_scene::shapes::uv_sphere(glam::Vec3::ZERO, 1.0, 224, 224),
            )
        }
    };
    println!(
        "\n## Ray throughput: {} ({} triangles), {} incoherent rays from the surface",
        name,
        mesh.triangle_count(),
        rays
    );
    println!("| back-end | query | Mrays/s | ratio to Embree |\n|---|---|---|---|");
    for r in bench_occlusion(&mesh, rays, 7, threads) {
        println!(
            "| {} | {} | {:.2} | {:.2} |",
            r.backend, r.query, r.mrays_per_s, r.ratio_to_embree
        );
    }

    // 2. Bake overhead.
    let (name, mesh) = match shared_mesh(&a.bake_mesh, "data/meshes/bunny_watertight.obj")? {
        Some(x) => x,
        None => {
            eprintln!(
                "bench: bunny_watertight.obj not found: using a procedural sphere on a plane"
            );
            let mut m =
                relight_scene::shapes::uv_sphere(glam::Vec3::new(0.0, 0.5, 0.0), 0.5, 96, 192);
            m.append(
                &relight_scene::shapes::ground_plane(glam::Vec3::ZERO, 4.0, 64),
                0,
            );
            ("procedural sphere + plane".into(), m)
        }
    };
    let samples = if a.quick { 128 } else { 1024 };
    let materials = vec![relight_scene::material::Material::default()];
    let mut mesh = mesh;
    mesh.material_ids.iter_mut().for_each(|m| *m = 0);
    let caster = accel::build_default(&mesh);
    let settings = ShBakeSettings {
        order: 4,
        samples,
        seed: 1,
        kind: ShTransferKind::Interreflected { bounces: 1 },
        threads: None,
        progress: false,
    };
    let t0 = Instant::now();
    let transfer = relight_bake::sh::bake(&mesh, &materials, caster.as_ref(), &settings)
        .map_err(|e| anyhow!("bake: {e}"))?;
    let bake_s = t0.elapsed().as_secs_f64();
    std::hint::black_box(&transfer);
    let cast_s = cast_bake_rays(&mesh, caster.as_ref(), samples);
    let nrays = mesh.vertex_count() as u64 * samples as u64;
    println!(
        "\n## SH bake: {} ({} vertices), order 4, {} samples, shadowed + 1 bounce, {}",
        name,
        mesh.vertex_count(),
        samples,
        caster.name()
    );
    println!(
        "| bake | same rays, cast only | overhead | rays | bake Mrays/s |\n|---|---|---|---|---|"
    );
    println!(
        "| {:.2} s | {:.2} s | {:.2}x | {} | {:.2} |",
        bake_s,
        cast_s,
        bake_s / cast_s,
        nrays,
        nrays as f64 / bake_s / 1e6
    );

    // 3. Relight vs bandwidth.
    let verts = if a.quick {
        a.relight_vertices.min(200_000)
    } else {
        a.relight_vertices
    };
    let r = relight_render::shade_sh::bench_relight(verts, 5);
    println!(
        "\n## SH relight: {} vertices, order 5, single-channel transfer + albedo",
        verts
    );
    println!("| ms/frame | MB/frame | achieved GB/s | STREAM copy GB/s | time over bandwidth bound |\n|---|---|---|---|---|");
    let achieved = r.bytes_per_frame as f64 / (r.ms_per_frame * 1e-3) / 1e9;
    println!(
        "| {:.2} | {:.1} | {:.2} | {:.2} | {:.2}x |",
        r.ms_per_frame,
        r.bytes_per_frame as f64 / 1e6,
        achieved,
        r.stream_copy_gbps,
        1.0 / r.ratio_to_bandwidth_bound
    );

    // 4. Hybrid method (issue 3): decomposition per frame, hybrid frames with 8 and 16 lights.
    bench_hybrid(a.quick);
    // 5. Gaussian-prefiltered environment (issue 4 building block).
    bench_prefilter();
    // 6. SG frame (issue 4): per-vertex view blend + per-pixel lobe blend and fetches.
    bench_sg(a.quick);
    Ok(())
}

/// A 512 x 512 SG frame of a ~15K-vertex sphere (1, 2 and 3 lobes; 1 only with --quick)
/// against the SH PRT frame of the same mesh and camera, measured in the same run (median of
/// 9 frames, 3 with --quick).
fn bench_sg(quick: bool) {
    let runs = if quick { 3 } else { 9 };
    println!(
        "\n## SG frame: 512 x 512, ~15K-vertex sphere, one sample per pixel (median of {runs})"
    );
    println!("| lobes | vertices | coverage | SG frame (ms) | of which per-vertex (ms) | SG CPU time, all threads (ms) | SH frame (ms) | SH CPU time (ms) | SG / SH | fps |\n|---|---|---|---|---|---|---|---|---|---|");
    let cpu = |c: Option<f64>| c.map_or("n/a".into(), |c| format!("{c:.1}"));
    for lobes in if quick { 1..=1 } else { 1..=3 } {
        let b = relight_render::shade_sg::bench_sg_frame(lobes, runs);
        println!(
            "| {lobes} | {} | {:.0} % | {:.1} | {:.1} | {} | {:.1} | {} | {:.2} | {:.0} |",
            b.vertices,
            100.0 * b.coverage,
            b.ms_per_frame,
            b.vertex_ms,
            cpu(b.cpu_ms_per_frame),
            b.sh_ms_per_frame,
            cpu(b.sh_cpu_ms_per_frame),
            b.ms_per_frame / b.sh_ms_per_frame,
            1e3 / b.ms_per_frame
        );
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Decomposition of a 6 x 64 x 64 cube map (median of 9), and a 512 x 512 hybrid frame with 8
/// lights on a ~100K-triangle scene (best of 3), area and point lights, 2048 and 1024 maps, and
/// with 16 (the render default) area lights and 2048 maps.
fn bench_hybrid(quick: bool) {
    use relight_render::hybrid::{
        build_shadow_maps, render_hybrid_with_maps, HybridLight, ShadowSettings,
    };
    let ms = median(
        (0..9)
            .map(|_| relight_sphere::decompose::bench_decompose())
            .collect(),
    );
    println!("\n## Hybrid: environment decomposition, 6 x 64 x 64 cube map, 3 lights + sky");
    println!(
        "| ms per decomposition (median of 9) | per-frame budget |\n|---|---|\n| {ms:.2} | 5 ms |"
    );
    let mut mesh = relight_scene::shapes::uv_sphere(glam::Vec3::new(0.0, 1.0, 0.0), 1.0, 150, 300);
    mesh.append(
        &relight_scene::shapes::ground_plane(glam::Vec3::ZERO, 10.0, 70),
        0,
    );
    let prt = vec![glam::Vec3::splat(0.1); mesh.vertex_count()];
    let albedo = vec![glam::Vec3::splat(0.6); mesh.vertex_count()];
    let camera = relight_scene::camera::Camera {
        origin: [0.0, 3.0, 5.0],
        target: [0.0, 0.6, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_deg: 45.0,
        width: 512,
        height: 512,
    };
    let lights_n = |n: usize| -> Vec<HybridLight> {
        (0..n)
            .map(|i| {
                let (phi, el) = (i as f32 * 2.4, 0.3 + 0.15 * i as f32);
                HybridLight {
                    dir: glam::Vec3::new(el.cos() * phi.cos(), el.sin(), el.cos() * phi.sin()),
                    power: glam::Vec3::ONE,
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
    println!(
        "\n## Hybrid frame: 512 x 512, {} triangles, 8 and 16 lights (16 = the render default; best of {})",
        mesh.triangle_count(),
        if quick { 1 } else { 3 }
    );
    println!("| lights | shadow maps | light model | shadow maps (ms) | shading (ms) | frame (ms) | PRT-only frame (ms) |\n|---|---|---|---|---|---|---|");
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
        println!(
            "| {count} | {map_size} | {} | {:.0} | {:.0} | {:.0} | {prt_ms:.0} |",
            if area_light {
                "area (PCSS)"
            } else {
                "point (PCF)"
            },
            best.0,
            best.1,
            best.0 + best.1
        );
    }
}

/// Gaussian-prefiltered cube map, 6 x 256 x 256, 8 levels: sequential (the library's
/// `PrefilteredEnv::build`) and with the per-face jobs on rayon's pool.
fn bench_prefilter() {
    use relight_sphere::cubemap::CubeFace;
    use relight_sphere::env_prefilter::{
        default_levels, prefilter_face, PrefilterOptions, PrefilteredEnv, SourcePyramid,
    };
    let sequential = relight_sphere::env_prefilter::bench_prefilter();
    let map = relight_sphere::EnvMap::cube_from_fn(256, |d| {
        glam::Vec3::splat(0.2 + d.y.max(0.0))
            + glam::Vec3::splat(50.0)
                * (d.dot(glam::Vec3::new(0.3, 0.8, 0.5).normalize()) > 0.999) as u8 as f32
    });
    let levels = default_levels(256, 8);
    let opts = PrefilterOptions::default();
    let t0 = Instant::now();
    let pyr = SourcePyramid::new(&map);
    let data: Vec<Vec<glam::Vec3>> = levels
        .iter()
        .map(|l| {
            let mut v = vec![glam::Vec3::ZERO; 6 * l.size * l.size];
            v.par_chunks_mut(l.size * l.size)
                .enumerate()
                .for_each(|(f, chunk)| {
                    prefilter_face(&pyr, l, &opts, CubeFace::from_index(f), chunk)
                });
            v
        })
        .collect();
    std::hint::black_box(PrefilteredEnv::from_levels(levels, data));
    let parallel = t0.elapsed().as_secs_f64();
    println!("\n## Gaussian-prefiltered environment: 6 x 256 x 256, 8 levels");
    println!("| sequential (s) | {} threads (s) | cmft's published time (s) |\n|---|---|---|\n| {sequential:.2} | {parallel:.2} | 6.0 |", rayon::current_num_threads());
}

/// Cast exactly the rays of a shadowed + 1 bounce bake (same directions and origins), doing
/// nothing with the answers: the pure ray-casting time the bake's overhead is measured against.
/// The bake casts each direction once, as a closest-hit ray (it keeps the front-facing hits
/// for the bounce pass instead of retracing), so that is what is timed here.
fn cast_bake_rays(mesh: &TriMesh, caster: &dyn RayCaster, samples: u32) -> f64 {
    let ng = vertex_geometric_normals(mesh);
    let t0 = Instant::now();
    let hits: u64 = (0..mesh.vertex_count())
        .into_par_iter()
        .map(|v| {
            let s = VertexSamples::new(1, v, samples, mesh.normals[v]);
            (0..samples)
                .filter(|&i| {
                    let ray = surface_ray(mesh.positions[v], ng[v], s.dir(i));
                    caster.intersect(&ray).is_some()
                })
                .count() as u64
        })
        .sum();
    std::hint::black_box(hits);
    t0.elapsed().as_secs_f64()
}
