//! Ray-casting throughput of every back-end on one shared ray set (section "Ray throughput").
//!
//! The rays are those of ambient occlusion / transfer baking: origins uniform by area on the
//! mesh surface, offset with [`offset_ray_origin`], directions cosine-distributed about the
//! geometric normal, `tmin = 0`, `tmax = inf`. Each back-end traces the same rays on a rayon
//! pool of the requested size, in chunks through `occluded_many` / `intersect_many`. Timing
//! is interleaved and best-of-[`REPEATS`] per short segment of rays (see [`bench_occlusion`]),
//! the most robust figure on a machine shared with other jobs.

use super::Section;
use crate::Result;
use glam::Vec3;
use rayon::prelude::*;
use relight_scene::accel::{build, offset_ray_origin, Backend, Hit, Ray, RayCaster};
use relight_scene::mesh::TriMesh;
use relight_sphere::warp::{square_to_cosine_hemisphere, Frame, Rng};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Timed rounds (every segment, back-end and query once per round); the fastest pass counts.
pub const REPEATS: usize = 5;
/// Rays per timed pass: short passes, each the best of [`REPEATS`], filter out bursts of load
/// from other processes better than long ones.
const SEGMENT: usize = 1 << 17;
/// Rays per `occluded_many` / `intersect_many` call (one rayon task).
const CHUNK: usize = 256;

/// One measured throughput.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchRow {
    /// Back-end name ([`RayCaster::name`]).
    pub backend: &'static str,
    /// `"occluded"` or `"intersect"`.
    pub query: &'static str,
    /// Millions of rays per second (wall clock, all threads).
    pub mrays_per_s: f64,
    /// `mrays_per_s` over Embree's for the same query (1 for Embree; NaN without Embree).
    pub ratio_to_embree: f64,
}

/// `count` incoherent rays leaving the surface of `mesh` (see the module docs), drawn from
/// PCG32 stream 0 of `seed`.
///
/// # Panics
/// If the mesh has no triangle of positive area.
pub fn surface_rays(mesh: &TriMesh, count: usize, seed: u64) -> Vec<Ray> {
    // Area CDF over triangles.
    let mut cdf = Vec::with_capacity(mesh.triangle_count());
    let mut total = 0f64;
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        let area = 0.5 * (b - a).cross(c - a).length() as f64;
        total += if area.is_finite() { area } else { 0.0 };
        cdf.push(total);
    }
    assert!(total > 0.0, "surface_rays: mesh has no area");
    let mut rng = Rng::new(seed, 0);
    (0..count)
        .map(|_| {
            let x = rng.next_f64() * total;
            let tri = cdf.partition_point(|&c| c <= x).min(cdf.len() - 1);
            // Skip zero-area triangles the search can land on only at x == 0.
            let tri = (tri..cdf.len())
                .find(|&t| mesh.geometric_normal(t) != Vec3::ZERO)
                .unwrap_or(0);
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let p = mesh.point(tri, u, v);
            let n = mesh.geometric_normal(tri);
            let dir = Frame::from_normal(n)
                .to_world(square_to_cosine_hemisphere(rng.next_vec2()))
                .normalize();
            Ray::new(offset_ray_origin(p, n, dir), dir, 0.0, f32::INFINITY)
        })
        .collect()
}

/// One timed query over a chunk of rays.
type Query = dyn Fn(&dyn RayCaster, &[Ray]) + Sync;

/// Seconds for one parallel pass of `f` over `rays` in chunks on `pool`.
fn time_pass(pool: &rayon::ThreadPool, rays: &[Ray], f: &(dyn Fn(&[Ray]) + Sync)) -> f64 {
    let t0 = Instant::now();
    pool.install(|| rays.par_chunks(CHUNK).for_each(f));
    t0.elapsed().as_secs_f64()
}

