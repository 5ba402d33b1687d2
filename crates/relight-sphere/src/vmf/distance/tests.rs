//! The exact L2 distance against quadrature over a grid of concentrations and angles; the
//! large-kappa approximation's error, where it is small and where it is not.

use super::super::tests::{degree_for, density_ref};
use super::*;
use crate::quadrature::sphere_rule;

/// A lobe about the axis at polar angle `theta` from +Z in the xz-plane.
fn lobe_at(theta: f64, kappa: f64, amp: Vec3) -> VmfLobe {
    VmfLobe::new(
        Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32),
        kappa as f32,
        amp,
    )
}

const KAPPAS: [f64; 6] = [0.0, 0.01, 1.0, 10.0, 100.0, 3000.0];
const ANGLES: [f64; 5] = [0.0, 0.05, 0.5, 2.0, PI];

#[test]
fn exact_distance_matches_quadrature() {
    let (a0, a1) = (Vec3::new(1.0, 0.5, 2.0), Vec3::new(0.7, 0.7, 0.1));
    for (i, &k0) in KAPPAS.iter().enumerate() {
        for &k1 in &KAPPAS[i..] {
            // Polynomial-exact rule resolving both lobes (their squares have 2 kappa).
            let (d, w) = sphere_rule(degree_for(2.0 * k0.max(k1)));
            for &t in &ANGLES {
                let (l0, l1) = (lobe_at(0.0, k0, a0), lobe_at(t, k1, a1));
                let (m0, m1) = (unit64(l0.axis), unit64(l1.axis));
                let (mut q, mut scale) = ([0.0f64; 3], [0.0f64; 3]);
                for (d, w) in d.iter().zip(&w) {
                    let (f0, f1) = (
                        density_ref(l0.kappa as f64, m0, *d),
                        density_ref(l1.kappa as f64, m1, *d),
                    );
                    for c in 0..3 {
                        let diff = a0[c] as f64 * f0 - a1[c] as f64 * f1;
                        q[c] += diff * diff * w;
                        scale[c] += ((a0[c] as f64 * f0).powi(2) + (a1[c] as f64 * f1).powi(2)) * w;
                    }
                }
                let got = l2_distance_squared(&l0, &l1);
                for c in 0..3 {
                    // Relative to |a0 f0|^2 + |a1 f1|^2 (the quadrature's own rounding scale):
                    // f64 quadrature of a resolved integrand, ~1e-13; f32 result: 1e-7.
                    assert!(
                        (got[c] as f64 - q[c]).abs() < 2e-7 * scale[c],
                        "k0 {k0} k1 {k1} angle {t} ch {c}: {} vs {}",
                        got[c],
                        q[c]
                    );
                }
            }
        }
    }
}

#[test]
fn exact_distance_has_no_cancellation() {
    for k in [0.0, 1e-3, 1.0, 50.0, 1e4, 1e6, 1e8] {
        // Equal lobes: 0 to rounding; equal shapes: (a0 - a1)^2 S exactly.
        let l = lobe_at(0.3, k, Vec3::ONE);
        let s = self_inner_product(k);
        assert!(
            (l2_distance_squared(&l, &l).max_element() as f64) < 1e-14 * s,
            "{k}"
        );
        let m = VmfLobe {
            amplitude: Vec3::splat(0.75),
            ..l
        };
        let want = 0.0625 * s;
        assert!(
            (l2_distance_squared(&l, &m).x as f64 / want - 1.0).abs() < 1e-6,
            "{k}"
        );
        // S(kappa) = kappa coth(kappa) / (4 pi).
        if k > 0.0 {
            let direct = k / k.tanh() / (4.0 * PI);
            assert!((s / direct - 1.0).abs() < 1e-13, "{k}");
        }
    }
    // Nearly equal sharp lobes: |f0 - f1|^2 / delta^2 tends to a constant as the angle delta
    // between them goes to 0 (the naive a0^2 S0 + a1^2 S1 - 2 a0 a1 X loses all digits here:
    // at kappa = 1e4, delta = 1e-6 the distance is 2.5e-9 S). Second order: for equal kappa,
    // |f0 - f1|^2 ~ 2 S L with L ~ kappa delta^2 / 4, i.e. ~ kappa^2 delta^2 / (8 pi).
    for k in [1e2f64, 1e4] {
        let mut ratios = vec![];
        for delta in [1e-4f64, 1e-5, 1e-6] {
            // Exact f32 axes: rotate about Z from X.
            let l0 = VmfLobe::new(Vec3::X, k as f32, Vec3::ONE);
            let a1 = Vec3::new(delta.cos() as f32, delta.sin() as f32, 0.0);
            let l1 = VmfLobe::new(a1, k as f32, Vec3::ONE);
            // The f32 axes' actual angle.
            let real = (l0.axis.cross(l1.axis).length() as f64).asin();
            ratios.push(l2_distance_squared(&l0, &l1).x as f64 / (real * real));
        }
        let want = k * k / (8.0 * PI) * (1.0 / k.tanh()) * (1.0 - 0.5 / k);
        for r in &ratios {
            assert!(
                (r / want - 1.0).abs() < 2e-3,
                "kappa {k}: {ratios:?} vs {want}"
            );
        }
    }
}

