//! Rotation of real SH coefficient vectors, any rotation, any order up to [`MAX_ORDER`].
//!
//! Method: the recurrence of Ivanic & Ruedenberg, "Rotation Matrices for Real Spherical
//! Harmonics. Direct Determination by Recursion", J. Phys. Chem. 100 (1996) 6342, with the
//! corrections of J. Phys. Chem. A 102 (1998) 9099 (Table 2 coefficients `u, v, w` and
//! functions `U, V, W, P`). Band `l` is built from band 1 and band `l - 1` in `O(l^2)`, all in
//! f64. The real SH basis is the crate's (`sh` module: no Condon-Shortley phase, index
//! `l(l+1)+m`); in it band 1 is `(Y_1^-1, Y_1^0, Y_1^1) ∝ (y, z, x)`, so the band-1 matrix is
//! the rotation matrix with rows and columns permuted to `(y, z, x)`.
//!
//! **Semantics**: [`ShRotation::new`]`(order, R)` maps the coefficients of `f` to those of
//! `g(d) = f(R^T d)`, i.e. `f` rotated by `R` (a lobe of `f` at `a` moves to `R a`). Each band
//! matrix `M_l` satisfies `Y_l(R d) = M_l Y_l(d)`.

use super::{order_of, sh_count, MAX_ORDER};
use crate::{Mat3, Vec3};

/// Block-diagonal SH rotation matrix (one `(2l+1) x (2l+1)` block per band).
#[derive(Clone, Debug, PartialEq)]
pub struct ShRotation {
    order: usize,
    /// Band `l` block, row-major, entry `(m, n)` at `(m + l) (2l + 1) + (n + l)`.
    bands: Vec<Vec<f64>>,
}

impl ShRotation {
    /// The rotation of SH coefficients of `order` induced by the 3D rotation `rot`
    /// (`g(d) = f(rot^T d)`).
    ///
    /// # Panics
    /// Debug builds assert `order <= MAX_ORDER` and that `rot` is orthonormal with
    /// determinant +1.
    pub fn new(order: usize, rot: Mat3) -> Self {
        debug_assert!(order <= MAX_ORDER);
        debug_assert!(
            (rot * rot.transpose() - Mat3::IDENTITY)
                .to_cols_array()
                .iter()
                .all(|e| e.abs() < 1e-4)
                && (rot.determinant() - 1.0).abs() < 1e-4,
            "not a rotation"
        );
        let mut bands = Vec::with_capacity(order);
        if order >= 1 {
            bands.push(vec![1.0]);
        }
        if order >= 2 {
            // Permute to the (y, z, x) order of band 1: axis index of m = -1, 0, 1.
            const AXIS: [usize; 3] = [1, 2, 0];
            let mut m1 = vec![0.0; 9];
            for i in 0..3 {
                for j in 0..3 {
                    m1[i * 3 + j] = rot.col(AXIS[j])[AXIS[i]] as f64;
                }
            }
            bands.push(m1);
        }
        for l in 2..order {
            let next = band_from_previous(l as i32, &bands[1], &bands[l - 1]);
            bands.push(next);
        }
        ShRotation { order, bands }
    }

    /// The order this rotation acts on.
    #[inline]
    pub fn order(&self) -> usize {
        self.order
    }

    /// The `(2l+1)^2` block of band `l`, row-major, entry `(m, n)` at `(m+l)(2l+1) + (n+l)`.
    #[inline]
    pub fn band_matrix(&self, l: usize) -> &[f64] {
        &self.bands[l]
    }

    /// Rotates RGB coefficients (`coeffs.len()` must be `order'^2` with `order' <= order`).
    ///
    /// # Panics
    /// Debug builds assert the length condition.
    pub fn apply(&self, coeffs: &[Vec3]) -> Vec<Vec3> {
        let n = order_of(coeffs.len());
        debug_assert!(n <= self.order);
        let mut out = vec![Vec3::ZERO; coeffs.len()];
        for l in 0..n {
            let (dim, off) = (2 * l + 1, l * l);
            let m = &self.bands[l];
            for i in 0..dim {
                let mut acc = [0f64; 3];
                for j in 0..dim {
                    let (e, c) = (m[i * dim + j], coeffs[off + j]);
                    acc[0] += e * c.x as f64;
                    acc[1] += e * c.y as f64;
                    acc[2] += e * c.z as f64;
                }
                out[off + i] = Vec3::new(acc[0] as f32, acc[1] as f32, acc[2] as f32);
            }
        }
        out
    }

