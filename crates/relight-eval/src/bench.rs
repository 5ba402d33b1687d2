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

use crate::Result;
use rayon::prelude::*;
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_bake::transport::{surface_ray, vertex_geometric_normals, VertexSamples};
use relight_scene::accel::{self, bench::bench_occlusion, RayCaster};
use relight_scene::mesh::TriMesh;
use serde::Serialize;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Instant;

/// The benchmarks' options.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Rays per throughput measurement.
    pub rays: usize,
    /// Mesh for the ray benchmark (`None`: `<data>/data/meshes/dragon.obj`, 100K triangles, if
    /// a data folder is given, else a procedural 100K-triangle sphere).
    pub ray_mesh: Option<PathBuf>,
    /// Mesh for the bake benchmark (`None`: `<data>/data/meshes/bunny_watertight.obj`, else a
    /// procedural sphere on a plane).
    pub bake_mesh: Option<PathBuf>,
    /// The shared data folder, if any.
    pub data: Option<PathBuf>,
    /// Vertices of the relight benchmark.
    pub relight_vertices: usize,
    /// Fewer rays and samples (a quick smoke run).
    pub quick: bool,
}

/// One table of the report.
#[derive(Clone, Debug, Serialize)]
pub struct Section {
    /// What was measured.
    pub title: String,
    /// Column names.
    pub columns: Vec<String>,
    /// Rows (numbers where the cell is a number).
    pub rows: Vec<Vec<Value>>,
}

impl Section {
    fn new(title: impl Into<String>, columns: &[&str]) -> Section {
        Section {
            title: title.into(),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            rows: vec![],
        }
    }

    fn row(&mut self, cells: Vec<Value>) {
        self.rows.push(cells);
    }

    /// The section as markdown.
    pub fn markdown(&self) -> String {
        let cell = |v: &Value| match v {
            Value::String(s) => s.clone(),
            Value::Number(n) => match n.as_f64() {
                Some(x) if n.is_f64() => format!("{x:.2}"),
                _ => n.to_string(),
            },
            other => other.to_string(),
        };
        let mut s = format!(
            "## {}\n| {} |\n|{}\n",
            self.title,
            self.columns.join(" | "),
            "---|".repeat(self.columns.len())
        );
        for r in &self.rows {
            s.push_str(&format!(
                "| {} |\n",
                r.iter().map(cell).collect::<Vec<_>>().join(" | ")
            ));
        }
        s
    }
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// Worker threads.
    pub threads: usize,
    /// CPU architecture.
    pub arch: String,
    /// The tables, in order.
    pub sections: Vec<Section>,
}

fn shared_mesh(
    explicit: &Option<PathBuf>,
    data: &Option<PathBuf>,
    rel: &str,
) -> Result<Option<(String, TriMesh)>> {
    let path = match explicit {
        Some(p) => Some(p.clone()),
        None => data.as_ref().map(|d| d.join(rel)).filter(|p| p.is_file()),
    };
    match path {
        Some(p) => {
            let m = relight_scene::io::load_mesh(&p)?.mesh;
            Ok(Some((p.display().to_string(), m)))
        }
        None => Ok(None),
    }
}

