//! EM against nonlinear least squares on the same transfer slices (Laurijssen & Dutré 2009,
//! section 6.1, where the Coleman-Li trust-region fit of the materials took 47 s against 2 s
//! for EM). Test-only: it reports errors, never timings.
//!
//! # What is compared
//! * **EM** ([`super::fit_em`]) sees the slice `T` only through `N` path samples: directions
//!   importance-sampled from the material's lobe and weighted by `T / pdf / N`, as the paper's
//!   section 5.1 produces them. It maximises the weighted likelihood, i.e. minimises the
//!   Kullback-Leibler divergence from `T / int T` to the mixture's shape; the amplitudes are
//!   the Monte Carlo estimates of the classes' integrals, so the energy is unbiased.
//! * **LM** ([`crate::sg_fit::fit`], bounded Levenberg-Marquardt with greedy initialisation)
//!   sees `T` tabulated on a 6 x 32 x 32 cube map and minimises the squared L2 error directly,
//!   with free amplitudes (no energy term); its SG lobes are converted with
//!   [`VmfLobe::from_sg`].
//!
//! Both are scored by the relative L2 error `|T - fit| / |T|` (exact closed forms for a vMF
//! slice, a fine quadrature otherwise) and by the relative energy error.
//!
//! # Findings (test `em_vs_levenberg_marquardt`, printed table; N = 20000 samples)
//!
//! ```text
//! slice              lobes  EM L2 err  LM L2 err  EM energy err  LM energy err
//! vMF mixture            1     0.7906     0.1617         0.00e0       -2.86e-1
//! vMF mixture            2     0.0175     0.0004         0.00e0       -4.17e-7
//! Phong 64 at 75deg      1     0.0603     0.0495       -2.65e-4        7.08e-3
//! Phong 64 at 75deg      2     0.0436     0.0235       -2.65e-4        6.53e-3
//! ```
//! * On a slice that *is* a 2-lobe vMF mixture (kappa 40 and 6, 60 degrees apart), LM on
//!   noise-free tabulated data is essentially exact; EM from 20000 samples is off by its
//!   sampling noise (1.8 %). With **one** lobe the two differ most: the likelihood estimate of
//!   a two-peaked class is a broad lobe between the peaks (79 % L2 error, all the energy), the
//!   least-squares one sits on the main peak (16 %, but 29 % of the energy lost). This is where
//!   the multi-lobe EM (the paper's future work) helps: 79 % -> 1.8 %.
//! * On a cosine-weighted Phong slice (exponent 64) at a grazing view (mirror direction 15
//!   degrees above the horizon, so the lobe is clipped and skewed: not a vMF), LM has the lower
//!   L2 error, as it optimises that norm (5.0 % vs 6.0 % with one lobe, 2.4 % vs 4.4 % with
//!   two); EM keeps the energy to Monte Carlo accuracy (3e-4) where LM's free amplitudes are
//!   0.7 % off.
//! * So EM gives up a little L2 accuracy for needing no tabulation of the slice (it consumes
//!   the path samples directly) and exact energy; the paper's speed argument (section 6.1) is
//!   not measured here.

use super::super::distance::mixture_l2_distance_squared;
use super::super::tests::degree_for;
use super::*;
use crate::envmap::EnvMap;
use crate::quadrature::sphere_rule;
use crate::sg_fit::{fit, FitOptions, FitTarget};
use crate::warp::Frame;
use crate::{Rng, Vec2};
use std::f64::consts::PI;

/// Relative L2 error of `lobes` against `t` by a product rule of the given degree (f64).
fn rel_l2(t: &dyn Fn(Vec3) -> f64, lobes: &[VmfLobe], degree: usize) -> f64 {
    let (d, w) = sphere_rule(degree);
    let (mut e, mut n) = (0.0, 0.0);
    for (d, w) in d.iter().zip(&w) {
        let v = Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
        let f: f64 = lobes
            .iter()
            .map(|l| l.amplitude.x as f64 * l.eval_unit64(v))
            .sum();
        let tv = t(v);
        e += (tv - f) * (tv - f) * w;
        n += tv * tv * w;
    }
    (e / n).sqrt()
}

fn lm_lobes(t: &dyn Fn(Vec3) -> f64, k: usize) -> Vec<VmfLobe> {
    let target = FitTarget::from_env(&EnvMap::cube_from_fn(32, |d| Vec3::splat(t(d) as f32)));
    fit(&target, k, &FitOptions::default(), None)
        .lobes
        .iter()
        .filter(|g| g.amplitude.x > 0.0)
        .map(VmfLobe::from_sg)
        .collect()
}

