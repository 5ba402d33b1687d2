//! Cuts bake cost (section "cuts-bake"; relight's target: the bunny's 35.9K vertices with
//! 32K environment samples in under 3 minutes on 2 cores).
//!
//! Through the public API of `relight_bake::cuts`, on `bunny.obj` (else a procedural sphere
//! on a plane):
//! 1. the light samples (Fibonacci lattice, Voronoi solid angles from 64 dense points each)
//!    and the geometric light tree over them;
//! 2. the visibility cuts of a contiguous block of vertices from the middle of the mesh, on
//!    every thread, against the **baseline** of sampling the same vertices' visibility
//!    functions (the same rays) with nothing else done; mean cut length and capped cuts;
//! 3. the whole mesh's bake extrapolated from the block's time per vertex, against the
//!    target;
//! 4. the illumination cut of a procedural sky with a sun at the budgets 128, 256 and 512;
//! 5. the per-pixel kernel [`shade`] (three vertex cuts of a triangle of the block,
//!    barycentric interpolation, light cut, BRDF at every merged cluster's direction) on one
//!    thread, Lambert and GGX conductor, at each light-cut budget, with the paper's binary
//!    visibility cuts; extrapolated to a 512 x 512 frame on every thread against the issue's
//!    6.4 fps;
//! 6. (not with `quick`) for both cut functions (visibility times cosine, binary visibility),
//!    the data-driven light trees of sec. 3.4 (pilot pass over every vertex, 1024 vertex
//!    clusters, beta 0.5 and 0) against the geometric tree: build time and mean cut length
//!    on the same block (the paper's Fig. 8b).

use super::{median_ms, Section};
use crate::Result;
use glam::Vec3;
use rayon::prelude::*;
use relight_bake::cuts::light_cut::{LightCut, DEFAULT_LIGHT_SIGMA, LIGHT_CUT_BUDGETS};
use relight_bake::cuts::merge::{merge_cuts, shade, CutKeys};
use relight_bake::cuts::samples::{sample_power, sample_radiance, EnvSamples, DEFAULT_SAMPLES};
use relight_bake::cuts::tree::{LightTree, DEFAULT_BETA, DEFAULT_K, DEFAULT_VERTEX_CLUSTERS};
use relight_bake::cuts::visibility::{CutFunction, CutParams, Scratch, VisibilitySampler};
use relight_bake::BakeError;
use relight_method::MethodError;
use relight_scene::accel::{self, RayCaster};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use relight_sphere::warp::{Frame, Rng};
use relight_sphere::EnvMap;
use serde_json::json;
use std::ops::Range;
use std::path::PathBuf;
use std::time::Instant;

/// The bake-time target on 2 cores, seconds (module docs).
pub const TARGET_SECONDS: f64 = 180.0;

/// A 512 x 257 sky with a 0.006 sr sun of radiance 2000 (the illumination cuts' test light).
pub(super) fn sky_with_sun() -> Environment {
    let sun = Vec3::new(0.3, 0.8, 0.2).normalize();
    Environment::new(EnvMap::latlong_from_fn(512, 257, |d| {
        let s = if d.dot(sun) > 0.999 { 2000.0 } else { 0.0 };
        Vec3::new(0.2, 0.3, 0.5) * (1.0 + d.y.max(0.0)) + Vec3::splat(s)
    }))
}

/// The cuts benches' mesh: `bunny.obj` (or `--bake-mesh`), else a procedural sphere on a
/// plane.
///
/// # Errors
/// A mesh that cannot be read.
pub(super) fn bunny_or_sphere(
    bake_mesh: &Option<PathBuf>,
    data: &Option<PathBuf>,
) -> Result<(String, TriMesh)> {
    Ok(
        match super::shared_mesh(bake_mesh, data, "data/meshes/bunny.obj")? {
            Some(x) => x,
            None => {
                eprintln!("bench: no bunny.obj: using a procedural sphere on a plane");
                let mut m =
                    relight_scene::shapes::uv_sphere(Vec3::new(0.0, 0.5, 0.0), 0.5, 96, 192);
                m.append(&relight_scene::shapes::ground_plane(Vec3::ZERO, 4.0, 64), 0);
                ("procedural sphere + plane".into(), m)
            }
        },
    )
}

