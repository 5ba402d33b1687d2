//! Isotropic spherical Gaussians (SGs): evaluation, closed-form integrals, products, inner
//! products, L2 distances and importance sampling.
//!
//! # Definition and conventions
//! An SG lobe with unit axis `mu`, sharpness `lambda > 0` and RGB amplitude `a` is
//!
//! ```text
//! G(v; mu, lambda, a) = a exp(lambda (mu . v - 1))          (peak value a at v = mu)
//! ```
//!
//! Green 2005 (thesis, eq. 2.1 and eq. 3.2) writes each lobe as `w_k G(w, mu_k, sigma_k)`, a
//! normalised 2D Gaussian of standard deviation `sigma` in a cube-face chart:
//! `exp(-|M(w) - M(mu)|^2 / 2 sigma^2) / (2 pi sigma^2)`. Near the axis `|M(w) - M(mu)|^2`
//! is the squared angle `theta^2 ~ 2 (1 - mu . w)`, so the two agree to second order with
//! **`lambda = 1 / sigma^2`** (sigma in radians) and `a = w / (2 pi sigma^2)`; this module
//! uses that mapping ([`sharpness_from_sigma`], [`sigma_from_sharpness`]). The exponential form
//! is the one of Wang et al. 2009 ("All-frequency rendering of dynamic, spatially-varying
//! reflectance", SIGGRAPH Asia, section 3), whose closed-form product and integral are used
//! here: it is exactly rotation invariant and needs no chart.
//!
//! # Why an SG mixture does not implement [`crate::basis::SphericalBasis`]
//! A mixture `sum_k G(v; mu_k, lambda_k, a_k)` is linear only in the amplitudes; the axes and
//! sharpnesses enter non-linearly, so the set of mixtures with `N` lobes is not a vector space
//! (the sum of two 1-lobe mixtures needs 2 lobes) and "projection" is a non-linear fit
//! (`sg_fit.rs`), not an inner product with fixed basis functions. The trait's verbs are
//! therefore provided as free functions: eval ([`eval_mixture`]), fit (`sg_fit`), rotate
//! ([`SgLobe::rotated`]), integrate a product ([`inner_product`], [`mixture_inner_product`],
//! and with an environment map [`integrate_with_env`]).

use crate::envmap::EnvMap;
use crate::warp::Frame;
use crate::{Mat3, Vec2, Vec3};

/// One isotropic spherical Gaussian lobe `a exp(lambda (mu . v - 1))` (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SgLobe {
    /// Unit axis `mu` (direction of the peak).
    pub axis: Vec3,
    /// Sharpness `lambda > 0` (`1 / sigma^2`, sigma in radians).
    pub sharpness: f32,
    /// RGB amplitude `a` (the value at the peak).
    pub amplitude: Vec3,
}

/// `lambda = 1 / sigma^2`: Green 2005's standard deviation (radians) to sharpness.
#[inline]
pub fn sharpness_from_sigma(sigma: f32) -> f32 {
    debug_assert!(sigma > 0.0);
    1.0 / (sigma * sigma)
}

/// `sigma = 1 / sqrt(lambda)`: sharpness to Green 2005's standard deviation (radians).
#[inline]
pub fn sigma_from_sharpness(lambda: f32) -> f32 {
    debug_assert!(lambda > 0.0);
    lambda.sqrt().recip()
}

/// `(1 - exp(-2 x)) / x`, stable for small `x` (limit 2 at `x = 0`), in f64.
#[inline]
fn one_minus_exp_m2x_over_x(x: f64) -> f64 {
    if x < 1e-8 {
        2.0 - 2.0 * x
    } else {
        -(-2.0 * x).exp_m1() / x
    }
}

/// Integral over the sphere of the unit-amplitude lobe of sharpness `lambda`:
/// `int exp(lambda (mu . v - 1)) dv = 2 pi (1 - exp(-2 lambda)) / lambda` (Wang et al. 2009,
/// eq. 5). Tends to `4 pi` as `lambda -> 0`.
///
/// # Panics
/// Debug builds assert `lambda >= 0`.
#[inline]
pub fn unit_integral(lambda: f32) -> f32 {
    debug_assert!(lambda >= 0.0);
    (2.0 * std::f64::consts::PI * one_minus_exp_m2x_over_x(lambda as f64)) as f32
}

impl SgLobe {
    /// A lobe; `axis` is normalised.
    ///
    /// # Panics
    /// Debug builds assert a non-zero axis and `sharpness > 0`.
    pub fn new(axis: Vec3, sharpness: f32, amplitude: Vec3) -> SgLobe {
        debug_assert!(axis.length_squared() > 0.0 && sharpness > 0.0);
        SgLobe {
            axis: axis.normalize(),
            sharpness,
            amplitude,
        }
    }

