//! Tests of the estimators: recovery of known lobes from samples of the sampler (tolerances
//! from the estimators' standard deviations), weighted (importance) samples, nested fits whose
//! likelihood never drops, degenerate inputs, and EM against Levenberg-Marquardt on the same
//! slices.

use super::super::distance::mixture_l2_distance_squared;
use super::super::{mean_cosine, mean_cosine_derivative, sample_vmf};
use super::*;
use crate::Rng;

/// `n` samples of the mixture `truth` (component chosen with probability proportional to the
/// amplitude's channel sum), each weighing `total / n` so that the weights sum to the
/// mixture's integral per channel when all lobes share one colour.
fn samples_of(truth: &[VmfLobe], n: usize, seed: u64) -> Vec<WeightedDir> {
    let amp = |l: &VmfLobe| (l.amplitude.x + l.amplitude.y + l.amplitude.z) as f64;
    let total: f64 = truth.iter().map(amp).sum();
    let mut rng = Rng::new(seed, 7);
    let colour = truth[0].amplitude / amp(&truth[0]) as f32;
    (0..n)
        .map(|_| {
            let mut x = rng.next_f64() * total;
            let mut j = 0;
            while j + 1 < truth.len() && x >= amp(&truth[j]) {
                x -= amp(&truth[j]);
                j += 1;
            }
            WeightedDir {
                dir: sample_vmf(truth[j].axis, truth[j].kappa, rng.next_vec2()),
                weight: colour * (total / n as f64) as f32,
            }
        })
        .collect()
}