#[test]
fn large_kappa_approximation_error_table() {
    // Relative error of the paper's eq. 7 against the exact distance, normalised by
    // a0^2 S0 + a1^2 S1 (the approximation's error is on that scale, and the distance itself
    // goes to zero for equal lobes).
    let angles = [0.0, 0.1, 0.5, 1.5, 3.0, PI];
    println!("kappa  | relative error of eq. 7 for angles {angles:?}");
    let mut table = vec![];
    for k in [0.5, 1.0, 3.0, 10.0, 30.0, 100.0, 1e4] {
        let row: Vec<f64> = angles
            .iter()
            .map(|&t| {
                let (l0, l1) = (
                    lobe_at(0.0, k, Vec3::ONE),
                    lobe_at(t, 0.8 * k, Vec3::splat(0.6)),
                );
                let exact = l2_distance_squared(&l0, &l1).x as f64;
                let approx = l2_distance_squared_large_kappa(&l0, &l1).x as f64;
                let scale = self_inner_product(k) + 0.36 * self_inner_product(0.8 * k);
                (approx - exact).abs() / scale
            })
            .collect();
        println!(
            "{k:6} | {}",
            row.iter()
                .map(|e| format!("{e:9.2e}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        table.push((k, row));
    }
    for (k, row) in &table {
        let worst = row.iter().cloned().fold(0.0, f64::max);
        // The dropped factors are 1 - exp(-2 k) for k in kappa0, kappa1 and kappa_c >= 0.2
        // kappa here: about 4 exp(-0.4 kappa) in all.
        if *k >= 30.0 {
            assert!(worst < 4.0 * (-0.4 * k).exp() + 1e-6, "{k}: {worst}");
        }
        // Small kappa: eq. 7 is far off (it assumes c(kappa) ~ kappa e^-kappa / 2 pi).
        if *k <= 1.0 {
            assert!(worst > 0.1, "{k}: {worst}");
        }
    }
    // Exactly opposite lobes of equal kappa (kappa_c = 0): the cross term of eq. 7 is infinite
    // even for sharp lobes, while the exact distance is a0^2 S0 + a1^2 S1 (no overlap).
    let l0 = VmfLobe::new(Vec3::Z, 50.0, Vec3::ONE);
    let l1 = VmfLobe::new(-Vec3::Z, 50.0, Vec3::ONE);
    assert!(l2_distance_squared_large_kappa(&l0, &l1).x.is_infinite());
    let exact = l2_distance_squared(&l0, &l1).x as f64;
    assert!((exact / (2.0 * self_inner_product(50.0)) - 1.0).abs() < 1e-6);
    // Zero amplitude: no NaN from 0 * inf.
    let z = VmfLobe {
        amplitude: Vec3::ZERO,
        ..l1
    };
    assert!(l2_distance_squared_large_kappa(&l0, &z).is_finite());
}

#[test]
fn mixture_distance_matches_pairwise_form() {
    let a = [
        lobe_at(0.2, 20.0, Vec3::ONE),
        lobe_at(1.0, 5.0, Vec3::splat(0.5)),
    ];
    let b = [lobe_at(0.25, 18.0, Vec3::ONE)];
    let (d, w) = sphere_rule(degree_for(40.0));
    let q: f64 = d
        .iter()
        .zip(&w)
        .map(|(d, w)| {
            let f = |l: &VmfLobe| {
                l.amplitude.x as f64 * density_ref(l.kappa as f64, unit64(l.axis), *d)
            };
            let diff = f(&a[0]) + f(&a[1]) - f(&b[0]);
            diff * diff * w
        })
        .sum();
    let got = mixture_l2_distance_squared(&a, &b).x as f64;
    assert!((got / q - 1.0).abs() < 1e-5, "{got} {q}");
    // One lobe each: the pairwise form agrees with the cancellation-free one.
    let one = mixture_l2_distance_squared(&a[..1], &b).x;
    assert!((one / l2_distance_squared(&a[0], &b[0]).x - 1.0).abs() < 1e-4);
}