/// The sections: the bake (samples, tree, cuts vs rays, extrapolation) and the light cut.
///
/// # Errors
/// A mesh that cannot be read, or a bake that fails.
pub(super) fn sections(
    bake_mesh: &Option<PathBuf>,
    data: &Option<PathBuf>,
    quick: bool,
) -> Result<Vec<Section>> {
    let (name, mesh) = bunny_or_sphere(bake_mesh, data)?;
    let err = |e: BakeError| MethodError::from(e);
    let lights = DEFAULT_SAMPLES;
    let t0 = Instant::now();
    let samples = EnvSamples::fibonacci(lights, 0).map_err(|e| err(e.into()))?;
    let samples_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t0 = Instant::now();
    let tree = LightTree::environment(&samples.dirs).map_err(|e| err(e.into()))?;
    let tree_ms = t0.elapsed().as_secs_f64() * 1e3;

    let caster = accel::build_default(&mesh);
    let sampler = VisibilitySampler::new(
        &mesh,
        caster.as_ref(),
        &samples.dirs,
        CutFunction::VisibilityCosine,
    )
    .map_err(err)?;
    let nv = mesh.vertex_count();
    let block = if quick { 64 } else { 1024 }.min(nv);
    let range = nv / 2 - block / 2..nv / 2 - block / 2 + block;
    let params = CutParams {
        sigma: relight_bake::cuts::cut::DEFAULT_SIGMA,
        max_nodes: relight_bake::cuts::cut::DEFAULT_MAX_CUT,
        threads: None,
        progress: false,
    };
    // Baseline: the same rays, the values thrown away; run before and after the cuts (the
    // first run also warms the caster and the thread pool), the faster one kept.
    let rays_only = || {
        let t0 = Instant::now();
        range.clone().into_par_iter().for_each_init(
            || (Scratch::default(), vec![0.0f32; lights]),
            |(s, out), v| {
                sampler.sample(v, out, s);
                std::hint::black_box(&out);
            },
        );
        t0.elapsed().as_secs_f64()
    };
    let rays_before = rays_only();
    let t0 = Instant::now();
    let cuts = sampler.cuts(&tree, range.clone(), &params).map_err(err)?;
    let cuts_s = t0.elapsed().as_secs_f64();
    let rays_s = rays_before.min(rays_only());
    let per_vertex_ms = cuts_s / block as f64 * 1e3;
    let whole_s = cuts_s / block as f64 * nv as f64 + (samples_ms + tree_ms) / 1e3;
    let mut bake = Section::new(
        format!(
            "Cuts bake: {name} ({nv} vertices), {lights} lights, sigma 2, cap 1000, {}, {} \
             threads; block of {block} vertices",
            caster.name(),
            rayon::current_num_threads()
        ),
        &[
            "samples (ms)",
            "tree (ms)",
            "cuts (s)",
            "same rays only (s)",
            "overhead",
            "per vertex (ms)",
            "mean cut",
            "capped",
            "whole mesh est. (s)",
            "target (s)",
        ],
    );
    bake.row(vec![
        json!(samples_ms),
        json!(tree_ms),
        json!(cuts_s),
        json!(rays_s),
        json!(cuts_s / rays_s),
        json!(per_vertex_ms),
        json!(cuts.mean_len()),
        json!(cuts.capped.len()),
        json!(whole_s),
        json!(TARGET_SECONDS),
    ]);

    // Illumination cuts of a sky with a sun (512 x 256 latlong).
    let env = sky_with_sun();
    let radiance_ms = median_ms(3, || {
        std::hint::black_box(sample_radiance(&samples, &env).ok());
    });
    let power = sample_power(&samples, &env).map_err(|e| err(e.into()))?;
    let mut lc = Section::new(
        format!("Illumination cut: {lights} lights, sky + sun, sigma {DEFAULT_LIGHT_SIGMA}"),
        &[
            "budget",
            "build (ms)",
            "sample radiance, grid included (ms)",
            "error bound met",
        ],
    );
    for budget in LIGHT_CUT_BUDGETS {
        let mut met = false;
        let ms = median_ms(5, || {
            if let Ok(c) = LightCut::build(&tree, &power, DEFAULT_LIGHT_SIGMA, budget) {
                met = c.error_bound_met;
            }
        });
        lc.row(vec![
            json!(budget),
            json!(ms),
            json!(radiance_ms),
            json!(met),
        ]);
    }
    let mut sections = vec![
        bake,
        lc,
        shade_section(
            &mesh,
            &samples,
            &tree,
            &power,
            range.clone(),
            caster.as_ref(),
            quick,
        )?,
    ];
    if !quick {
        let mut kinds = Section::new(
            format!("Light trees on {name}: mean cut of the same {block} vertices"),
            &[
                "function",
                "tree",
                "beta",
                "pilot pass (s)",
                "tree build (s)",
                "mean cut",
                "capped",
            ],
        );
        let normals: Vec<Vec3> = samples.dirs.iter().map(|&d| -d).collect();
        for function in [CutFunction::VisibilityCosine, CutFunction::Visibility] {
            let fname = match function {
                CutFunction::VisibilityCosine => "V max(0, cos)",
                CutFunction::Visibility => "V",
            };
            let sampler = VisibilitySampler::new(&mesh, caster.as_ref(), &samples.dirs, function)
                .map_err(err)?;
            let c = sampler.cuts(&tree, range.clone(), &params).map_err(err)?;
            kinds.row(vec![
                json!(fname),
                json!("geometric"),
                json!(1.0),
                json!(0.0),
                json!(tree_ms / 1e3),
                json!(c.mean_len()),
                json!(c.capped.len()),
            ]);
            let t0 = Instant::now();
            let pilot = sampler
                .pilot_vectors(DEFAULT_VERTEX_CLUSTERS, DEFAULT_K, None, false)
                .map_err(err)?;
            let pilot_s = t0.elapsed().as_secs_f64();
            for beta in [DEFAULT_BETA, 0.0] {
                let t0 = Instant::now();
                let dd = LightTree::data_driven(&samples.dirs, &normals, &pilot, DEFAULT_K, beta)
                    .map_err(|e| err(e.into()))?;
                let build_s = t0.elapsed().as_secs_f64();
                let c = sampler.cuts(&dd, range.clone(), &params).map_err(err)?;
                kinds.row(vec![
                    json!(fname),
                    json!("data-driven"),
                    json!(beta),
                    json!(pilot_s),
                    json!(build_s),
                    json!(c.mean_len()),
                    json!(c.capped.len()),
                ]);
            }
        }
        sections.push(kinds);
    }
    Ok(sections)
}