    /// Rotates scalar coefficients (`coeffs.len()` must be `order'^2` with `order' <= order`).
    ///
    /// # Panics
    /// Debug builds assert the length condition.
    pub fn apply_f32(&self, coeffs: &[f32]) -> Vec<f32> {
        let n = order_of(coeffs.len());
        debug_assert!(n <= self.order);
        let mut out = vec![0f32; coeffs.len()];
        for l in 0..n {
            let (dim, off) = (2 * l + 1, l * l);
            let m = &self.bands[l];
            for i in 0..dim {
                let acc: f64 = (0..dim)
                    .map(|j| m[i * dim + j] * coeffs[off + j] as f64)
                    .sum();
                out[off + i] = acc as f32;
            }
        }
        out
    }

    /// Number of coefficients this rotation acts on.
    #[inline]
    pub fn coeff_count(&self) -> usize {
        sh_count(self.order)
    }
}

/// Ivanic & Ruedenberg's recurrence: band `l` from band 1 (`r1`) and band `l - 1` (`prev`).
fn band_from_previous(l: i32, r1: &[f64], prev: &[f64]) -> Vec<f64> {
    let dim = (2 * l + 1) as usize;
    let pdim = (2 * l - 1) as usize;
    let r = |i: i32, j: i32| r1[((i + 1) * 3 + (j + 1)) as usize];
    let mp = |a: i32, b: i32| prev[((a + l - 1) as usize) * pdim + (b + l - 1) as usize];
    // Function P of the paper (1998 corrected form).
    let p = |i: i32, a: i32, b: i32| -> f64 {
        if b == l {
            r(i, 1) * mp(a, l - 1) - r(i, -1) * mp(a, -l + 1)
        } else if b == -l {
            r(i, 1) * mp(a, -l + 1) + r(i, -1) * mp(a, l - 1)
        } else {
            r(i, 0) * mp(a, b)
        }
    };
    let mut out = vec![0.0; dim * dim];
    for m in -l..=l {
        for n in -l..=l {
            let d = if m == 0 { 1.0 } else { 0.0 };
            let am = m.abs();
            let denom = if n.abs() == l {
                (2 * l * (2 * l - 1)) as f64
            } else {
                ((l + n) * (l - n)) as f64
            };
            let u = (((l + m) * (l - m)) as f64 / denom).sqrt();
            let v = 0.5
                * ((1.0 + d) * ((l + am - 1) * (l + am)) as f64 / denom).sqrt()
                * (1.0 - 2.0 * d);
            let w = -0.5 * (((l - am - 1) * (l - am)) as f64 / denom).sqrt() * (1.0 - d);
            let mut e = 0.0;
            if u != 0.0 {
                e += u * p(0, m, n);
            }
            if v != 0.0 {
                let vv = if m == 0 {
                    p(1, 1, n) + p(-1, -1, n)
                } else if m > 0 {
                    let k: f64 = if m == 1 { 1.0 } else { 0.0 };
                    p(1, m - 1, n) * (1.0 + k).sqrt() - p(-1, -m + 1, n) * (1.0 - k)
                } else {
                    let k: f64 = if m == -1 { 1.0 } else { 0.0 };
                    p(1, m + 1, n) * (1.0 - k) + p(-1, -m - 1, n) * (1.0 + k).sqrt()
                };
                e += v * vv;
            }
            if w != 0.0 {
                let ww = if m > 0 {
                    p(1, m + 1, n) + p(-1, -m - 1, n)
                } else {
                    p(1, m - 1, n) - p(-1, -m + 1, n)
                };
                e += w * ww;
            }
            out[((m + l) as usize) * dim + (n + l) as usize] = e;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::EnvMap;
    use crate::sh::{eval_rgb, eval_sh, project_fn};
    use crate::warp::{square_to_uniform_sphere, Rng};
    use crate::Quat;

    fn random_rotation(rng: &mut Rng) -> Mat3 {
        let axis = square_to_uniform_sphere(rng.next_vec2());
        Mat3::from_quat(Quat::from_axis_angle(
            axis,
            std::f32::consts::TAU * rng.next_f32(),
        ))
    }

    fn random_coeffs(order: usize, rng: &mut Rng) -> Vec<Vec3> {
        (0..sh_count(order))
            .map(|_| {
                Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                )
            })
            .collect()
    }

    #[test]
    fn pointwise_rotation_all_orders() {
        // apply(c) evaluated at d equals c evaluated at R^T d, exactly (no quadrature).
        let mut rng = Rng::new(10, 1);
        for order in 1..=MAX_ORDER {
            let rot = random_rotation(&mut rng);
            let c = random_coeffs(order, &mut rng);
            let rc = ShRotation::new(order, rot).apply(&c);
            for _ in 0..10 {
                let d = square_to_uniform_sphere(rng.next_vec2());
                let (a, b) = (eval_rgb(&rc, d), eval_rgb(&c, rot.transpose() * d));
                // Sum of up to 1024 terms of size ~0.5 x 2 in f32.
                assert!(
                    (a - b).abs().max_element() < 2e-5 * order as f32,
                    "order {order}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn band_matrices_orthogonal_composition_inverse() {
        let mut rng = Rng::new(3, 3);
        let order = 16;
        let (r1, r2) = (random_rotation(&mut rng), random_rotation(&mut rng));
        let (a, b) = (ShRotation::new(order, r1), ShRotation::new(order, r2));
        let ab = ShRotation::new(order, r1 * r2);
        let inv = ShRotation::new(order, r1.transpose());
        for l in 0..order {
            let dim = 2 * l + 1;
            let (ma, mb, mab, mi) = (
                a.band_matrix(l),
                b.band_matrix(l),
                ab.band_matrix(l),
                inv.band_matrix(l),
            );
            for i in 0..dim {
                for j in 0..dim {
                    let mut mmt = 0.0;
                    let mut prod = 0.0;
                    for k in 0..dim {
                        mmt += ma[i * dim + k] * ma[j * dim + k];
                        prod += ma[i * dim + k] * mb[k * dim + j];
                    }
                    let id = if i == j { 1.0 } else { 0.0 };
                    // Inputs are f32 rotations (~1e-7); errors grow mildly with l.
                    assert!((mmt - id).abs() < 1e-5, "orthogonal l={l}");
                    assert!((prod - mab[i * dim + j]).abs() < 1e-4, "composition l={l}");
                    assert!(
                        (mi[i * dim + j] - ma[j * dim + i]).abs() < 1e-4,
                        "inverse l={l}"
                    );
                }
            }
        }
        // Identity maps to identity; apply then apply inverse is the identity.
        let id = ShRotation::new(order, Mat3::IDENTITY);
        let c = random_coeffs(order, &mut rng);
        assert!(id
            .apply(&c)
            .iter()
            .zip(&c)
            .all(|(x, y)| (*x - *y).abs().max_element() < 1e-6));
        let back = inv.apply(&a.apply(&c));
        assert!(back
            .iter()
            .zip(&c)
            .all(|(x, y)| (*x - *y).abs().max_element() < 1e-4));
        let s: Vec<f32> = c.iter().map(|v| v.x).collect();
        let rs = a.apply_f32(&s);
        assert!(rs
            .iter()
            .zip(a.apply(&c))
            .all(|(x, y)| (x - y.x).abs() < 1e-6));
    }

    #[test]
    fn known_rotation_of_band1() {
        // A lobe along +X rotated by +90 degrees about +Y goes to -Z (right-handed).
        let rot = Mat3::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let mut y = [0f32; 4];
        eval_sh(2, Vec3::X, &mut y);
        let c: Vec<Vec3> = y.iter().map(|&v| Vec3::splat(v)).collect();
        let rc = ShRotation::new(2, rot).apply(&c);
        let mut expect = [0f32; 4];
        eval_sh(2, -Vec3::Z, &mut expect);
        for i in 0..4 {
            assert!((rc[i].x - expect[i]).abs() < 1e-6);
        }
    }

    #[test]
    fn rotate_then_project_equals_project_then_rotate() {
        let mut rng = Rng::new(77, 2);
        for order in [3, 8, 16] {
            let rot = random_rotation(&mut rng);
            let c = random_coeffs(order, &mut rng);
            // Analytic rotation evaluated on a dense map, then projected.
            let grid = EnvMap::latlong(1024, 513, vec![Vec3::ZERO; 1024 * 513]);
            let projected_rotated = project_fn(&grid, order, |d| eval_rgb(&c, rot.transpose() * d));
            let f_proj = project_fn(&grid, order, |d| eval_rgb(&c, d));
            let rotated_projected = ShRotation::new(order, rot).apply(&f_proj);
            for (i, (a, b)) in projected_rotated.iter().zip(&rotated_projected).enumerate() {
                // Both sides carry the latlong quadrature error ~(l h)^2 / 12 with h = pi/512.
                assert!(
                    (*a - *b).abs().max_element() < 2e-3,
                    "order {order} i {i}: {a} vs {b}"
                );
                // And both equal the analytic rotation of c.
            }
            let exact = ShRotation::new(order, rot).apply(&c);
            for (a, b) in projected_rotated.iter().zip(&exact) {
                assert!(
                    (*a - *b).abs().max_element() < 2e-3,
                    "order {order}: {a} vs {b}"
                );
            }
        }
    }
}
