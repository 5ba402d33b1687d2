//! The vMF material fit, EM against nonlinear least squares (section "vMF fit"; the
//! paper's section 6.1: "For a Blinn-Phong BRDF with glossy exponent e = 128,
//! it takes about 47 seconds to compute all slice parameters with the nonlinear minimization
//! procedure \[CL96\]. Fitting a similar transfer function with our EM estimation on the other
//! hand, takes about 2 seconds").
//!
//! Per view, the two ways of getting the eq. 9 glossy lobe of a Blinn-Phong material:
//! * **EM** (closed form, eq. 13-14 with the maximum-likelihood kappa): what the bake runs,
//!   [`MaterialLobes::fit`] from `n = 1024` importance-sampled directions per term (the
//!   bake's `--material-samples`), both terms;
//! * **LM**: the glossy term tabulated on a `6 x 32 x 32` cube map (the `sg` bake's direct
//!   resolution) and fitted by relight's bounded Levenberg-Marquardt
//!   ([`relight_sphere::sg_fit::fit`], 1 lobe, default options), tabulation included.
//!
//! Both over the views of icosahedral level 3 above the horizon (the paper's "all slice
//! parameters" of one material; its bake allows level 5). The baseline is EM in the same run.
//! The accuracy of the two on the same slices is `relight_sphere::vmf::em`'s test
//! `em_vs_levenberg_marquardt` (docs/RESULTS.md, section vmf).

use super::Section;
use glam::Vec3;
use relight_bake::vmf::{views_of_level, MaterialLobes};
use relight_scene::material::Material;
use relight_sphere::envmap::EnvMap;
use relight_sphere::sg_fit::{fit, FitOptions, FitTarget};
use serde_json::json;
use std::time::Instant;

/// The glossy term of `m` for the local `view` (normal +Z) on a `6 x n x n` cube map.
pub fn tabulated_glossy(m: &Material, view: Vec3, n: usize) -> FitTarget {
    FitTarget::from_env(&EnvMap::cube_from_fn(n, |w| m.glossy_eval(view, w)))
}

/// Seconds to fit every view of `views` by EM and by LM, and LM's mean relative L2 error.
pub fn fit_views(m: &Material, views: &[Vec3], samples: u32) -> (f64, f64, f64) {
    let t0 = Instant::now();
    for &v in views {
        std::hint::black_box(MaterialLobes::fit(m, v, samples));
    }
    let em = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let mut err = 0.0;
    for &v in views {
        let target = tabulated_glossy(m, v, 32);
        err += fit(&target, 1, &FitOptions::default(), None).relative_error;
    }
    let lm = t0.elapsed().as_secs_f64();
    (em, lm, err / views.len().max(1) as f64)
}

/// The section: Blinn-Phong exponents 32 and 128 (only 128 with `quick`, on level-2 views).
pub(super) fn section(quick: bool) -> Section {
    let level = if quick { 2 } else { 3 };
    let views = views_of_level(level);
    let mut sec = Section::new(
        format!(
            "vMF fit: eq. 9 lobes of a Blinn-Phong material for the {} views of level {level}, EM \
             (closed form, 1024 samples per term) against Levenberg-Marquardt on a 6 x 32 x 32 \
             tabulation, one thread (paper: 2 s against 47 s at exponent 128)",
            views.len()
        ),
        &[
            "exponent",
            "views",
            "EM s (all views)",
            "LM s (all views)",
            "LM over EM",
            "LM relative L2 error",
        ],
    );
    let exps: &[f32] = if quick { &[128.0] } else { &[32.0, 128.0] };
    for &e in exps {
        let m = Material::BlinnPhong {
            diffuse: Vec3::splat(0.1),
            specular: Vec3::splat(0.6),
            exponent: e,
        };
        let (em, lm, err) = fit_views(&m, &views, 1024);
        sec.row(vec![
            json!(e),
            json!(views.len()),
            json!(em),
            json!(lm),
            json!(lm / em),
            json!(err),
        ]);
    }
    sec
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_fits_run_and_lm_fits_the_tabulated_lobe() {
        let m = Material::BlinnPhong {
            diffuse: Vec3::splat(0.1),
            specular: Vec3::splat(0.6),
            exponent: 32.0,
        };
        let views = &views_of_level(0);
        let (em, lm, err) = fit_views(&m, views, 256);
        assert!(em > 0.0 && lm > 0.0);
        // A Blinn-Phong lobe away from the horizon is nearly one vMF: measured below 10 %
        // (the 4 level-0 views are 30 degrees up or more).
        assert!(err < 0.2, "{err}");
    }
}
