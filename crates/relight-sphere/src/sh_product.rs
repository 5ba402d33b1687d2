//! SH products via the triple-product (Gaunt) tensor
//! `Gamma_ijk = int Y_i(w) Y_j(w) Y_k(w) dw` (real SH of [`crate::sh`]).
//!
//! The product of two order-`n` functions, projected back to order `n`, is
//! `c_k = sum_ij Gamma_ijk a_i b_j` (Ng, Ramamoorthi & Hanrahan 2004, "Triple Product Wavelet
//! Integrals for All-Frequency Relighting", eq. 4; Sloan 2008, "Stupid SH tricks", section
//! "Products"). Fixing `a` gives the linear operator `M_kj = sum_i Gamma_ijk a_i` (e.g. a
//! visibility or transfer matrix, Sloan, Kautz & Snyder 2002).
//!
//! The tensor is computed exactly (to f64 rounding): writing `Y_lm(theta, phi) = A_lm(z) T_m(phi)`
//! with `T_m = cos(m phi)`, `sin(|m| phi)` or 1, the integral separates into an azimuthal part
//! (uniform rule with `3n` points, exact for trigonometric polynomials of that degree) and a
//! polar part (Gauss-Legendre in `z`, exact since the product of the three `A` is a polynomial
//! of degree `<= 3(n-1)` whenever the azimuthal part is non-zero). Only the entries allowed by the
//! selection rules (`|l_i - l_j| <= l_k <= l_i + l_j`, `l_i + l_j + l_k` even,
//! `|m_k| = |m_i| ± |m_j|`) are evaluated and stored, for `i <= j`.

use crate::quadrature::gauss_legendre;
use crate::sh::{order_of, sh_count, sh_index, MAX_ORDER};
use crate::Vec3;
use std::f64::consts::PI;

/// The sparse triple-product tensor of one order.
#[derive(Clone, Debug)]
pub struct ShProduct {
    order: usize,
    /// `(i, j, k, Gamma_ijk)` with `i <= j`, sorted by `k`.
    entries: Vec<(u16, u16, u16, f32)>,
}

impl ShProduct {
    /// Tensor for order `order` (`<= MAX_ORDER`). Cost grows like `order^5`; order 8 takes
    /// milliseconds, order 16 well under a second.
    ///
    /// # Panics
    /// Panics if `order > MAX_ORDER`.
    pub fn new(order: usize) -> Self {
        assert!(order <= MAX_ORDER, "order {order} exceeds MAX_ORDER");
        let n = order;
        let count = sh_count(n);
        // Polar factors A_lm(z) at Gauss-Legendre nodes: Y_{l,|m|} at phi = 0.
        let (zs, wz) = gauss_legendre((3 * n) / 2 + 1);
        let mut a = vec![vec![0f64; count]; zs.len()];
        let mut y = vec![0f64; count];
        for (q, &z) in zs.iter().enumerate() {
            polar_factors(n, z, &mut y);
            for l in 0..n as i32 {
                for m in -l..=l {
                    a[q][sh_index(l, m)] = y[sh_index(l, m.abs())];
                }
            }
        }
        // Azimuthal factors T_m(phi) at a uniform rule exact for degree 3(n - 1).
        let nphi = 3 * n.max(1);
        // tab[(m + n) * nphi + q] = T_m(phi_q), |m| < n.
        let mut tab = vec![0f64; (2 * n + 1) * nphi];
        for m in -(n as i32)..=(n as i32) {
            for q in 0..nphi {
                let phi = 2.0 * PI * (q as f64 + 0.5) / nphi as f64;
                tab[(m + n as i32) as usize * nphi + q] = match m.cmp(&0) {
                    std::cmp::Ordering::Greater => (m as f64 * phi).cos(),
                    std::cmp::Ordering::Less => (-m as f64 * phi).sin(),
                    std::cmp::Ordering::Equal => 1.0,
                };
            }
        }
        let row = |m: i32| &tab[(m + n as i32) as usize * nphi..(m + n as i32 + 1) as usize * nphi];
        let phi_integral = |m1: i32, m2: i32, m3: i32| -> f64 {
            let (r1, r2, r3) = (row(m1), row(m2), row(m3));
            (0..nphi).map(|q| r1[q] * r2[q] * r3[q]).sum::<f64>() * 2.0 * PI / nphi as f64
        };
        let lm = |i: usize| -> (i32, i32) {
            let l = (i as f64).sqrt() as i32;
            (l, i as i32 - l * l - l)
        };
        let mut entries = Vec::new();
        for i in 0..count {
            let (l1, m1) = lm(i);
            for j in i..count {
                let (l2, m2) = lm(j);
                let mut cands = [m1.abs() + m2.abs(), (m1.abs() - m2.abs()).abs()];
                if cands[0] == cands[1] {
                    cands[1] = -1;
                }
                for l3 in (l1 - l2).abs()..=(l1 + l2).min(n as i32 - 1) {
                    if (l1 + l2 + l3) % 2 != 0 {
                        continue;
                    }
                    for &am3 in cands.iter().filter(|&&c| c >= 0 && c <= l3) {
                        for m3 in if am3 == 0 { vec![0] } else { vec![am3, -am3] } {
                            let p = phi_integral(m1, m2, m3);
                            if p.abs() < 1e-12 {
                                continue;
                            }
                            let k = sh_index(l3, m3);
                            let zpart: f64 = zs
                                .iter()
                                .enumerate()
                                .map(|(q, _)| wz[q] * a[q][i] * a[q][j] * a[q][k])
                                .sum();
                            let g = p * zpart;
                            if g.abs() > 1e-12 {
                                entries.push((i as u16, j as u16, k as u16, g as f32));
                            }
                        }
                    }
                }
            }
        }
        entries.sort_by_key(|e| (e.2, e.0, e.1));
        ShProduct { order, entries }
    }