/// Run the benchmarks; each section is also printed as markdown on stderr as it completes.
///
/// # Errors
/// A mesh that cannot be read, or a bake that fails.
pub fn run(a: &BenchOptions) -> Result<BenchReport> {
    let threads = rayon::current_num_threads();
    let rays = if a.quick { a.rays.min(200_000) } else { a.rays };
    let mut report = BenchReport {
        threads,
        arch: std::env::consts::ARCH.into(),
        sections: vec![],
    };
    let mut push = |s: Section| {
        eprintln!("{}", s.markdown());
        report.sections.push(s);
    };

    // 1. Ray throughput.
    let (name, mesh) = match shared_mesh(&a.ray_mesh, &a.data, "data/meshes/dragon.obj")? {
        Some(x) => x,
        None => {
            eprintln!("bench: no dragon.obj (--ray-mesh or --data): using a procedural sphere");
            (
                "procedural sphere".into(),
                relight_scene::shapes::uv_sphere(glam::Vec3::ZERO, 1.0, 224, 224),
            )
        }
    };
    let mut sec = Section::new(
        format!(
            "Ray throughput: {} ({} triangles), {} incoherent rays from the surface",
            name,
            mesh.triangle_count(),
            rays
        ),
        &["back-end", "query", "Mrays/s", "ratio to Embree"],
    );
    for r in bench_occlusion(&mesh, rays, 7, threads) {
        sec.row(vec![
            json!(r.backend),
            json!(r.query),
            json!(r.mrays_per_s),
            json!(r.ratio_to_embree),
        ]);
    }
    push(sec);

    // 2. Bake overhead.
    let (name, mesh) = match shared_mesh(&a.bake_mesh, &a.data, "data/meshes/bunny_watertight.obj")?
    {
        Some(x) => x,
        None => {
            eprintln!("bench: no bunny_watertight.obj: using a procedural sphere on a plane");
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
        transfer: ShTransferKind::Interreflected,
        bounces: 1,
        ..Default::default()
    };
    let t0 = Instant::now();
    let transfer = relight_bake::sh::bake(&mesh, &materials, caster.as_ref(), &settings)
        .map_err(relight_method::MethodError::from)?;
    let bake_s = t0.elapsed().as_secs_f64();
    std::hint::black_box(&transfer);
    let cast_s = cast_bake_rays(&mesh, caster.as_ref(), samples);
    let nrays = mesh.vertex_count() as u64 * samples as u64;
    let mut sec = Section::new(
        format!(
            "SH bake: {} ({} vertices), order 4, {} samples, shadowed + 1 bounce, {}",
            name,
            mesh.vertex_count(),
            samples,
            caster.name()
        ),
        &[
            "bake (s)",
            "same rays, cast only (s)",
            "overhead",
            "rays",
            "bake Mrays/s",
        ],
    );
    sec.row(vec![
        json!(bake_s),
        json!(cast_s),
        json!(bake_s / cast_s),
        json!(nrays),
        json!(nrays as f64 / bake_s / 1e6),
    ]);
    push(sec);

    // 3. Relight vs bandwidth.
    let verts = if a.quick {
        a.relight_vertices.min(200_000)
    } else {
        a.relight_vertices
    };
    let r = relight_render::shade_sh::bench_relight(verts, 5);
    let mut sec = Section::new(
        format!("SH relight: {verts} vertices, order 5, single-channel transfer + albedo"),
        &[
            "ms/frame",
            "MB/frame",
            "achieved GB/s",
            "STREAM copy GB/s",
            "time over bandwidth bound",
        ],
    );
    let achieved = r.bytes_per_frame as f64 / (r.ms_per_frame * 1e-3) / 1e9;
    sec.row(vec![
        json!(r.ms_per_frame),
        json!(r.bytes_per_frame as f64 / 1e6),
        json!(achieved),
        json!(r.stream_copy_gbps),
        json!(1.0 / r.ratio_to_bandwidth_bound),
    ]);
    push(sec);

    // 4. Hybrid method: decomposition per frame, hybrid frames with 8 and 16 lights.
    for s in bench_hybrid(a.quick) {
        push(s);
    }
    // 5. Gaussian-prefiltered environment.
    push(bench_prefilter());
    // 6. SG frame: per-vertex view blend + per-pixel lobe blend and fetches.
    push(bench_sg(a.quick));
    Ok(report)
}

/// A 512 x 512 SG frame of a ~15K-vertex sphere (1, 2 and 3 lobes; 1 only with `quick`)
/// against the SH PRT frame of the same mesh and camera, measured in the same run (median of
/// 9 frames, 3 with `quick`).
fn bench_sg(quick: bool) -> Section {
    let runs = if quick { 3 } else { 9 };
    let mut sec = Section::new(
        format!("SG frame: 512 x 512, ~15K-vertex sphere, one sample per pixel (median of {runs})"),
        &[
            "lobes",
            "vertices",
            "coverage",
            "SG frame (ms)",
            "of which per-vertex (ms)",
            "SG CPU time, all threads (ms)",
            "SH frame (ms)",
            "SH CPU time (ms)",
            "SG / SH",
            "fps",
        ],
    );
    for lobes in if quick { 1..=1 } else { 1..=3 } {
        let b = relight_render::shade_sg::bench_sg_frame(lobes, runs);
        sec.row(vec![
            json!(lobes),
            json!(b.vertices),
            json!(b.coverage),
            json!(b.ms_per_frame),
            json!(b.vertex_ms),
            json!(b.cpu_ms_per_frame),
            json!(b.sh_ms_per_frame),
            json!(b.sh_cpu_ms_per_frame),
            json!(b.ms_per_frame / b.sh_ms_per_frame),
            json!(1e3 / b.ms_per_frame),
        ]);
    }
    sec
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Decomposition of a 6 x 64 x 64 cube map (median of 9), and a 512 x 512 hybrid frame with 8
/// lights on a ~100K-triangle scene (best of 3), area and point lights, 2048 and 1024 maps, and
/// with 16 (the render default) area lights and 2048 maps.
fn bench_hybrid(quick: bool) -> Vec<Section> {
    use relight_render::hybrid::{
        build_shadow_maps, render_hybrid_with_maps, HybridLight, ShadowSettings,
    };
    let ms = median(
        (0..9)
            .map(|_| relight_sphere::decompose::bench_decompose())
            .collect(),
    );
    let mut dec = Section::new(
        "Hybrid: environment decomposition, 6 x 64 x 64 cube map, 3 lights + sky",
        &[
            "ms per decomposition (median of 9)",
            "per-frame budget (ms)",
        ],
    );
    dec.row(vec![json!(ms), json!(5)]);
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

/// Gaussian-prefiltered cube map, 6 x 256 x 256, 8 levels: sequential (the library's
/// `PrefilteredEnv::build`) and with the per-face jobs on rayon's pool.
fn bench_prefilter() -> Section {
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
    let mut sec = Section::new(
        "Gaussian-prefiltered environment: 6 x 256 x 256, 8 levels",
        &[
            "sequential (s)",
            &format!("{} threads (s)", rayon::current_num_threads()),
            "cmft's published time (s)",
        ],
    );
    sec.row(vec![json!(sequential), json!(parallel), json!(6.0)]);
    sec
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
