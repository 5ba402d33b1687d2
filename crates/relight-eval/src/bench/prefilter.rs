//! The Gaussian-prefiltered environment (section "Gaussian-prefiltered environment"):
//! 6 x 256 x 256, 8 levels, sequential ([`PrefilteredEnv::build`]) and with the per-(level,
//! face) jobs on rayon's pool, against cmft's published 6.0 s.

use super::Section;
use glam::Vec3;
use rayon::prelude::*;
use relight_sphere::cubemap::CubeFace;
use relight_sphere::env_prefilter::{
    default_levels, prefilter_face, PrefilterLevel, PrefilterOptions, PrefilteredEnv, SourcePyramid,
};
use relight_sphere::envmap::EnvMap;
use serde_json::json;
use std::time::Instant;

/// The benchmark's environment, `6 x n x n`: a sky gradient with a sun-like disc and two
/// small lights (`relight_sphere::decompose::sky_with_discs`; the prefilter's cost does not
/// depend on the content).
pub fn bench_map(n: usize) -> EnvMap {
    relight_sphere::decompose::sky_with_discs(
        n,
        &[
            (
                Vec3::new(0.4, 0.7, -0.59).normalize(),
                2.5,
                Vec3::new(50.0, 45.0, 40.0),
            ),
            (
                Vec3::new(-0.8, 0.1, 0.59).normalize(),
                5.0,
                Vec3::splat(3.0),
            ),
            (Vec3::X, 5.0, Vec3::splat(5.0)),
        ],
    )
}

/// Seconds to prefilter `map` into `levels` on one thread ([`PrefilteredEnv::build`],
/// pyramid included).
pub fn prefilter_sequential(map: &EnvMap, levels: &[PrefilterLevel]) -> f64 {
    let t0 = Instant::now();
    let p = PrefilteredEnv::build(map, levels, &PrefilterOptions::default());
    let s = t0.elapsed().as_secs_f64();
    std::hint::black_box(p);
    s
}

/// Seconds to prefilter `map` into `levels` with the faces of each level as jobs on rayon's
/// current pool (pyramid included).
pub fn prefilter_parallel(map: &EnvMap, levels: &[PrefilterLevel]) -> f64 {
    let opts = PrefilterOptions::default();
    let t0 = Instant::now();
    let pyr = SourcePyramid::new(map);
    let data: Vec<Vec<Vec3>> = levels
        .iter()
        .map(|l| {
            let mut v = vec![Vec3::ZERO; 6 * l.size * l.size];
            v.par_chunks_mut(l.size * l.size)
                .enumerate()
                .for_each(|(f, chunk)| {
                    prefilter_face(&pyr, l, &opts, CubeFace::from_index(f), chunk)
                });
            v
        })
        .collect();
    std::hint::black_box(PrefilteredEnv::from_levels(levels.to_vec(), data));
    t0.elapsed().as_secs_f64()
}

/// The section: [`bench_map`]`(256)` into the 8 default levels, sequential and on every
/// thread of rayon's pool.
pub(super) fn section() -> Section {
    let map = bench_map(256);
    let levels = default_levels(256, 8);
    let sequential = prefilter_sequential(&map, &levels);
    let parallel = prefilter_parallel(&map, &levels);
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