    /// Value of the unit-amplitude lobe `exp(lambda (mu . v - 1))` at unit `dir`.
    #[inline]
    pub fn eval_unit(&self, dir: Vec3) -> f32 {
        (self.sharpness * (self.axis.dot(dir) - 1.0)).exp()
    }

    /// Value `a exp(lambda (mu . v - 1))` at unit `dir`.
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        self.amplitude * self.eval_unit(dir)
    }

    /// Exact integral over the sphere, `a 2 pi (1 - exp(-2 lambda)) / lambda`.
    #[inline]
    pub fn integral(&self) -> Vec3 {
        self.amplitude * unit_integral(self.sharpness)
    }

    /// The lobe of `v -> G(R^T v)`, i.e. rotated by `world_from_lobe` (axis `R mu`).
    #[inline]
    pub fn rotated(&self, world_from_lobe: Mat3) -> SgLobe {
        SgLobe {
            axis: (world_from_lobe * self.axis).normalize(),
            ..*self
        }
    }
}

/// The product of two SGs is an SG (Wang et al. 2009, eq. 4): with
/// `u = lambda_1 mu_1 + lambda_2 mu_2`, `lambda_m = |u|`, `mu_m = u / lambda_m` and
/// `a_m = a_1 a_2 exp(lambda_m - lambda_1 - lambda_2)` (component-wise RGB product).
/// When `u = 0` (equal sharpness, opposite axes) the product is the constant
/// `a_1 a_2 exp(-2 lambda)`, returned as a lobe of tiny sharpness about `mu_1`.
pub fn product(g1: &SgLobe, g2: &SgLobe) -> SgLobe {
    let u = g1.axis * g1.sharpness + g2.axis * g2.sharpness;
    let lm = u.length();
    let amp = g1.amplitude * g2.amplitude * (lm - g1.sharpness - g2.sharpness).exp();
    if lm > 1e-6 {
        SgLobe {
            axis: u / lm,
            sharpness: lm,
            amplitude: amp,
        }
    } else {
        SgLobe {
            axis: g1.axis,
            sharpness: 1e-6,
            amplitude: amp,
        }
    }
}

/// `int G_1(v) G_2(v) dv` in closed form (integral of [`product`]), computed in f64 as
/// `a_1 a_2 2 pi (exp(lambda_m - lambda_1 - lambda_2) - exp(-lambda_m - lambda_1 - lambda_2)) / lambda_m`
/// so that very sharp lobes do not overflow.
pub fn inner_product(g1: &SgLobe, g2: &SgLobe) -> Vec3 {
    let (l1, l2) = (g1.sharpness as f64, g2.sharpness as f64);
    let (a, b) = (g1.axis, g2.axis);
    let u = [
        a.x as f64 * l1 + b.x as f64 * l2,
        a.y as f64 * l1 + b.y as f64 * l2,
        a.z as f64 * l1 + b.z as f64 * l2,
    ];
    let lm = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    let s = 2.0 * std::f64::consts::PI * (lm - l1 - l2).exp() * one_minus_exp_m2x_over_x(lm);
    g1.amplitude * g2.amplitude * s as f32
}

/// Value of the mixture `sum_k G_k(dir)`.
#[inline]
pub fn eval_mixture(lobes: &[SgLobe], dir: Vec3) -> Vec3 {
    lobes.iter().fold(Vec3::ZERO, |acc, g| acc + g.eval(dir))
}

/// Exact integral of a mixture over the sphere.
pub fn integrate_mixture(lobes: &[SgLobe]) -> Vec3 {
    lobes.iter().fold(Vec3::ZERO, |acc, g| acc + g.integral())
}

/// `int A(v) B(v) dv` of two mixtures (per RGB channel), `sum_{j,k} <A_j, B_k>`.
pub fn mixture_inner_product(a: &[SgLobe], b: &[SgLobe]) -> Vec3 {
    a.iter()
        .flat_map(|x| b.iter().map(move |y| inner_product(x, y)))
        .fold(Vec3::ZERO, |acc, v| acc + v)
}

/// L2 distance `sqrt(int (A - B)^2)` of two mixtures, per RGB channel, from
/// `<A,A> - 2 <A,B> + <B,B>` (clamped at zero; absolute accuracy about `1e-3 |A| |B|` in f32
/// because of the cancellation, so compare nearly equal mixtures by their parameters).
pub fn l2_distance(a: &[SgLobe], b: &[SgLobe]) -> Vec3 {
    let d2 = mixture_inner_product(a, a) - 2.0 * mixture_inner_product(a, b)
        + mixture_inner_product(b, b);
    d2.max(Vec3::ZERO).map(f32::sqrt)
}

