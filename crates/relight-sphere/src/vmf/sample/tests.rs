//! The sampling triple: chi-square goodness of fit for concentrations from 0 to 1e4 (in
//! zoomed coordinates), the inverse, the pdf's integral, agreement with the SG sampler and
//! the paper's large-kappa form (eq. 12).

use super::super::tests::lobe_rule;
use super::*;
use crate::chi2::{chi2_sphere_test, ChiTest};
use crate::sg::sample_sg;
use crate::Rng;

/// An orthonormal frame about unit `mu` built independently of [`Frame`] (Gram-Schmidt from
/// X or Y), in f64.
fn gram_schmidt(mu: Vec3) -> [[f64; 3]; 3] {
    let m = [mu.x as f64, mu.y as f64, mu.z as f64];
    let a = if m[0].abs() < 0.8 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let d = a[0] * m[0] + a[1] * m[1] + a[2] * m[2];
    let mut e1 = [a[0] - d * m[0], a[1] - d * m[1], a[2] - d * m[2]];
    let n = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).sqrt();
    e1 = [e1[0] / n, e1[1] / n, e1[2] / n];
    let e2 = [
        m[1] * e1[2] - m[2] * e1[1],
        m[2] * e1[0] - m[0] * e1[2],
        m[0] * e1[1] - m[1] * e1[0],
    ];
    [e1, e2, m]
}

/// The chi-square test of the triple in coordinates zoomed about the axis. A lobe of
/// concentration `kappa` lives within `1 - mu . w ~ 1 / kappa`, far inside one of the helper's
/// 16 `z` bins, so the test maps a direction with `s = 1 - mu . w` and azimuth `phi` (in an
/// independent frame about `mu`) to `z' = 1 - m s` with the same azimuth, `m = max(1,
/// kappa / 8)`: a linear map of `z`, hence of constant Jacobian `m` on solid angle, so the
/// mapped density is `pdf(w) / m` at the preimage. The image covers `s <= 2 / m = 16 / kappa`
/// (all but `exp(-16)` of the mass; samples beyond are clamped to `z' = -1`, where the last bin
/// expects a fraction of them).
fn chi2_zoomed(axis: Vec3, kappa: f32, pdf_kappa: f32, seed: u64) -> crate::chi2::ChiResult {
    let m = (kappa as f64 / 8.0).max(1.0);
    let f = gram_schmidt(axis);
    let dot = |v: Vec3, e: [f64; 3]| v.x as f64 * e[0] + v.y as f64 * e[1] + v.z as f64 * e[2];
    let mut rng = Rng::new(seed, 3);
    chi2_sphere_test(
        // 16 x 16 sub-samples per bin: the density varies by a factor e per z bin.
        &ChiTest {
            sub: 16,
            ..ChiTest::default()
        },
        |_| {
            let w = sample_vmf(axis, kappa, rng.next_vec2());
            let (x, y, z) = (dot(w, f[0]), dot(w, f[1]), dot(w, f[2]));
            let s = if z > 0.0 {
                (x * x + y * y) / (1.0 + z)
            } else {
                1.0 - z
            };
            let zp = (1.0 - m * s).max(-1.0);
            let r = (1.0 - zp * zp).max(0.0).sqrt();
            let phi = y.atan2(x);
            Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, zp as f32)
        },
        |d| {
            let s = (1.0 - d.z as f64) / m;
            let r = (s * (2.0 - s)).max(0.0).sqrt();
            let phi = (d.y as f64).atan2(d.x as f64);
            let (c, sn) = (r * phi.cos(), r * phi.sin());
            let w = [0, 1, 2].map(|i| c * f[0][i] + sn * f[1][i] + (1.0 - s) * f[2][i]);
            let w = Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32);
            vmf_pdf(axis, pdf_kappa, w) as f64 / m
        },
    )
}

#[test]
fn sampling_triple_passes_chi2_for_every_kappa() {
    let axis = Vec3::new(0.36, -0.48, 0.8);
    for (i, kappa) in [0.0f32, 1e-4, 0.5, 3.0, 40.0, 1e4].into_iter().enumerate() {
        let res = chi2_zoomed(axis, kappa, kappa, 10 + i as u64);
        assert!(res.passed, "kappa {kappa}: {res:?}");
    }
    // The test can fail: samples of kappa 40 against the pdf of kappa 44 (10 % sharper), and
    // of kappa 1e4 against 1.05e4.
    assert!(!chi2_zoomed(axis, 40.0, 44.0, 1).passed);
    assert!(!chi2_zoomed(axis, 1e4, 1.05e4, 2).passed);
}