/// Per-pixel cost of [`shade`] (see the module docs, item 5).
fn shade_section(
    mesh: &TriMesh,
    samples: &EnvSamples,
    tree: &LightTree,
    power: &[Vec3],
    range: Range<usize>,
    caster: &dyn RayCaster,
    quick: bool,
) -> Result<Section> {
    let err = |e: BakeError| MethodError::from(e);
    let sampler = VisibilitySampler::new(mesh, caster, &samples.dirs, CutFunction::Visibility)
        .map_err(err)?;
    let params = CutParams {
        sigma: relight_bake::cuts::cut::DEFAULT_SIGMA,
        max_nodes: relight_bake::cuts::cut::DEFAULT_MAX_CUT,
        threads: None,
        progress: false,
    };
    let cuts = sampler.cuts(tree, range.clone(), &params).map_err(err)?;
    // Triangles with their three vertices in the block (else consecutive vertex triples).
    let start = range.start as u32;
    let mut tris: Vec<[u32; 3]> = mesh
        .indices
        .iter()
        .filter(|t| t.iter().all(|&v| range.contains(&(v as usize))))
        .map(|t| t.map(|v| v - start))
        .collect();
    if tris.is_empty() {
        tris = (0..range.len() as u32 / 3)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
    }
    let pixels = if quick { 2_000 } else { 20_000 };
    let materials = [
        (
            "Lambert",
            Material::Lambert {
                albedo: Vec3::splat(0.7),
            },
        ),
        (
            "GGX conductor a=0.2",
            Material::GgxConductor {
                specular: Vec3::splat(0.9),
                alpha: 0.2,
            },
        ),
    ];
    let threads = rayon::current_num_threads();
    let mut sec = Section::new(
        format!(
            "Cuts per-pixel shading (binary visibility cuts, mean {:.0} nodes; {} triangles), \
             one thread, 512 x 512 extrapolated to {threads} threads",
            cuts.mean_len(),
            tris.len()
        ),
        &[
            "material",
            "light cut",
            "merged nodes",
            "per pixel (us)",
            "512x512 frame (ms)",
            "target (ms)",
        ],
    );
    for (mname, mat) in materials {
        for budget in LIGHT_CUT_BUDGETS {
            let lc = LightCut::build(tree, power, DEFAULT_LIGHT_SIGMA, budget)
                .map_err(|e| err(e.into()))?;
            let mut rng = Rng::new(5, budget as u64);
            let t0 = Instant::now();
            let mut acc = Vec3::ZERO;
            for _ in 0..pixels {
                let t = tris[rng.next_below(tris.len() as u32) as usize];
                let (a, b) = (rng.next_f32(), rng.next_f32());
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                let bary = [1.0 - a - b, a, b];
                let n = (mesh.normals[t[0] as usize + start as usize]
                    + mesh.normals[t[1] as usize + start as usize]
                    + mesh.normals[t[2] as usize + start as usize])
                    .normalize_or(Vec3::Y);
                let frame = Frame::from_normal(n);
                let wi = frame.to_local((n + Vec3::new(0.3, 0.2, 0.1)).normalize());
                let vc = [0, 1, 2].map(|k| cuts.cut(t[k] as usize));
                acc += shade(&lc, vc, bary, false, |w| mat.lobes(wi, frame.to_local(w)));
            }
            std::hint::black_box(acc);
            let us = t0.elapsed().as_secs_f64() * 1e6 / pixels as f64;
            // Merged clusters per pixel (the traversal's length), counted apart from the
            // timing.
            let mut merged = 0usize;
            for t in &tris {
                let vc = [0, 1, 2].map(|k| CutKeys::from(cuts.cut(t[k] as usize)));
                merge_cuts([CutKeys::from(&lc), vc[0], vc[1], vc[2]], |_, _| {
                    merged += 1
                });
            }
            sec.row(vec![
                json!(mname),
                json!(budget),
                json!(merged as f64 / tris.len() as f64),
                json!(us),
                json!(us * 512.0 * 512.0 / threads as f64 / 1e3),
                json!(1e3 / 6.4),
            ]);
        }
    }
    Ok(sec)
}