/// The angle between two unit f32 vectors in f64 from the chord, `2 asin(|a - b| / 2)`
/// (glam's f32 `angle_between` uses `acos`, whose resolution near 1 is 3.5e-4 radian).
fn angle64(a: Vec3, b: Vec3) -> f64 {
    let (a, b) = (crate::vmf::unit64(a), crate::vmf::unit64(b));
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    2.0 * (0.5 * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
        .min(1.0)
        .asin()
}

/// Standard deviations of the maximum-likelihood estimates from `n` samples of one lobe:
/// the axis (per tangent direction, radians) `1 / sqrt(n kappa A)` (the mean of the tangent
/// components has variance `A / (kappa n)`, divided by `r = A`), and `kappa` (relative)
/// `1 / (kappa sqrt(n A'(kappa)))` (inverse Fisher information of `kappa`).
fn sigmas(kappa: f64, n: f64) -> (f64, f64) {
    let a = mean_cosine(kappa);
    (
        1.0 / (n * kappa * a).sqrt(),
        1.0 / (kappa * (n * mean_cosine_derivative(kappa)).sqrt()),
    )
}

#[test]
fn one_lobe_estimate_recovers_known_lobes() {
    let n = 20_000;
    for (i, kappa) in [2.0f32, 20.0, 200.0, 1e4, 1e6].into_iter().enumerate() {
        let axis = crate::warp::square_to_uniform_sphere(Rng::new(i as u64, 1).next_vec2());
        let truth = VmfLobe::new(axis, kappa, Vec3::new(0.5, 0.3, 0.2));
        let s = samples_of(&[truth], n, 100 + i as u64);
        let ml = estimate_one_lobe(&s, KappaEstimate::MaximumLikelihood, KAPPA_MAX).unwrap();
        let (sa, sk) = sigmas(kappa as f64, n as f64);
        // 5 standard deviations: the angle is Rayleigh (P(> 5 sigma) = 4e-6), kappa Gaussian.
        let angle = angle64(ml.axis, axis);
        assert!(
            angle < 5.0 * sa + 2e-7,
            "kappa {kappa}: angle {angle} vs sigma {sa}"
        );
        let rel = ml.kappa as f64 / kappa as f64 - 1.0;
        assert!(
            rel.abs() < 5.0 * sk,
            "kappa {kappa}: {} ({rel} vs {sk})",
            ml.kappa
        );
        // eq. 15: the weights are the amplitude (sum of 20000 f32 weights of 5e-5 etc.).
        assert!((ml.amplitude - truth.amplitude).abs().max_element() < 1e-5);
        // eq. 13 is Banerjee's approximation applied to the same r.
        let b = estimate_one_lobe(&s, KappaEstimate::Banerjee, KAPPA_MAX).unwrap();
        let q = crate::vmf::one_minus_mean_cosine(ml.kappa as f64);
        let want = crate::vmf::kappa_banerjee(1.0 - q, q);
        assert!(
            (b.kappa as f64 / want - 1.0).abs() < 1e-5,
            "{} {want}",
            b.kappa
        );
        assert_eq!(b.axis, ml.axis);
        // EM with one lobe is the closed form.
        let em = fit_em(&s, 1, &EmOptions::default()).unwrap();
        assert!((em.lobes[0].kappa / ml.kappa - 1.0).abs() < 1e-6);
        assert!(angle64(em.lobes[0].axis, ml.axis) < 1e-6);
    }
}

#[test]
fn importance_weighted_samples_estimate_the_slice() {
    // Uniform directions weighted by T(x) / (N / 4 pi): the estimate targets T, with the
    // effective sample size (sum w)^2 / sum w^2 in place of N (~N / kappa here).
    let truth = VmfLobe::new(Vec3::new(0.0, 0.6, -0.8), 8.0, Vec3::new(1.0, 0.5, 0.25));
    let n = 40_000;
    let mut rng = Rng::new(3, 3);
    let s: Vec<WeightedDir> = (0..n)
        .map(|_| {
            let d = crate::warp::square_to_uniform_sphere(rng.next_vec2());
            WeightedDir {
                dir: d,
                weight: truth.eval(d) * (4.0 * std::f32::consts::PI / n as f32),
            }
        })
        .collect();
    let sw: f64 = s.iter().map(|w| w.weight.x as f64).sum();
    let sw2: f64 = s.iter().map(|w| (w.weight.x as f64).powi(2)).sum();
    let ess = sw * sw / sw2;
    let l = estimate_one_lobe(&s, KappaEstimate::MaximumLikelihood, KAPPA_MAX).unwrap();
    let (sa, sk) = sigmas(8.0, ess);
    assert!(angle64(l.axis, truth.axis) < 5.0 * sa, "{l:?} ess {ess}");
    assert!(
        (l.kappa as f64 / 8.0 - 1.0).abs() < 5.0 * sk,
        "{l:?} ess {ess}"
    );
    // The amplitude is a Monte Carlo estimate of the integral: relative sd sqrt(n sum w^2 /
    // (sum w)^2 - 1) / sqrt(n).
    let sd = ((n as f64 * sw2 / (sw * sw) - 1.0) / n as f64).sqrt();
    assert!(
        ((l.amplitude.x - 1.0) as f64).abs() < 5.0 * sd,
        "{l:?} sd {sd}"
    );
}

fn three_lobes() -> Vec<VmfLobe> {
    let c = Vec3::new(0.6, 0.3, 0.1);
    vec![
        VmfLobe::new(Vec3::new(0.3, 0.8, -0.2), 30.0, c * 0.5),
        VmfLobe::new(Vec3::new(-0.7, 0.1, 0.5), 8.0, c * 0.2),
        VmfLobe::new(Vec3::new(0.1, -0.6, -0.9), 80.0, c * 0.3),
    ]
}

#[test]
fn em_recovers_a_mixture_and_more_lobes_never_lower_the_likelihood() {
    let truth = three_lobes();
    let n = 30_000;
    let s = samples_of(&truth, n, 5);
    let fits = fit_em_nested(&s, 5, &EmOptions::default());
    assert_eq!(fits.len(), 5);
    let mut t64 = [0f64; 3];
    for w in &s {
        for (t, x) in t64.iter_mut().zip(w.weight.to_array()) {
            *t += x as f64;
        }
    }
    let total = Vec3::new(t64[0] as f32, t64[1] as f32, t64[2] as f32);
    println!("lobes  log-likelihood  iterations  rel. L2 error vs truth");
    let norm = mixture_l2_distance_squared(&truth, &[]).x.sqrt();
    let mut errors = vec![];
    for (k, f) in fits.iter().enumerate() {
        assert_eq!(f.lobes.len(), k + 1);
        // Energy kept: the amplitudes sum to the weights (f32 sums).
        let sum = f.lobes.iter().fold(Vec3::ZERO, |a, l| a + l.amplitude);
        assert!((sum - total).abs().max_element() < 1e-5, "{sum} {total}");
        assert!(f
            .lobes
            .iter()
            .all(|l| l.axis.is_finite() && l.kappa.is_finite()));
        let e = mixture_l2_distance_squared(&truth, &f.lobes).x.sqrt() / norm;
        println!(
            "{:5}  {:14.6}  {:10}  {e:.4}",
            k + 1,
            f.log_likelihood,
            f.iterations
        );
        errors.push(e);
        if k > 0 {
            // Nested fits: never lower (exactly: the fallback keeps the previous lobes).
            assert!(f.log_likelihood >= fits[k - 1].log_likelihood, "{k}");
        }
    }
    // The third lobe is what the data needs: the error drops by an order of magnitude from 1
    // to 3 lobes, and 4 or 5 lobes gain little likelihood (they split sampling noise).
    assert!(errors[2] < 0.1 * errors[0], "{errors:?}");
    assert!(fits[2].log_likelihood - fits[1].log_likelihood > 0.1);
    assert!(fits[4].log_likelihood - fits[2].log_likelihood < 1e-2);
    // The 3-lobe fit recovers each lobe within 6 standard deviations of its own sample count.
    let fit = &fits[2];
    for t in &truth {
        let l = fit
            .lobes
            .iter()
            .min_by(|a, b| angle64(a.axis, t.axis).total_cmp(&angle64(b.axis, t.axis)))
            .unwrap();
        let frac = t.amplitude.x as f64 / 0.6;
        let (sa, sk) = sigmas(t.kappa as f64, frac * n as f64);
        assert!(angle64(l.axis, t.axis) < 6.0 * sa, "{l:?} vs {t:?}");
        assert!(
            (l.kappa as f64 / t.kappa as f64 - 1.0).abs() < 6.0 * sk,
            "{l:?} vs {t:?}"
        );
        // The class weight is multinomial: sd sqrt(p (1 - p) / n).
        let got = l.amplitude.x as f64 / 0.6;
        let sd = (frac * (1.0 - frac) / n as f64).sqrt();
        assert!((got - frac).abs() < 6.0 * sd, "{got} vs {frac}");
    }
    // The public likelihood of the f32 lobes agrees with the fit's (f64 parameters).
    let ll = log_likelihood(&s, &fit.lobes).unwrap();
    assert!(
        (ll - fit.log_likelihood).abs() < 1e-5,
        "{ll} {}",
        fit.log_likelihood
    );
    // Deterministic.
    assert_eq!(fit_em(&s, 3, &EmOptions::default()).unwrap(), fits[2]);
}

#[test]
fn degenerate_inputs_give_no_nan() {
    let opts = EmOptions::default();
    let check = |f: &EmFit, total: Vec3| {
        assert!(f.log_likelihood.is_finite());
        for l in &f.lobes {
            assert!(
                l.axis.is_finite() && (l.axis.length() - 1.0).abs() < 1e-5,
                "{l:?}"
            );
            assert!(l.kappa.is_finite() && l.kappa >= 0.0 && l.kappa <= opts.kappa_max);
            assert!(l.amplitude.is_finite() && l.amplitude.min_element() >= 0.0);
        }
        let sum = f.lobes.iter().fold(Vec3::ZERO, |a, l| a + l.amplitude);
        assert!((sum - total).abs().max_element() < 1e-5 * total.max_element().max(1.0));
    };
    // No samples, all weights zero, only invalid weights or directions: no lobe.
    let w = |d: Vec3, x: f32| WeightedDir {
        dir: d,
        weight: Vec3::splat(x),
    };
    for s in [
        vec![],
        vec![w(Vec3::Y, 0.0); 10],
        vec![w(Vec3::Y, -1.0), w(Vec3::X, f32::NAN), w(Vec3::ZERO, 1.0)],
        vec![w(Vec3::splat(f32::NAN), 1.0)],
    ] {
        assert!(estimate_one_lobe(&s, KappaEstimate::Banerjee, KAPPA_MAX).is_none());
        assert!(fit_em(&s, 3, &opts).is_none());
        assert!(fit_em_nested(&s, 3, &opts).is_empty());
        assert!(log_likelihood(&s, &three_lobes()).is_none());
    }
    assert!(fit_em(&[w(Vec3::Y, 1.0)], 0, &opts).is_none());
    // One sample: kappa_max about it, its weight as amplitude; more lobes stay finite.
    let one = [w(Vec3::new(0.0, 0.6, 0.8), 0.5), w(Vec3::X, -3.0)];
    for est in [KappaEstimate::Banerjee, KappaEstimate::MaximumLikelihood] {
        let l = estimate_one_lobe(&one, est, 1e4).unwrap();
        assert_eq!((l.kappa, l.amplitude), (1e4, Vec3::splat(0.5)));
        assert!(angle64(l.axis, one[0].dir) < 1e-6);
    }
    for k in 1..=3 {
        let f = fit_em(&one, k, &opts).unwrap();
        check(&f, Vec3::splat(0.5));
    }
    // Opposite samples of equal weight: one lobe is uniform (kappa 0, n = 0) and two lobes
    // are the two spikes.
    let pair = [w(Vec3::Z, 1.0), w(-Vec3::Z, 1.0)];
    let l = estimate_one_lobe(&pair, KappaEstimate::MaximumLikelihood, KAPPA_MAX).unwrap();
    assert_eq!((l.kappa, l.amplitude), (0.0, Vec3::splat(2.0)));
    let f = fit_em(&pair, 2, &opts).unwrap();
    check(&f, Vec3::splat(2.0));
    assert!(
        f.lobes
            .iter()
            .all(|l| l.kappa == KAPPA_MAX && l.amplitude.x == 1.0),
        "{f:?}"
    );
    assert!(f.lobes[0].axis.dot(f.lobes[1].axis) < -0.999);
    // More lobes than samples, and many copies of one direction.
    let few = [w(Vec3::X, 1.0), w(Vec3::Y, 2.0), w(Vec3::Z, 3.0)];
    check(&fit_em(&few, 5, &opts).unwrap(), Vec3::splat(6.0));
    let same = vec![w(Vec3::new(0.6, 0.0, 0.8), 0.1); 100];
    check(&fit_em(&same, 3, &opts).unwrap(), Vec3::splat(10.0));
}

#[test]
fn a_split_that_ends_lower_falls_back_to_the_previous_fit() {
    // Samples of one lobe: the one-lobe estimate is the likelihood's optimum among single
    // lobes, and a split left un-iterated (0 EM steps) starts below it, so the nested fit must
    // fall back: the previous lobe, a dead copy, the same likelihood.
    let truth = VmfLobe::new(Vec3::new(0.0, 0.6, 0.8), 20.0, Vec3::ONE);
    let s = samples_of(&[truth], 5000, 9);
    let opts = EmOptions {
        max_iterations: 0,
        split_trial_iterations: 0,
        ..EmOptions::default()
    };
    let fits = fit_em_nested(&s, 3, &opts);
    assert_eq!(fits.len(), 3);
    for k in 1..3 {
        assert_eq!(fits[k].log_likelihood, fits[0].log_likelihood);
        assert_eq!(fits[k].lobes[0], fits[0].lobes[0]);
        assert!(fits[k].lobes[1..].iter().all(|l| l.amplitude == Vec3::ZERO));
        assert_eq!(fits[k].iterations, 0);
    }
    // With iterations the split is kept and the likelihood rises (slightly: one lobe's data).
    let fits = fit_em_nested(&s, 2, &EmOptions::default());
    assert!(fits[1].log_likelihood >= fits[0].log_likelihood);
}