/// `int (sum_k G_k(w)) L(w) dw` against an environment map (any layout) with the map's exact
/// quadrature weights ([`EnvMap::texel`]): the brute-force "integrate a product with the
/// lighting" verb, `O(texels x lobes)`; renderers use `env_prefilter` instead.
pub fn integrate_with_env(lobes: &[SgLobe], map: &EnvMap) -> Vec3 {
    let mut acc = [0f64; 3];
    for t in map.texel_iter() {
        let v = eval_mixture(lobes, t.dir) * t.value * t.solid_angle;
        acc[0] += v.x as f64;
        acc[1] += v.y as f64;
        acc[2] += v.z as f64;
    }
    Vec3::new(acc[0] as f32, acc[1] as f32, acc[2] as f32)
}

/// Samples the normalised SG `p(v) = exp(lambda (mu . v - 1)) / unit_integral(lambda)` from
/// `u` in `[0,1)^2`: `cos theta = 1 + ln(1 - u_0 (1 - exp(-2 lambda))) / lambda`,
/// `phi = 2 pi u_1` about `mu` (the inverse CDF of the exponential in `cos theta`).
///
/// # Panics
/// Debug builds assert a unit axis and `lambda > 0`.
pub fn sample_sg(axis: Vec3, lambda: f32, u: Vec2) -> Vec3 {
    debug_assert!(lambda > 0.0);
    let l = lambda as f64;
    let cos_t = (1.0 + (-(u.x as f64) * (-(-2.0 * l).exp_m1())).ln_1p() / l).clamp(-1.0, 1.0);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u.y as f64;
    let local = Vec3::new(
        (sin_t * phi.cos()) as f32,
        (sin_t * phi.sin()) as f32,
        cos_t as f32,
    );
    Frame::from_normal(axis).to_world(local).normalize()
}

/// Density of [`sample_sg`] with respect to solid angle.
#[inline]
pub fn sg_pdf(axis: Vec3, lambda: f32, dir: Vec3) -> f32 {
    debug_assert!(lambda > 0.0);
    (lambda * (axis.dot(dir) - 1.0)).exp() / unit_integral(lambda)
}

