//! Exact SH projection of a latlong map against the point rule (section "SH projection of a
//! latlong map"; formerly the ignored test `bench_latlong_projection` of
//! `relight_sphere::sh::project`).
//!
//! [`relight_sphere::sh::project::project_latlong`] integrates the bilinear interpolant of the
//! map exactly (Fourier sums in phi, Gauss-Legendre in theta); the baseline is
//! [`relight_sphere::sh::project_env_point_rule`], which evaluates `order^2` harmonics per
//! texel. Both run on one thread, on the same random map.

use super::Section;
use glam::Vec3;
use relight_sphere::envmap::EnvMap;
use relight_sphere::sh::project::{project_latlong, LatLongProjector};
use relight_sphere::sh::project_env_point_rule;
use relight_sphere::warp::Rng;
use serde_json::json;
use std::time::Instant;

/// Times of one projection (best of the runs), milliseconds.
#[derive(Clone, Debug, PartialEq)]
pub struct ProjectionBench {
    /// Map width (height is half of it).
    pub width: usize,
    /// SH order.
    pub order: usize,
    /// `project_latlong`: projector built and applied.
    pub exact_ms: f64,
    /// Building a [`LatLongProjector`] alone.
    pub build_ms: f64,
    /// Applying a projector built beforehand (a video frame of the same size).
    pub reuse_ms: f64,
    /// The point rule.
    pub point_rule_ms: f64,
    /// Largest difference of a coefficient between the two projections.
    pub max_difference: f64,
    /// The exact `L_00` (red), the scale `max_difference` is to be read against.
    pub l00: f64,
}

/// Best wall time of `runs` calls of `f` (milliseconds) and the last result.
fn best_of<T>(runs: usize, f: impl Fn() -> T) -> (f64, T) {
    let mut best = f64::MAX;
    let mut out = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        out = Some(std::hint::black_box(f()));
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (best, out.expect("at least one run"))
}

/// Project a random `width x width/2` latlong map at SH `order` exactly (whole, projector
/// built, projector reused) and with the point rule, each the best of `runs`.
///
/// # Panics
/// If `width < 4` or `order` exceeds `relight_sphere::sh::MAX_ORDER`.
pub fn bench_projection(width: usize, order: usize, runs: usize) -> ProjectionBench {
    let (w, h) = (width, width / 2);
    let mut rng = Rng::new(1, 1);
    let tex: Vec<Vec3> = (0..w * h)
        .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
        .collect();
    let map = EnvMap::latlong(w, h, tex);
    let (exact_ms, exact) = best_of(runs, || project_latlong(&map, order));
    let (build_ms, pr) = best_of(runs, || LatLongProjector::new(w, h, order));
    let (reuse_ms, _) = best_of(runs, || pr.project(map.texels()));
    let (point_rule_ms, point) = best_of(runs, || project_env_point_rule(&map, order));
    let max_difference = exact
        .iter()
        .zip(&point)
        .map(|(a, b)| (*a - *b).abs().max_element() as f64)
        .fold(0.0, f64::max);
    ProjectionBench {
        width,
        order,
        exact_ms,
        build_ms,
        reuse_ms,
        point_rule_ms,
        max_difference,
        l00: exact[0].x as f64,
    }
}

/// The section: a 1024 x 512 map at order 10, best of 3 (about half a second on an idle
/// machine); 256 x 128, best of 2 with `quick`.
pub(super) fn section(quick: bool) -> Section {
    let (width, runs) = if quick { (256, 2) } else { (1024, 3) };
    let b = bench_projection(width, 10, runs);
    let mut sec = Section::new(
        format!(
            "SH projection of a latlong map: {} x {}, order {}, random texels, one thread \
             (best of {runs})",
            b.width,
            b.width / 2,
            b.order
        ),
        &[
            "exact (ms)",
            "projector build (ms)",
            "projector reuse (ms)",
            "point rule (ms)",
            "point rule / exact",
            "point rule / reuse",
            "max |exact - point rule| over L00 (%)",
            "L00",
        ],
    );
    sec.row(vec![
        json!(b.exact_ms),
        json!(b.build_ms),
        json!(b.reuse_ms),
        json!(b.point_rule_ms),
        json!(b.point_rule_ms / b.exact_ms),
        json!(b.point_rule_ms / b.reuse_ms),
        json!(100.0 * b.max_difference / b.l00),
        json!(b.l00),
    ]);
    sec
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projections_agree_and_times_are_positive() {
        let b = bench_projection(64, 4, 1);
        assert!(
            b.exact_ms > 0.0 && b.build_ms > 0.0 && b.point_rule_ms > 0.0,
            "{b:?}"
        );
        // Texels uniform in [0, 1): L00 = 2 sqrt(pi) * 0.5 = 1.77 up to sampling noise.
        assert!((b.l00 - 1.772).abs() < 0.05, "{b:?}");
        // The point rule differs from the exact integral by its quadrature error, small
        // against L00 at 64 x 32.
        assert!(b.max_difference < 0.05 * b.l00, "{b:?}");
    }
}
