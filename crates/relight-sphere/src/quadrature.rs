//! Quadrature rules: Gauss-Legendre on `[-1, 1]` and a product rule on the sphere (f64).

use crate::Vec3;
use std::f64::consts::PI;

/// Nodes and weights of the `n`-point Gauss-Legendre rule on `[-1, 1]` (exact for polynomials
/// of degree `2n - 1`). Nodes by Newton iteration on `P_n` from the Tricomi initial guesses
/// (Abramowitz & Stegun 25.4.29); weights `2 / ((1 - x^2) P_n'(x)^2)`.
///
/// # Panics
/// Debug builds assert `n >= 1`.
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    debug_assert!(n >= 1);
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_n'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let pn = if n == 1 { x } else { p1 };
            let pn1 = if n == 1 { 1.0 } else { p0 };
            dp = n as f64 * (x * pn - pn1) / (x * x - 1.0);
            let dx = pn / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        if n == 1 {
            x = 0.0;
            dp = 1.0;
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = x;
        nodes[n - 1 - i] = -x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    (nodes, weights)
}

/// Product rule on the unit sphere exact for polynomials in `(x, y, z)` of total degree
/// `<= degree`: Gauss-Legendre in `z` (`degree / 2 + 1` nodes) times `degree + 1` uniform
/// azimuths `phi = atan2(y, x)`. Returns directions (unit, as f64 triples) and weights summing
/// to `4 pi`.
pub fn sphere_rule(degree: usize) -> (Vec<[f64; 3]>, Vec<f64>) {
    let (zs, wz) = gauss_legendre(degree / 2 + 1);
    let nphi = degree + 1;
    let mut dirs = Vec::with_capacity(zs.len() * nphi);
    let mut weights = Vec::with_capacity(zs.len() * nphi);
    for (z, w) in zs.iter().zip(&wz) {
        let r = (1.0 - z * z).max(0.0).sqrt();
        for k in 0..nphi {
            let phi = 2.0 * PI * (k as f64 + 0.5) / nphi as f64;
            dirs.push([r * phi.cos(), r * phi.sin(), *z]);
            weights.push(w * 2.0 * PI / nphi as f64);
        }
    }
    (dirs, weights)
}

/// [`sphere_rule`] with f32 directions.
pub fn sphere_rule_f32(degree: usize) -> (Vec<Vec3>, Vec<f64>) {
    let (d, w) = sphere_rule(degree);
    (
        d.iter()
            .map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
            .collect(),
        w,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrates_polynomials_exactly() {
        for n in [1, 2, 3, 8, 16, 33] {
            let (x, w) = gauss_legendre(n);
            assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-13, "n={n}");
            for deg in 0..2 * n {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(deg as i32)).sum();
                let exact = if deg % 2 == 1 {
                    0.0
                } else {
                    2.0 / (deg as f64 + 1.0)
                };
                assert!((q - exact).abs() < 1e-12, "n={n} deg={deg}: {q}");
            }
        }
    }

    #[test]
    fn sphere_rule_is_exact() {
        // int x^2 y^2 z^2 dw = 4 pi / 105; int z^4 = 4 pi / 5; int x^3 = 0.
        let (d, w) = sphere_rule(6);
        let q = |f: &dyn Fn(&[f64; 3]) -> f64| d.iter().zip(&w).map(|(p, w)| f(p) * w).sum::<f64>();
        let fp = 4.0 * PI;
        assert!((q(&|_| 1.0) - fp).abs() < 1e-12);
        assert!((q(&|p| (p[0] * p[1] * p[2]).powi(2)) - fp / 105.0).abs() < 1e-12);
        assert!((q(&|p| p[2].powi(4)) - fp / 5.0).abs() < 1e-12);
        assert!(q(&|p| p[0].powi(3)).abs() < 1e-12);
        // Degree 8 is beyond the rule: z^8 is not integrated exactly.
        assert!((q(&|p| p[2].powi(8)) - fp / 9.0).abs() > 1e-6);
    }
}