    /// The order.
    #[inline]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Stored non-zero entries `(i, j, k, Gamma_ijk)` with `i <= j`.
    #[inline]
    pub fn entries(&self) -> &[(u16, u16, u16, f32)] {
        &self.entries
    }

    /// Projected product of two scalar SH vectors of this order.
    ///
    /// # Panics
    /// Debug builds assert both lengths equal `order^2`.
    pub fn product(&self, a: &[f32], b: &[f32]) -> Vec<f32> {
        debug_assert!(a.len() == sh_count(self.order) && b.len() == a.len());
        let mut c = vec![0f32; a.len()];
        for &(i, j, k, g) in &self.entries {
            let (i, j) = (i as usize, j as usize);
            let ab = if i == j {
                a[i] * b[i]
            } else {
                a[i] * b[j] + a[j] * b[i]
            };
            c[k as usize] += g * ab;
        }
        c
    }

    /// Projected product of a scalar SH vector `a` (e.g. visibility) and RGB coefficients `b`.
    ///
    /// # Panics
    /// Debug builds assert both lengths equal `order^2`.
    pub fn product_rgb(&self, a: &[f32], b: &[Vec3]) -> Vec<Vec3> {
        debug_assert!(a.len() == sh_count(self.order) && b.len() == a.len());
        let mut c = vec![Vec3::ZERO; a.len()];
        for &(i, j, k, g) in &self.entries {
            let (i, j) = (i as usize, j as usize);
            let ab = if i == j {
                b[i] * a[i]
            } else {
                b[j] * a[i] + b[i] * a[j]
            };
            c[k as usize] += ab * g;
        }
        c
    }

    /// The matrix `M` (row-major, `order^2 x order^2`) with `M b = product(a, b)`:
    /// `M_kj = sum_i Gamma_ijk a_i`.
    pub fn product_matrix(&self, a: &[f32]) -> Vec<f32> {
        let n = order_of(a.len());
        debug_assert_eq!(n, self.order);
        let count = a.len();
        let mut m = vec![0f32; count * count];
        for &(i, j, k, g) in &self.entries {
            let (i, j, k) = (i as usize, j as usize, k as usize);
            m[k * count + j] += g * a[i];
            if i != j {
                m[k * count + i] += g * a[j];
            }
        }
        m
    }
}

/// `Y_{l,m}` for `m >= 0` at azimuth 0 and `cos theta = z`, in f64 (the definition of
/// [`crate::sh::eval_sh_slow`], taking an exact f64 `z`), written to `out[sh_index(l, m)]`.
fn polar_factors(order: usize, z: f64, out: &mut [f64]) {
    let s = (1.0 - z * z).max(0.0).sqrt();
    crate::sh::legendre_factors(order, z, s, |l, m, v| out[sh_index(l, m)] = v);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::sphere_rule_f32;
    use crate::sh::{eval_scalar, eval_sh};
    use crate::warp::Rng;

    fn random(order: usize, rng: &mut Rng) -> Vec<f32> {
        (0..sh_count(order)).map(|_| rng.next_f32() - 0.5).collect()
    }

    #[test]
    fn product_matches_exact_projection() {
        let mut rng = Rng::new(12, 0);
        for order in [1, 2, 3, 5, 8] {
            let p = ShProduct::new(order);
            let (a, b) = (random(order, &mut rng), random(order, &mut rng));
            let c = p.product(&a, &b);
            // Project the pointwise product with a rule exact for degree 3 (order - 1).
            let (dirs, w) = sphere_rule_f32(3 * order);
            let mut expect = vec![0f64; sh_count(order)];
            let mut y = vec![0f32; sh_count(order)];
            for (d, w) in dirs.iter().zip(&w) {
                let f = (eval_scalar(&a, *d) * eval_scalar(&b, *d)) as f64;
                eval_sh(order, *d, &mut y);
                for (e, yk) in expect.iter_mut().zip(&y) {
                    *e += f * *yk as f64 * w;
                }
            }
            for (k, (x, e)) in c.iter().zip(&expect).enumerate() {
                assert!(
                    (*x as f64 - e).abs() < 1e-5,
                    "order {order} k {k}: {x} vs {e}"
                );
            }
            // Matrix form and RGB form agree.
            let m = p.product_matrix(&a);
            let n = sh_count(order);
            for k in 0..n {
                let mb: f32 = (0..n).map(|j| m[k * n + j] * b[j]).sum();
                assert!((mb - c[k]).abs() < 1e-5);
            }
            let brgb: Vec<Vec3> = b.iter().map(|&v| Vec3::new(v, 2.0 * v, -v)).collect();
            let crgb = p.product_rgb(&a, &brgb);
            assert!(crgb
                .iter()
                .zip(&c)
                .all(|(v, s)| (v.y - 2.0 * s).abs() < 1e-5 && (v.z + s).abs() < 1e-5));
        }
    }

    #[test]
    fn constant_is_identity() {
        // The constant function 1 has a_0 = sqrt(4 pi) and multiplies as the identity.
        let order = 6;
        let p = ShProduct::new(order);
        let mut one = vec![0f32; sh_count(order)];
        one[0] = (4.0 * std::f32::consts::PI).sqrt();
        let b = random(order, &mut Rng::new(1, 0));
        let c = p.product(&one, &b);
        assert!(c.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-5));
    }

    #[test]
    fn order16_is_fast_enough() {
        let t = std::time::Instant::now();
        let p = ShProduct::new(16);
        assert!(!p.entries().is_empty());
        // Loose bound for a shared 2-core machine.
        assert!(t.elapsed().as_secs_f32() < 10.0);
    }
}