/// Occlusion and closest-hit throughput of every available back-end (plus, with feature
/// `embree`, Embree's robust, watertight mode, backend `"embree3-robust"`) on the same `rays`
/// surface rays of `mesh` (seeded by `seed`) with `threads` worker threads. Ratios are against
/// `"embree3"` (Embree's default, fast mode).
///
/// The rays are cut into segments of `SEGMENT` rays; every segment is traced by every back-end
/// and query once per round ([`REPEATS`] rounds after a warm-up round), and the time of a
/// back-end is the sum over segments of its fastest pass, so bursts of load from other
/// processes hit all back-ends alike and are filtered out. Back-ends that fail to build
/// (reported on stderr) are left out.
///
/// # Panics
/// If `rays == 0`, `threads == 0`, the thread pool cannot start, or the mesh has no area.
pub fn bench_occlusion(mesh: &TriMesh, rays: usize, seed: u64, threads: usize) -> Vec<BenchRow> {
    assert!(
        rays > 0 && threads > 0,
        "bench_occlusion: need rays > 0 and threads > 0"
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("bench_occlusion: cannot start thread pool");
    let ray_set = surface_rays(mesh, rays, seed);
    #[allow(unused_mut)]
    let mut casters: Vec<Box<dyn RayCaster>> = Backend::available()
        .iter()
        .filter_map(|&b| {
            build(mesh, b)
                .map_err(|e| eprintln!("bench: {b:?} skipped: {e}"))
                .ok()
        })
        .collect();
    // Embree's watertight mode too: the like-for-like comparison for relight's watertight BVH.
    #[cfg(feature = "embree")]
    match relight_scene::accel::embree::EmbreeScene::build_robust(mesh) {
        Ok(e) => casters.push(Box::new(e)),
        Err(e) => eprintln!("bench: embree robust skipped: {e}"),
    }
    let occluded = |c: &dyn RayCaster, rs: &[Ray]| {
        let mut out = [false; CHUNK];
        c.occluded_many(rs, &mut out[..rs.len()]);
        std::hint::black_box(&out);
    };
    let intersect = |c: &dyn RayCaster, rs: &[Ray]| {
        let mut out = [None::<Hit>; CHUNK];
        c.intersect_many(rs, &mut out[..rs.len()]);
        std::hint::black_box(&out);
    };
    let queries: [(&'static str, &Query); 2] = [("occluded", &occluded), ("intersect", &intersect)];
    // best[caster][query][segment] = shortest pass over that segment of the rays, in seconds.
    let segments: Vec<&[Ray]> = ray_set.chunks(SEGMENT).collect();
    let mut best = vec![
        [
            vec![f64::INFINITY; segments.len()],
            vec![f64::INFINITY; segments.len()]
        ];
        casters.len()
    ];
    for round in 0..=REPEATS {
        for (si, seg) in segments.iter().enumerate() {
            for (c, b) in casters.iter().zip(&mut best) {
                for (q, (_, f)) in queries.iter().enumerate() {
                    let s = time_pass(&pool, seg, &|rs| f(&**c, rs));
                    if round > 0 {
                        b[q][si] = b[q][si].min(s);
                    }
                }
            }
        }
    }
    let mut rows = Vec::new();
    for (c, b) in casters.iter().zip(&best) {
        for (q, (query, _)) in queries.iter().enumerate() {
            let mrays_per_s = rays as f64 / b[q].iter().sum::<f64>() / 1e6;
            rows.push(BenchRow {
                backend: c.name(),
                query,
                mrays_per_s,
                ratio_to_embree: f64::NAN,
            });
        }
    }
    // Ratios against Embree's row for the same query.
    let embree: Vec<(&'static str, f64)> = rows
        .iter()
        .filter(|r| r.backend == "embree3")
        .map(|r| (r.query, r.mrays_per_s))
        .collect();
    for r in &mut rows {
        if let Some(&(_, e)) = embree.iter().find(|(q, _)| *q == r.query) {
            r.ratio_to_embree = r.mrays_per_s / e;
        }
    }
    rows
}

/// The section: `rays` rays on `ray_mesh`, else `<data>/data/meshes/dragon.obj`, else a
/// procedural 100K-triangle sphere, on `threads` threads.
pub(super) fn section(
    ray_mesh: &Option<PathBuf>,
    data: &Option<PathBuf>,
    rays: usize,
    threads: usize,
) -> Result<Section> {
    let (name, mesh) = match super::shared_mesh(ray_mesh, data, "data/meshes/dragon.obj")? {
        Some(x) => x,
        None => {
            eprintln!("bench: no dragon.obj (--ray-mesh or --data): using a procedural sphere");
            (
                "procedural sphere".into(),
                relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 224, 224),
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
    Ok(sec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surface_rays_leave_the_surface() {
        // A unit square in the XZ plane facing +Y: every ray must point up, start on it.
        let m = TriMesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::X,
            ],
            normals: vec![Vec3::Y; 4],
            uvs: None,
            indices: vec![[0, 1, 2], [0, 2, 3]],
            material_ids: vec![0, 0],
        };
        let rays = surface_rays(&m, 2000, 7);
        let mut mean_cos = 0.0;
        for r in &rays {
            assert!(
                r.dir.y > 0.0 && r.origin.y > 0.0 && r.origin.y < 1e-3,
                "{r:?}"
            );
            assert!((0.0..=1.0).contains(&r.origin.x) && (0.0..=1.0).contains(&r.origin.z));
            mean_cos += r.dir.y / rays.len() as f32;
        }
        // Cosine-weighted: E[cos] = 2/3; 2000 samples give a std error of ~0.005.
        assert!((mean_cos - 2.0 / 3.0).abs() < 0.02, "mean cos {mean_cos}");
    }

    #[test]
    fn bench_runs_on_a_small_mesh() {
        let m = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 8, 16);
        let rows = bench_occlusion(&m, 2000, 1, 2);
        let backends = Backend::available().len() + cfg!(feature = "embree") as usize;
        assert_eq!(rows.len(), 2 * backends);
        assert!(rows.iter().all(|r| r.mrays_per_s > 0.0), "{rows:?}");
    }
}