#[test]
fn pdf_integrates_to_one() {
    for kappa in [0.0f32, 1e-4, 1.0, 30.0, 1e4] {
        let axis = Vec3::new(0.0, 0.6, 0.8);
        let (d, w) = lobe_rule(axis, kappa as f64, 8);
        let i: f64 = d
            .iter()
            .zip(&w)
            .map(|(d, w)| vmf_pdf(axis, kappa, *d) as f64 * w)
            .sum();
        // f32 pdf values: relative 6e-8 each.
        assert!((i - 1.0).abs() < 1e-6, "kappa {kappa}: {i}");
    }
}

#[test]
fn inverse_inverts_sampling() {
    for kappa in [0.0f32, 1e-4, 1.0, 10.0, 1e4, 1e6] {
        let axis = Vec3::new(-0.6, 0.0, 0.8);
        let mut rng = Rng::new(4, 4);
        for _ in 0..4000 {
            let u = rng.next_vec2();
            let d = sample_vmf(axis, kappa, u);
            assert!((d.length() - 1.0).abs() < 1e-6);
            let back = invert_vmf_sample(axis, kappa, d);
            // The sample is an f32 direction, off by ~1.2e-7 radian (rounding of the frame
            // product and the normalisation). u.x = (1 - exp(-kappa s)) / (1 - exp(-2 kappa))
            // moves by at most kappa theta 1.2e-7 for theta = sqrt(2 s) <= sqrt(40 / kappa)
            // (all u.x < 1 - exp(-20)): sqrt(40 kappa) 1.2e-7, plus f32 rounding of u.
            let tol0 = 2e-6 + (40.0 * kappa as f64).sqrt() * 1.2e-7;
            assert!(
                ((back.x - u.x).abs() as f64) < tol0,
                "{kappa}: {u} -> {back}"
            );
            // The azimuth: an angle of 1.2e-7 / sin theta, i.e. a distance of 1.2e-7 on the
            // sphere; wrap-around at u.y = 0 ~ 1.
            let s = (1.0 - d.dot(axis) as f64).max(0.0);
            let sin_t = (s * (2.0 - s)).sqrt();
            let mut e = (back.y - u.y).abs();
            e = e.min(1.0 - e);
            assert!(
                (e as f64) * 2.0 * std::f64::consts::PI * sin_t < 3e-7 + 1e-6 * sin_t,
                "{kappa}: {u} -> {back}"
            );
        }
    }
}

#[test]
fn agrees_with_sg_sampler_and_large_kappa_form() {
    // Same warp as sample_sg for moderate kappa (a vMF is a normalised SG).
    let axis = Vec3::new(0.48, 0.6, 0.64);
    let mut rng = Rng::new(2, 9);
    for kappa in [0.3f32, 3.0, 30.0] {
        for _ in 0..500 {
            let u = rng.next_vec2();
            let (a, b) = (sample_vmf(axis, kappa, u), sample_sg(axis, kappa, u));
            assert!((a - b).length() < 2e-6, "{kappa}: {a} {b}");
        }
    }
    // kappa >> 1: 1 - cos theta = -ln(1 - u) / kappa (paper eq. 12); here with relative
    // accuracy, through the half squared chord to the axis (+Z: exact frame).
    for kappa in [1e4f32, 1e6, 1e8] {
        for ux in [1e-6f32, 0.1, 0.5, 0.9, 0.999] {
            let d = sample_vmf(Vec3::Z, kappa, Vec2::new(ux, 0.3));
            let s = super::super::one_minus_dot([0.0, 0.0, 1.0], super::super::unit64(d));
            let want = -(-(ux as f64)).ln_1p() / kappa as f64;
            // f32 direction: relative error of s about 2 * 6e-8 / theta^2 * theta... ~1e-6.
            assert!((s / want - 1.0).abs() < 1e-5, "{kappa} {ux}: {s} {want}");
        }
    }
}

#[test]
fn extreme_inputs_give_unit_directions() {
    for kappa in [0.0f32, 1e-30, 1e-12, 1e-11, crate::vmf::KAPPA_MAX, f32::MAX] {
        for u in [
            Vec2::ZERO,
            Vec2::new(1.0 - f32::EPSILON, 1.0 - f32::EPSILON),
            Vec2::new(0.5, 0.5),
        ] {
            let d = sample_vmf(Vec3::Y, kappa, u);
            assert!(
                d.is_finite() && (d.length() - 1.0).abs() < 1e-6,
                "{kappa} {u}: {d}"
            );
            let p = vmf_pdf(Vec3::Y, kappa, d);
            assert!(p.is_finite() || kappa == f32::MAX, "{kappa}: {p}");
            let b = invert_vmf_sample(Vec3::Y, kappa, d);
            assert!(b.is_finite() && b.min_element() >= 0.0 && b.max_element() < 1.0);
        }
    }
    // kappa = 0 is the uniform sphere: u.x = 1/2 is the equator.
    let d = sample_vmf(Vec3::Y, 0.0, Vec2::new(0.5, 0.0));
    assert!(d.dot(Vec3::Y).abs() < 1e-6);
}
