//! The SG fitter (section "SG fitter"; formerly the ignored test `fit_timing` of
//! `relight_sphere::sg_fit`): time per bounded Levenberg-Marquardt fit
//! ([`relight_sphere::sg_fit::fit`], greedy from scratch, default options) of 1, 2 and 3
//! lobes to a glossy BRDF lobe tabulated on a `6 x n x n` cube map, at the SG bake's two
//! resolutions (6 x 8 x 8 indirect, 6 x 32 x 32 direct). Its baseline is the 1-lobe fit of the
//! same target in the same run.
//!
//! Targets: `T(w) = glossy_eval(v, w)` (cosine included, per steradian, as the bake
//! tabulates) about the normal `+Y` for the view `v = (0.6, 0.8, 0)` (37 degrees off the
//! normal), for a Blinn-Phong lobe of exponent 40 (the former test's lobe) and a GGX
//! conductor of roughness 0.2. Options are [`FitOptions::default`], as in the former test (up
//! to 100 iterations, stop below a 1e-6 relative gain); the bake instead bounds the sharpness
//! by `(n / 2)^2`, stops below 0.1 % and mostly refines warm-started fits
//! ([`relight_sphere::sg_fit::refine`]): section "SG bake" measures those.

use super::{median, Section};
use glam::Vec3;
use relight_scene::material::Material;
use relight_sphere::envmap::EnvMap;
use relight_sphere::sg_fit::{fit, FitOptions, FitTarget};
use relight_sphere::warp::Frame;
use serde_json::json;
use std::time::Instant;

/// One fit, timed.
#[derive(Clone, Debug, PartialEq)]
pub struct FitBench {
    /// Median wall time of one fit, milliseconds.
    pub ms: f64,
    /// Levenberg-Marquardt iterations of the fit.
    pub iterations: usize,
    /// Relative L2 error of the fit.
    pub relative_error: f64,
}

/// The glossy lobe of `material` for the view `(0.6, 0.8, 0)` about the normal `+Y`,
/// tabulated on a `6 x n x n` cube map (module docs).
pub fn glossy_target(material: &Material, n: usize) -> FitTarget {
    let frame = Frame::from_normal(Vec3::Y);
    let wi = frame.to_local(Vec3::new(0.6, 0.8, 0.0));
    FitTarget::from_env(&EnvMap::cube_from_fn(n, |w| {
        material.glossy_eval(wi, frame.to_local(w))
    }))
}

/// Fit `lobes` lobes to `target` `runs` times (the fit is deterministic); the median time.
pub fn bench_fit(target: &FitTarget, lobes: usize, runs: usize) -> FitBench {
    let mut times = vec![];
    let mut last = None;
    for _ in 0..runs.max(1) {
        let t0 = Instant::now();
        let r = fit(target, lobes, &FitOptions::default(), None);
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        last = Some(r);
    }
    let r = last.expect("at least one run");
    FitBench {
        ms: median(times),
        iterations: r.iterations,
        relative_error: r.relative_error,
    }
}

/// The two BRDFs of the section with their names.
fn materials() -> [(&'static str, Material); 2] {
    [
        (
            "Blinn-Phong, exponent 40",
            Material::BlinnPhong {
                diffuse: Vec3::ZERO,
                specular: Vec3::new(0.5, 0.4, 0.3),
                exponent: 40.0,
            },
        ),
        (
            "GGX conductor, alpha 0.2",
            Material::GgxConductor {
                specular: Vec3::new(0.9, 0.7, 0.5),
                alpha: 0.2,
            },
        ),
    ]
}

/// The section: both BRDFs at 6 x 8 x 8 and 6 x 32 x 32, 1 to 3 lobes, median of 5 fits
/// (1 and 2 lobes, one fit each with `quick`).
pub(super) fn section(quick: bool) -> Section {
    let (max_lobes, runs) = if quick { (2, 1) } else { (3, 5) };
    let mut sec = Section::new(
        format!(
            "SG fitter: one Levenberg-Marquardt fit (greedy, from scratch) to a tabulated \
             glossy lobe, one thread (median of {runs})"
        ),
        &[
            "BRDF",
            "cube map",
            "lobes",
            "ms per fit",
            "time over the 1-lobe fit",
            "iterations",
            "relative error",
        ],
    );
    for (name, m) in materials() {
        for n in [8, 32] {
            let target = glossy_target(&m, n);
            let mut one = f64::NAN;
            for lobes in 1..=max_lobes {
                let b = bench_fit(&target, lobes, runs);
                if lobes == 1 {
                    one = b.ms;
                }
                sec.row(vec![
                    json!(name),
                    json!(format!("6 x {n} x {n}")),
                    json!(lobes),
                    json!(b.ms),
                    json!(b.ms / one),
                    json!(b.iterations),
                    json!(b.relative_error),
                ]);
            }
        }
    }
    sec
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_lobes_fit_a_glossy_lobe_better_than_one() {
        for (name, m) in materials() {
            let target = glossy_target(&m, 8);
            assert!(target.norm2() > 0.0, "{name}");
            let one = bench_fit(&target, 1, 1);
            let two = bench_fit(&target, 2, 1);
            assert!(one.ms > 0.0 && one.iterations > 0, "{name}: {one:?}");
            // A second lobe can only lower the error of the greedy fit (it starts from the
            // one-lobe solution); 1e-9 for rounding.
            assert!(
                two.relative_error <= one.relative_error + 1e-9,
                "{name}: {one:?} {two:?}"
            );
            assert!(one.relative_error < 0.5, "{name}: {one:?}");
        }
    }
}