#[test]
fn em_vs_levenberg_marquardt() {
    let n = 20_000;
    println!("slice            lobes  EM L2 err  LM L2 err  EM energy err  LM energy err");
    // (a) A 2-lobe vMF slice, sampled exactly (uniform weights).
    let truth = [
        VmfLobe::new(Vec3::new(0.0, 1.0, 0.0), 40.0, Vec3::splat(0.7)),
        VmfLobe::new(Vec3::new(0.0, 0.5, 0.866), 6.0, Vec3::splat(0.3)),
    ];
    let tf = |d: Vec3| eval_mixture_x(&truth, d);
    let mut rng = Rng::new(1, 2);
    let samples: Vec<WeightedDir> = (0..n)
        .map(|_| {
            let l = if rng.next_f32() < 0.7 {
                &truth[0]
            } else {
                &truth[1]
            };
            WeightedDir {
                dir: crate::vmf::sample_vmf(l.axis, l.kappa, rng.next_vec2()),
                weight: Vec3::splat(1.0 / n as f32),
            }
        })
        .collect();
    let norm = mixture_l2_distance_squared(&truth, &[]).x.sqrt();
    let mut a_err = vec![];
    for k in [1, 2] {
        let em = fit_em(&samples, k, &EmOptions::default()).unwrap().lobes;
        let lm = lm_lobes(&tf, k);
        let e_em = mixture_l2_distance_squared(&truth, &em).x.sqrt() / norm;
        let e_lm = mixture_l2_distance_squared(&truth, &lm).x.sqrt() / norm;
        let en = |l: &[VmfLobe]| l.iter().map(|l| l.amplitude.x).sum::<f32>() - 1.0;
        println!(
            "vMF mixture      {k:5}  {e_em:9.4}  {e_lm:9.4}  {:13.2e}  {:13.2e}",
            en(&em),
            en(&lm)
        );
        a_err.push((e_em, e_lm));
    }
    // Two lobes: LM on noise-free data of its own model class is near exact (cube-map
    // quadrature only); EM is within sampling noise (L2 error ~ a few / sqrt(N)).
    assert!(a_err[1].1 < 5e-3, "{a_err:?}");
    assert!(a_err[1].0 < 3e-2, "{a_err:?}");
    // The second lobe is needed: it divides EM's error by more than 10.
    assert!(a_err[1].0 < 0.1 * a_err[0].0, "{a_err:?}");

    // (b) A cosine-weighted Phong slice (exponent 64) viewed at 75 degrees from the normal
    // (+Y): the mirror direction is 15 degrees above the horizon, so the lobe is clipped and
    // skewed. T(w) = (e + 2) / (2 pi) max(0, r . w)^e max(0, w . N).
    let e = 64.0f64;
    let th = 75f64.to_radians();
    let r = Vec3::new(th.sin() as f32, th.cos() as f32, 0.0);
    let t = |d: Vec3| {
        let c = (r.dot(d) as f64).max(0.0);
        (e + 2.0) / (2.0 * PI) * c.powf(e) * (d.y as f64).max(0.0)
    };
    // Phong lobe sampling about r: cos alpha = u^(1 / (e + 1)), pdf (e + 1) / (2 pi) cos^e;
    // weight T / pdf / N = (e + 2) / (e + 1) max(0, w . N) / N (zero below the horizon).
    let frame = Frame::from_normal(r);
    let mut rng = Rng::new(4, 2);
    let samples: Vec<WeightedDir> = (0..n)
        .map(|_| {
            let u: Vec2 = rng.next_vec2();
            let ca = (u.x as f64).powf(1.0 / (e + 1.0));
            let sa = (1.0 - ca * ca).max(0.0).sqrt();
            let phi = 2.0 * PI * u.y as f64;
            let d = frame
                .to_world(Vec3::new(
                    (sa * phi.cos()) as f32,
                    (sa * phi.sin()) as f32,
                    ca as f32,
                ))
                .normalize();
            let wgt = (e + 2.0) / (e + 1.0) * (d.y as f64).max(0.0) / n as f64;
            WeightedDir {
                dir: d,
                weight: Vec3::splat(wgt as f32),
            }
        })
        .collect();
    // int T = (e + 2) / (e + 1) E_phong[max(0, w . N)] by a fine quadrature.
    let deg = degree_for(4.0 * e);
    let (d, w) = sphere_rule(deg);
    let energy: f64 = d
        .iter()
        .zip(&w)
        .map(|(d, w)| t(Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32)) * w)
        .sum();
    let mut b_err = vec![];
    for k in [1, 2] {
        let em = fit_em(&samples, k, &EmOptions::default()).unwrap().lobes;
        let lm = lm_lobes(&t, k);
        let (e_em, e_lm) = (rel_l2(&t, &em, deg), rel_l2(&t, &lm, deg));
        let en = |l: &[VmfLobe]| l.iter().map(|l| l.amplitude.x as f64).sum::<f64>() / energy - 1.0;
        println!(
            "Phong 64 at 75deg {k:4}  {e_em:9.4}  {e_lm:9.4}  {:13.2e}  {:13.2e}",
            en(&em),
            en(&lm)
        );
        b_err.push((e_em, e_lm, en(&em), en(&lm)));
    }
    // Measured (module docs): one lobe, EM 6.0 % and LM 5.0 % relative L2 error (a vMF
    // cannot take the clipped, skewed shape), two lobes 4.4 % and 2.4 %; EM's energy is a
    // Monte Carlo estimate, within 5 of its standard deviations sqrt(N var(w)) / sum(w).
    let (sum, sum2) = samples.iter().fold((0.0, 0.0), |(a, b), s| {
        let x = s.weight.x as f64;
        (a + x, b + x * x)
    });
    let sd = (sum2 - sum * sum / n as f64).max(0.0).sqrt() / sum;
    for (e_em, e_lm, en_em, _) in &b_err {
        assert!(*e_em < 0.1 && *e_lm < 0.1, "{b_err:?}");
        assert!(e_lm <= e_em, "LM minimises the L2 error: {b_err:?}");
        assert!(en_em.abs() < 5.0 * sd, "{b_err:?} sd {sd}");
    }
    // A second lobe lowers both errors.
    assert!(
        b_err[1].0 < b_err[0].0 && b_err[1].1 < b_err[0].1,
        "{b_err:?}"
    );
}

/// Channel x of a mixture in f64.
fn eval_mixture_x(lobes: &[VmfLobe], d: Vec3) -> f64 {
    lobes
        .iter()
        .map(|l| l.amplitude.x as f64 * l.eval_unit64(d))
        .sum()
}
