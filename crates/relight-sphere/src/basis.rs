//! The small trait shared by spherical representations (SH now; spherical Gaussians, vMF and
//! others follow the same shape): a fixed set of basis functions over the unit sphere, with
//! projection of environment maps and reconstruction built on top.
//!
//! Conventions: directions are unit vectors in the frame of the crate (+Y up); coefficients are
//! RGB (`Vec3`) or scalar (`f32`); [`SphericalBasis::project_env`] uses the exact quadrature
//! weights of [`EnvMap::texel`], which is a least-squares projection only for orthonormal bases.

use crate::envmap::{project_point_rule, EnvMap};
use crate::sh::{eval_sh, sh_count, MAX_ORDER};
use crate::Vec3;

/// A finite set of basis functions over the sphere.
pub trait SphericalBasis {
    /// Number of basis functions (coefficients).
    fn coeff_count(&self) -> usize;

    /// Writes the value of every basis function at unit direction `dir` into
    /// `out[..coeff_count()]`.
    fn eval_basis(&self, dir: Vec3, out: &mut [f32]);

    /// Whether the basis is orthonormal over the sphere (so that projection is the inner
    /// product with each basis function).
    fn is_orthonormal(&self) -> bool;

    /// Reconstruction `sum_i c_i B_i(dir)` (the default allocates a scratch buffer per call;
    /// implementations override it when they can do better).
    ///
    /// # Panics
    /// Debug builds assert `coeffs.len() == coeff_count()`.
    fn eval_rgb(&self, coeffs: &[Vec3], dir: Vec3) -> Vec3 {
        debug_assert_eq!(coeffs.len(), self.coeff_count());
        let mut b = vec![0f32; self.coeff_count()];
        self.eval_basis(dir, &mut b);
        coeffs
            .iter()
            .zip(&b)
            .fold(Vec3::ZERO, |a, (c, &y)| a + *c * y)
    }

    /// Inner products `int L(w) B_i(w) dw` with the map's exact texel weights (f64
    /// accumulation). For an orthonormal basis these are the projection coefficients.
    fn project_env(&self, map: &EnvMap) -> Vec<Vec3> {
        project_point_rule(
            map,
            self.coeff_count(),
            |d, o| self.eval_basis(d, o),
            |t| t.value,
        )
    }
}

/// Real spherical harmonics of a given order (conventions of [`crate::sh`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShBasis {
    /// Order `n` (bands `0..n-1`, `n^2` functions), at most [`MAX_ORDER`].
    pub order: usize,
}

impl ShBasis {
    /// SH basis of `order`.
    ///
    /// # Panics
    /// Panics if `order > MAX_ORDER`.
    pub fn new(order: usize) -> Self {
        assert!(
            order <= MAX_ORDER,
            "SH order {order} exceeds MAX_ORDER {MAX_ORDER}"
        );
        ShBasis { order }
    }
}

impl SphericalBasis for ShBasis {
    fn coeff_count(&self) -> usize {
        sh_count(self.order)
    }

    fn eval_basis(&self, dir: Vec3, out: &mut [f32]) {
        eval_sh(self.order, dir, out);
    }

    fn is_orthonormal(&self) -> bool {
        true
    }

    fn eval_rgb(&self, coeffs: &[Vec3], dir: Vec3) -> Vec3 {
        debug_assert_eq!(coeffs.len(), self.coeff_count());
        crate::sh::eval_rgb(coeffs, dir)
    }

    /// Exact for latlong maps (`sh::project`), the point rule for cube and probe maps.
    fn project_env(&self, map: &EnvMap) -> Vec<Vec3> {
        crate::sh::project_env(map, self.order)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::{eval_rgb, project_env};

    #[test]
    fn sh_basis_matches_sh_module() {
        let f = |d: Vec3| Vec3::new(1.0 + d.x, d.y * d.y, (2.0 * d.z).cos());
        let m = EnvMap::cube_from_fn(12, f);
        let b = ShBasis::new(4);
        assert_eq!(b.coeff_count(), 16);
        assert!(b.is_orthonormal());
        let (p, q) = (b.project_env(&m), project_env(&m, 4));
        assert!(p
            .iter()
            .zip(&q)
            .all(|(a, c)| (*a - *c).abs().max_element() < 1e-5));
        let d = Vec3::new(0.48, 0.6, 0.64);
        assert!((b.eval_rgb(&p, d) - eval_rgb(&p, d)).abs().max_element() < 1e-6);
    }
}