/// Inverse of [`sample_sg`]: the `u` that maps to unit `dir`.
pub fn invert_sg_sample(axis: Vec3, lambda: f32, dir: Vec3) -> Vec2 {
    debug_assert!(lambda > 0.0);
    let local = Frame::from_normal(axis).to_local(dir);
    let l = lambda as f64;
    let c = (local.z as f64).clamp(-1.0, 1.0);
    let u0 = (l * (c - 1.0)).exp_m1() / (-2.0 * l).exp_m1();
    let mut phi = (local.y as f64).atan2(local.x as f64);
    if phi < 0.0 {
        phi += 2.0 * std::f64::consts::PI;
    }
    Vec2::new(
        u0.clamp(0.0, 1.0) as f32,
        (phi / (2.0 * std::f64::consts::PI)) as f32,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chi2::{chi2_sphere_test, ChiTest};
    use crate::quadrature::sphere_rule_f32;
    use crate::warp::hammersley;
    use crate::Rng;
    use std::f32::consts::PI;

    /// `int f` by Hammersley points on the sphere (quasi-Monte Carlo, as an independent check).
    fn qmc(f: impl Fn(Vec3) -> f64, n: u32) -> f64 {
        (0..n)
            .map(|i| f(crate::warp::square_to_uniform_sphere(hammersley(i, n))))
            .sum::<f64>()
            * 4.0
            * std::f64::consts::PI
            / n as f64
    }

    fn lobe(rng: &mut Rng, lmax: f32) -> SgLobe {
        let d = crate::warp::square_to_uniform_sphere(rng.next_vec2());
        SgLobe::new(
            d,
            0.5 + lmax * rng.next_f32(),
            Vec3::new(rng.next_f32(), rng.next_f32(), 0.5),
        )
    }

    #[test]
    fn integral_and_inner_product_vs_qmc() {
        let mut rng = Rng::new(3, 4);
        for _ in 0..6 {
            let (a, b) = (lobe(&mut rng, 20.0), lobe(&mut rng, 20.0));
            let n = 1 << 18;
            let ia = qmc(|v| a.eval(v).x as f64, n);
            // QMC with 2^18 points on lobes with lambda <= 20: relative error well below 1e-3.
            assert!(
                (ia - a.integral().x as f64).abs() < 2e-3 * ia,
                "{ia} {:?}",
                a
            );
            let iab = qmc(|v| (a.eval(v) * b.eval(v)).y as f64, n);
            let cf = inner_product(&a, &b).y as f64;
            assert!((iab - cf).abs() < 2e-3 * iab.max(1e-3), "{iab} {cf}");
            // The product lobe is pointwise the product.
            let p = product(&a, &b);
            for i in 0..50 {
                let v = crate::warp::square_to_uniform_sphere(hammersley(i, 50));
                let (x, y) = (p.eval(v), a.eval(v) * b.eval(v));
                assert!((x - y).abs().max_element() < 1e-5 + 1e-4 * y.max_element());
            }
        }
        // Limits: lambda -> 0 gives 4 pi; sharp lobes tend to 2 pi / lambda.
        assert!((unit_integral(0.0) - 4.0 * PI).abs() < 1e-5);
        assert!((unit_integral(1e4) * 1e4 - 2.0 * PI).abs() < 1e-4);
        // Opposite equal lobes: the product is the constant exp(-2 lambda).
        let g = SgLobe::new(Vec3::Y, 2.0, Vec3::ONE);
        let h = SgLobe::new(-Vec3::Y, 2.0, Vec3::ONE);
        let e = 4.0 * PI * (-4.0f32).exp();
        assert!((inner_product(&g, &h).x - e).abs() < 1e-5 * e.max(1.0));
    }

    #[test]
    fn l2_distance_matches_quadrature() {
        let mut rng = Rng::new(9, 1);
        let a = [lobe(&mut rng, 10.0), lobe(&mut rng, 10.0)];
        let b = [lobe(&mut rng, 10.0)];
        let (dirs, w) = sphere_rule_f32(60);
        let mut d2 = 0.0f64;
        for (d, w) in dirs.iter().zip(&w) {
            let diff = eval_mixture(&a, *d).z - eval_mixture(&b, *d).z;
            d2 += (diff * diff) as f64 * w;
        }
        let got = l2_distance(&a, &b).z as f64;
        assert!(
            (got - d2.sqrt()).abs() < 1e-3 * d2.sqrt(),
            "{got} {}",
            d2.sqrt()
        );
        assert!(l2_distance(&a, &a).max_element() < 2e-2 * mixture_inner_product(&a, &a).x.sqrt());
        let tot = integrate_mixture(&a);
        assert!(
            (tot - a[0].integral() - a[1].integral())
                .abs()
                .max_element()
                < 1e-6
        );
    }

    #[test]
    fn env_integral_matches_closed_form() {
        let a = SgLobe::new(Vec3::new(0.3, 0.8, -0.2), 12.0, Vec3::new(1.0, 0.5, 0.2));
        let b = SgLobe::new(Vec3::new(0.5, 0.6, 0.1), 7.0, Vec3::new(0.3, 1.0, 2.0));
        let map = EnvMap::cube_from_fn(48, |d| b.eval(d));
        let got = integrate_with_env(&[a], &map);
        let want = inner_product(&a, &b);
        // Midpoint rule on 6x48x48 texels for smooth lobes (lambda <= 12): well below 0.5 %.
        assert!(
            ((got - want).abs() / want).max_element() < 5e-3,
            "{got} {want}"
        );
    }

    #[test]
    fn rotation_moves_the_axis() {
        let g = SgLobe::new(Vec3::X, 5.0, Vec3::ONE);
        let r = Mat3::from_rotation_y(0.7);
        let h = g.rotated(r);
        let v = Vec3::new(0.3, 0.5, -0.81).normalize();
        assert!((h.eval(r * v) - g.eval(v)).abs().max_element() < 1e-5);
    }

    #[test]
    fn sampling_triple_chi2_and_inverse() {
        for (axis, lambda) in [
            (Vec3::new(0.2, 0.9, -0.3).normalize(), 3.0),
            (Vec3::new(0.6, 0.0, 0.8), 12.0),
            (-Vec3::Y, 0.05),
        ] {
            let mut rng = Rng::new(5, 2);
            let res = chi2_sphere_test(
                // 16 x 16 sub-samples per bin: the pdf integral of a lambda = 12 lobe needs them.
                &ChiTest {
                    sub: 16,
                    ..ChiTest::default()
                },
                |_| sample_sg(axis, lambda, rng.next_vec2()),
                |d| sg_pdf(axis, lambda, d) as f64,
            );
            assert!(res.passed, "lambda {lambda}: {res:?}");
            let mut rng = Rng::new(1, 8);
            for _ in 0..2000 {
                let u = rng.next_vec2();
                let d = sample_sg(axis, lambda, u);
                assert!((d.length() - 1.0).abs() < 1e-5);
                let back = invert_sg_sample(axis, lambda, d);
                // f32 directions: cos theta near 1 carries ~1e-7 absolute error, amplified by
                // lambda in u_0; 2e-3 covers lambda = 12.
                let mut e = (back - u).abs();
                e.y = e.y.min(1.0 - e.y);
                assert!(e.max_element() < 2e-3, "{u} -> {back}");
            }
        }
    }
}
