//! Real spherical harmonics: evaluation, projection of environment maps, zonal convolution
//! and windowing. Two child modules build on the definitions here: [`rotate`] (rotation of any
//! order) and [`project`] (the exact projection of latlong maps that [`project_env`] uses).
//!
//! # Convention (the crate's, stated once here)
//! Real, orthonormal SH over the unit sphere, on **world Cartesian** `(x, y, z)` with the
//! Legendre polar axis along world **+Z**, `cos theta = z`, `phi = atan2(y, x)`, **without the
//! Condon-Shortley phase** (Ramamoorthi & Hanrahan 2001, "An Efficient Representation for
//! Irradiance Environment Maps", eq. 3 / appendix; Sloan 2008, "Stupid Spherical Harmonics
//! (SH) Tricks", appendix A2):
//! * `Y_l^0 = K_l^0 P_l^0(z)`,
//! * `Y_l^m = sqrt(2) K_l^m cos(m phi) P_l^m(z)`, `m > 0`,
//! * `Y_l^-m = sqrt(2) K_l^m sin(m phi) P_l^m(z)`, `m > 0`,
//!
//! with `K_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!)` and `P_l^m` the associated Legendre
//! function *without* the `(-1)^m` factor, so e.g. `Y_1^{-1} = 0.488603 y`,
//! `Y_1^0 = 0.488603 z`, `Y_1^1 = 0.488603 x`, `Y_2^{-2} = 1.092548 xy`.
//! Flat index `l (l + 1) + m`; **order** `n` means bands `0..n-1`, i.e. `n^2` coefficients.
//!
//! Coefficients of radiance `L` are `L_lm = int L(w) Y_lm(w) dw`; reconstruction is
//! `L(w) ~ sum L_lm Y_lm(w)`.

use crate::envmap::{project_point_rule, EnvMap};
use crate::Vec3;
use std::f64::consts::PI;
use std::sync::OnceLock;

pub mod project;
pub mod rotate;

/// Largest supported order (bands `0..MAX_ORDER-1`).
pub const MAX_ORDER: usize = 32;

/// Number of coefficients of order `order`: `order^2`.
#[inline]
pub const fn sh_count(order: usize) -> usize {
    order * order
}

/// Flat index `l (l + 1) + m` of `Y_l^m`.
///
/// # Panics
/// Debug builds assert `l >= 0` and `|m| <= l`.
#[inline]
pub fn sh_index(l: i32, m: i32) -> usize {
    debug_assert!(l >= 0 && m.abs() <= l);
    (l * (l + 1) + m) as usize
}

/// Order of a coefficient vector of length `len` (`len` must be a perfect square).
///
/// # Panics
/// Debug builds assert that `len` is a perfect square.
#[inline]
pub fn order_of(len: usize) -> usize {
    let n = (len as f64).sqrt().round() as usize;
    debug_assert_eq!(n * n, len, "SH coefficient count must be a square");
    n
}

// Hard-coded band 0..3 constants (R&H 2001 eq. 3; Sloan 2008 appendix A2), as f64 for clarity.
const C0: f32 = 0.282_094_791_773_878_1_f64 as f32; // 1 / (2 sqrt(pi))
const C1: f32 = 0.488_602_511_902_919_9_f64 as f32; // sqrt(3) / (2 sqrt(pi))
const C2A: f32 = 1.092_548_430_592_079_1_f64 as f32; // sqrt(15) / (2 sqrt(pi))
const C2B: f32 = 0.315_391_565_252_52_f64 as f32; // sqrt(5) / (4 sqrt(pi))
const C2C: f32 = 0.546_274_215_296_039_5_f64 as f32; // sqrt(15) / (4 sqrt(pi))
const C3A: f32 = 0.590_043_589_926_643_5_f64 as f32; // sqrt(35 / (32 pi))
const C3B: f32 = 2.890_611_442_640_554_f64 as f32; // sqrt(105) / (2 sqrt(pi))
const C3C: f32 = 0.457_045_799_464_465_7_f64 as f32; // sqrt(21 / (32 pi))
const C3D: f32 = 0.373_176_332_590_115_4_f64 as f32; // sqrt(7) / (4 sqrt(pi))
const C3E: f32 = 1.445_305_721_320_277_f64 as f32; // sqrt(105) / (4 sqrt(pi))

/// Bands 0..3 by their Cartesian polynomials.
#[inline]
fn eval_sh_order4(d: Vec3) -> [f32; 16] {
    let (x, y, z) = (d.x, d.y, d.z);
    let (x2, y2, z2) = (x * x, y * y, z * z);
    [
        C0,
        C1 * y,
        C1 * z,
        C1 * x,
        C2A * x * y,
        C2A * y * z,
        C2B * (3.0 * z2 - 1.0),
        C2A * x * z,
        C2C * (x2 - y2),
        C3A * y * (3.0 * x2 - y2),
        C3B * x * y * z,
        C3C * y * (5.0 * z2 - 1.0),
        C3D * z * (5.0 * z2 - 3.0),
        C3C * x * (5.0 * z2 - 1.0),
        C3E * z * (x2 - y2),
        C3A * x * (x2 - 3.0 * y2),
    ]
}

/// Recurrence coefficients of the normalised associated Legendre functions
/// `y_l^m = K_l^m P_l^m / sin^m(theta)`: `y_l^m = a_lm (z y_{l-1}^m - b_lm y_{l-2}^m)` with
/// `a_lm = sqrt((4l^2 - 1) / (l^2 - m^2))`, `b_lm = sqrt(((l-1)^2 - m^2) / (4(l-1)^2 - 1))`,
/// and the diagonal factors `y_m^m = sqrt((2m+1) / 2m) y_{m-1}^{m-1}`. Indexed by `sh_index(l, m)`.
struct Recurrence {
    a: Vec<f32>,
    b: Vec<f32>,
    diag: Vec<f32>,
}

fn recurrence() -> &'static Recurrence {
    static TABLE: OnceLock<Recurrence> = OnceLock::new();
    TABLE.get_or_init(|| {
        let n = sh_count(MAX_ORDER);
        let (mut a, mut b) = (vec![0f32; n], vec![0f32; n]);
        for l in 2..MAX_ORDER as i32 {
            for m in 0..=(l - 2) {
                let (lf, mf) = (l as f64, m as f64);
                a[sh_index(l, m)] = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt() as f32;
                let l1 = lf - 1.0;
                b[sh_index(l, m)] = ((l1 * l1 - mf * mf) / (4.0 * l1 * l1 - 1.0)).sqrt() as f32;
            }
        }
        let diag = (0..MAX_ORDER)
            .map(|m| {
                if m == 0 {
                    1.0
                } else {
                    ((2 * m + 1) as f64 / (2 * m) as f64).sqrt() as f32
                }
            })
            .collect();
        Recurrence { a, b, diag }
    })
}

/// Evaluates all `order^2` real SH at unit direction `dir` into `out[..order^2]`.
/// Orders `<= 4` use the hard-coded polynomials; higher orders the normalised associated
/// Legendre recurrence along `z` combined with `Re/Im (x + i y)^m` (no trigonometry).
///
/// # Panics
/// Debug builds assert `order <= MAX_ORDER` and `out.len() >= order^2`.
#[inline]
pub fn eval_sh(order: usize, dir: Vec3, out: &mut [f32]) {
    debug_assert!(order <= MAX_ORDER && out.len() >= sh_count(order));
    if order <= 4 {
        let all = eval_sh_order4(dir);
        out[..sh_count(order)].copy_from_slice(&all[..sh_count(order)]);
        return;
    }
    let r = recurrence();
    let (x, y, z) = (dir.x, dir.y, dir.z);
    let sqrt2 = std::f32::consts::SQRT_2;
    // (cm, sm) = Re, Im of (x + i y)^m; ymm = y_m^m.
    let (mut cm, mut sm) = (1.0f32, 0.0f32);
    let mut ymm = C0;
    for m in 0..order as i32 {
        if m > 0 {
            let c = cm * x - sm * y;
            sm = cm * y + sm * x;
            cm = c;
            ymm *= r.diag[m as usize];
        }
        let (fc, fs) = if m == 0 {
            (1.0, 0.0)
        } else {
            (sqrt2 * cm, sqrt2 * sm)
        };
        let put = |out: &mut [f32], l: i32, v: f32| {
            out[sh_index(l, m)] = v * fc;
            if m > 0 {
                out[sh_index(l, -m)] = v * fs;
            }
        };
        put(out, m, ymm);
        if m + 1 >= order as i32 {
            continue;
        }
        let mut prev2 = ymm;
        let mut prev1 = (2.0 * m as f32 + 3.0).sqrt() * z * ymm;
        put(out, m + 1, prev1);
        for l in (m + 2)..order as i32 {
            let i = sh_index(l, m);
            let cur = r.a[i] * (z * prev1 - r.b[i] * prev2);
            put(out, l, cur);
            prev2 = prev1;
            prev1 = cur;
        }
    }
}

/// Reference evaluation in f64 from the textbook definition: explicit factorials for `K_l^m`,
/// the unnormalised associated Legendre recurrence (`P_m^m = (2m-1)!! sin^m`,
/// `P_{m+1}^m = (2m+1) z P_m^m`, `(l-m) P_l^m = (2l-1) z P_{l-1}^m - (l+m-1) P_{l-2}^m`) and
/// `cos(m phi)`, `sin(m phi)` from `phi = atan2(y, x)`.
///
/// # Panics
/// Debug builds assert `order <= MAX_ORDER` and `out.len() >= order^2`.
pub fn eval_sh_slow(order: usize, dir: Vec3, out: &mut [f64]) {
    debug_assert!(order <= MAX_ORDER && out.len() >= sh_count(order));
    // No renormalisation: like the fast path, evaluate at the given (unit) vector, with
    // sin(theta) = |(x, y)|, so both see the same f32 input.
    let (x, y, z) = (dir.x as f64, dir.y as f64, dir.z as f64);
    let sin_t = (x * x + y * y).sqrt();
    let phi = y.atan2(x);
    legendre_factors(order, z, sin_t, |l, m, v| {
        if m == 0 {
            out[sh_index(l, 0)] = v;
        } else {
            out[sh_index(l, m)] = v * (m as f64 * phi).cos();
            out[sh_index(l, -m)] = v * (m as f64 * phi).sin();
        }
    });
}

/// The polar part of [`eval_sh_slow`]: for `0 <= m <= l < order`, calls
/// `emit(l, m, K_l^m P_l^m(z))` (times `sqrt 2` when `m > 0`, the real basis' factor), with
/// explicit factorials in `K_l^m` and the unnormalised associated Legendre recurrence, in f64.
/// `sin_t` is `sin(theta)` (passed in so callers control its rounding).
pub(crate) fn legendre_factors(
    order: usize,
    z: f64,
    sin_t: f64,
    mut emit: impl FnMut(i32, i32, f64),
) {
    let fact = |k: i32| (1..=k).fold(1.0f64, |a, i| a * i as f64);
    for m in 0..order as i32 {
        // P_l^m(z) for l = m.. by the classic recurrence.
        let mut pmm = 1.0;
        for k in 1..=m {
            pmm *= (2 * k - 1) as f64 * sin_t;
        }
        let mut p_prev = 0.0;
        let mut p = pmm;
        for l in m..order as i32 {
            if l == m + 1 {
                p_prev = p;
                p = (2 * m + 1) as f64 * z * pmm;
            } else if l > m + 1 {
                let next =
                    ((2 * l - 1) as f64 * z * p - (l + m - 1) as f64 * p_prev) / (l - m) as f64;
                p_prev = p;
                p = next;
            }
            let k = ((2 * l + 1) as f64 / (4.0 * PI) * fact(l - m) / fact(l + m)).sqrt();
            emit(l, m, if m == 0 { k * p } else { 2f64.sqrt() * k * p });
        }
    }
}

/// RGB SH coefficients `L_lm = int L(w) Y_lm(w) dw` of `map` up to `order` (f64 accumulation).
///
/// * **Latlong**: exact for the function the map represents, its bilinear interpolant (what
///   [`EnvMap::eval`] and Mitsuba's `envmap` return), by the separable projection of
///   [`project`]; a constant map projects to `L_00` only (to rounding).
/// * **Cube, probe**: the point rule [`project_env_point_rule`] (their interpolants are not
///   separable; see [`project`]). A constant cube leaks nothing above band 0 (to
///   rounding), a constant 48-pixel probe about 1e-3 of `L_00`.
///
/// # Panics
/// Panics if `order > MAX_ORDER` (latlong; debug builds assert it for the other layouts).
pub fn project_env(map: &EnvMap, order: usize) -> Vec<Vec3> {
    match map.layout() {
        crate::envmap::EnvLayout::LatLong => project::project_latlong(map, order),
        _ => project_env_point_rule(map, order),
    }
}

/// Point-rule projection `L_lm = sum_i value_i Y_lm(dir_i) w_i` with the exact quadrature
/// weights of [`EnvMap::texel`] (every layout) and f64 accumulation. Exact only for `Y_00`: e.g.
/// a constant 64 x 33 latlong map leaks 1.6e-3 of `L_00` into band 2. Kept for the cube and
/// probe layouts and for comparisons; [`project_env`] is exact for latlong maps.
///
/// # Panics
/// Debug builds assert `order <= MAX_ORDER`.
pub fn project_env_point_rule(map: &EnvMap, order: usize) -> Vec<Vec3> {
    debug_assert!(order <= MAX_ORDER);
    project_point_rule(
        map,
        sh_count(order),
        |d, o| eval_sh(order, d, o),
        |t| t.value,
    )
}

/// Projects a function of direction (e.g. an analytic radiance) with the quadrature of `map`'s
/// texels (values of `map` are ignored; only its directions and weights are used).
pub fn project_fn(grid: &EnvMap, order: usize, f: impl Fn(Vec3) -> Vec3) -> Vec<Vec3> {
    debug_assert!(order <= MAX_ORDER);
    project_point_rule(
        grid,
        sh_count(order),
        |d, o| eval_sh(order, d, o),
        |t| f(t.dir),
    )
}

/// Reconstruction `sum_lm c_lm Y_lm(dir)`; the order is `sqrt(coeffs.len())`.
///
/// # Panics
/// Debug builds assert that `coeffs.len()` is a square `<= MAX_ORDER^2`.
#[inline]
pub fn eval_rgb(coeffs: &[Vec3], dir: Vec3) -> Vec3 {
    let order = order_of(coeffs.len());
    let mut basis = [0f32; sh_count(MAX_ORDER)];
    eval_sh(order, dir, &mut basis);
    coeffs
        .iter()
        .zip(&basis)
        .fold(Vec3::ZERO, |a, (c, &y)| a + *c * y)
}

/// Scalar reconstruction `sum_lm c_lm Y_lm(dir)`.
#[inline]
pub fn eval_scalar(coeffs: &[f32], dir: Vec3) -> f32 {
    let order = order_of(coeffs.len());
    let mut basis = [0f32; sh_count(MAX_ORDER)];
    eval_sh(order, dir, &mut basis);
    coeffs.iter().zip(&basis).map(|(c, y)| c * y).sum()
}

/// `A_l` of Ramamoorthi & Hanrahan 2001 (eqs. 8-9): the factor with which the clamped cosine
/// kernel `max(0, cos)` convolves band `l`, so that irradiance is `E_lm = A_l L_lm`.
/// `A_0 = pi`, `A_1 = 2 pi / 3`, `A_l = 0` for odd `l > 1`, and for even `l`
/// `A_l = 2 pi (-1)^(l/2 - 1) / ((l + 2)(l - 1)) * l! / (2^l ((l/2)!)^2)`.
pub fn clamped_cosine_zonal(l: usize) -> f32 {
    match l {
        0 => std::f32::consts::PI,
        1 => 2.0 * std::f32::consts::PI / 3.0,
        _ if l % 2 == 1 => 0.0,
        _ => {
            // l! / (2^l ((l/2)!)^2) = prod_{k=1}^{l/2} (2k - 1) / (2k).
            let ratio: f64 = (1..=l / 2)
                .map(|k| (2 * k - 1) as f64 / (2 * k) as f64)
                .product();
            let sign = if l % 4 == 2 { 1.0 } else { -1.0 }; // (-1)^(l/2 - 1)
            (2.0 * PI * sign / ((l + 2) as f64 * (l - 1) as f64) * ratio) as f32
        }
    }
}

/// Zonal SH coefficients `z_l` of the clamped cosine `max(0, cos theta)` around the SH polar
/// axis: `z_l = A_l / sqrt(4 pi / (2l + 1))`, for bands `0..order-1`. Feed these to
/// [`convolve_zonal`].
pub fn clamped_cosine_zonal_coeffs(order: usize) -> Vec<f32> {
    (0..order)
        .map(|l| clamped_cosine_zonal(l) / (4.0 * PI / (2 * l + 1) as f64).sqrt() as f32)
        .collect()
}

/// Multiplies band `l` of `coeffs` by `factors[l]` (bands beyond `factors.len()` become 0).
pub fn scale_bands(coeffs: &[Vec3], factors: &[f32]) -> Vec<Vec3> {
    let order = order_of(coeffs.len());
    let mut out = coeffs.to_vec();
    for l in 0..order {
        let f = factors.get(l).copied().unwrap_or(0.0);
        for c in &mut out[l * l..(l + 1) * (l + 1)] {
            *c *= f;
        }
    }
    out
}

/// Convolution with a zonal (rotationally symmetric) kernel `h(w . n) = sum_l z_l Y_l^0`
/// (`zonal[l] = z_l`, the kernel's own SH coefficients about the polar axis): by the Funk-Hecke
/// theorem `(h * f)_lm = sqrt(4 pi / (2l + 1)) z_l f_lm`, where
/// `(h * f)(n) = int f(w) h(w . n) dw`. Bands beyond `zonal.len()` become 0.
pub fn convolve_zonal(coeffs: &[Vec3], zonal: &[f32]) -> Vec<Vec3> {
    let factors: Vec<f32> = zonal
        .iter()
        .enumerate()
        .map(|(l, z)| z * (4.0 * PI / (2 * l + 1) as f64).sqrt() as f32)
        .collect();
    scale_bands(coeffs, &factors)
}

/// Irradiance coefficients `E_lm = A_l L_lm` from radiance coefficients (R&H 2001 eq. 7):
/// `E(n) = int L(w) max(0, n . w) dw = sum E_lm Y_lm(n)`.
pub fn irradiance_from_radiance(radiance: &[Vec3]) -> Vec<Vec3> {
    let order = order_of(radiance.len());
    let a: Vec<f32> = (0..order).map(clamped_cosine_zonal).collect();
    scale_bands(radiance, &a)
}

/// A window applied to SH bands to reduce ringing (Gibbs phenomenon).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Window {
    /// No windowing (all weights 1).
    None,
    /// Hann: `w_l = (1 + cos(pi l / n)) / 2` for order `n`.
    Hann,
    /// Lanczos sigma factors: `w_l = sinc(pi l / n) = sin(pi l / n) / (pi l / n)`.
    Lanczos,
    /// Sloan 2008 ("Stupid SH tricks", windowing) / Sloan 2017 ("Deringing SH"): the
    /// minimiser of `||f - g||^2 + lambda ||Laplacian g||^2`, i.e.
    /// `w_l = 1 / (1 + lambda l^2 (l + 1)^2)`.
    Sloan {
        /// Strength of the Laplacian penalty (`>= 0`).
        lambda: f32,
    },
}

/// A window name that does not parse.
#[derive(Debug, thiserror::Error)]
#[error("unknown SH window '{0}' (none, hann, lanczos, sloan[:LAMBDA] with a finite LAMBDA >= 0)")]
pub struct WindowParseError(pub String);

impl std::str::FromStr for Window {
    type Err = WindowParseError;

    /// `none`, `hann`, `lanczos`, `sloan` (lambda 0.001) or `sloan:LAMBDA`.
    fn from_str(s: &str) -> Result<Window, WindowParseError> {
        let lambda = |l: &str| l.parse::<f32>().ok().filter(|x| x.is_finite() && *x >= 0.0);
        match s.split_once(':') {
            None if s == "none" => Ok(Window::None),
            None if s == "hann" => Ok(Window::Hann),
            None if s == "lanczos" => Ok(Window::Lanczos),
            None if s == "sloan" => Ok(Window::Sloan { lambda: 0.001 }),
            Some(("sloan", l)) => lambda(l)
                .map(|lambda| Window::Sloan { lambda })
                .ok_or_else(|| WindowParseError(s.into())),
            _ => Err(WindowParseError(s.into())),
        }
    }
}

/// Per-band weights `w_0..w_{order-1}` of `window` (`w_0 = 1`, non-increasing).
pub fn window_weights(order: usize, window: Window) -> Vec<f32> {
    let n = order.max(1) as f64;
    (0..order)
        .map(|l| {
            let t = PI * l as f64 / n;
            let w = match window {
                Window::None => 1.0,
                Window::Hann => 0.5 * (1.0 + t.cos()),
                Window::Lanczos => {
                    if l == 0 {
                        1.0
                    } else {
                        t.sin() / t
                    }
                }
                Window::Sloan { lambda } => {
                    debug_assert!(lambda >= 0.0);
                    let ll = (l * (l + 1)) as f64;
                    1.0 / (1.0 + lambda as f64 * ll * ll)
                }
            };
            w as f32
        })
        .collect()
}

/// Applies `window` for `order` to `coeffs` in place (band `l` multiplied by `w_l`).
///
/// # Panics
/// Debug builds assert `coeffs.len() >= order^2`.
pub fn apply_window(coeffs: &mut [Vec3], order: usize, window: Window) {
    debug_assert!(coeffs.len() >= sh_count(order));
    let w = window_weights(order, window);
    for (l, wl) in w.iter().enumerate() {
        for c in &mut coeffs[l * l..(l + 1) * (l + 1)] {
            *c *= *wl;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::EnvLayout;
    use crate::warp::{square_to_uniform_sphere, Rng};

    fn random_dirs(n: usize, seed: u64) -> Vec<Vec3> {
        let mut rng = Rng::new(seed, 0);
        let mut v: Vec<Vec3> = (0..n)
            .map(|_| square_to_uniform_sphere(rng.next_vec2()))
            .collect();
        v.extend([
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(0.0, 0.6, -0.8),
        ]);
        v
    }

    #[test]
    fn fast_matches_slow_all_orders() {
        let mut fast = vec![0f32; sh_count(MAX_ORDER)];
        let mut slow = vec![0f64; sh_count(MAX_ORDER)];
        for d in random_dirs(500, 1) {
            for order in 1..=MAX_ORDER {
                eval_sh(order, d, &mut fast);
                eval_sh_slow(order, d, &mut slow);
                for i in 0..sh_count(order) {
                    // |Y_lm| <= sqrt((2l+1)/4pi) ~ 2.2 at l = 31; f32 recurrence error ~ l ulp.
                    assert!(
                        (fast[i] as f64 - slow[i]).abs() < 1e-5,
                        "order {order} i {i} {d}: {} vs {}",
                        fast[i],
                        slow[i]
                    );
                }
            }
        }
    }

    #[test]
    fn published_constants() {
        // R&H 2001 eq. 3 with x, y, z: spot values of the convention.
        let mut y = [0f64; 9];
        let d = Vec3::new(0.36, 0.48, 0.8);
        eval_sh_slow(3, d, &mut y);
        let (x, yy, z) = (0.36f64, 0.48, 0.8);
        let expect = [
            0.282095,
            0.488603 * yy,
            0.488603 * z,
            0.488603 * x,
            1.092548 * x * yy,
            1.092548 * yy * z,
            0.315392 * (3.0 * z * z - 1.0),
            1.092548 * x * z,
            0.546274 * (x * x - yy * yy),
        ];
        for i in 0..9 {
            assert!(
                (y[i] - expect[i]).abs() < 2e-6,
                "{i}: {} vs {}",
                y[i],
                expect[i]
            );
        }
    }

    #[test]
    fn orthonormal_by_quadrature() {
        // Gram matrix of order 8 with the exact latlong weights of a dense map.
        let order = 8;
        let n = sh_count(order);
        let grid = EnvMap::constant(Vec3::ZERO).to_latlong(512, 257);
        let mut gram = vec![0f64; n * n];
        let mut y = vec![0f32; n];
        for t in grid.texel_iter() {
            eval_sh(order, t.dir, &mut y);
            for i in 0..n {
                for j in 0..n {
                    gram[i * n + j] += (y[i] * y[j]) as f64 * t.solid_angle as f64;
                }
            }
        }
        for i in 0..n {
            for j in 0..n {
                let e = if i == j { 1.0 } else { 0.0 };
                // Tent-weight quadrature of degree-14 polynomials on 257 rows: error ~(l h)^2/12.
                assert!(
                    (gram[i * n + j] - e).abs() < 2e-3,
                    "({i},{j}) {}",
                    gram[i * n + j]
                );
            }
        }
    }

    #[test]
    fn constant_env_projects_to_l00_every_layout() {
        let c = Vec3::new(0.5, 1.0, 2.0);
        let maps = [
            EnvMap::constant(c),
            EnvMap::latlong(64, 33, vec![c; 64 * 33]),
            EnvMap::cube(16, vec![c; 6 * 256]),
            EnvMap::probe(48, vec![c; 48 * 48]),
        ];
        let l00 = c * (4.0 * std::f32::consts::PI).sqrt();
        for m in &maps {
            let p = project_env(m, 4);
            assert!(
                ((p[0] - l00) / l00).abs().max_element() < 1e-5,
                "{:?}: {}",
                m.layout(),
                p[0]
            );
            // Higher bands vanish: latlong maps are projected exactly (`sh::project`); cube
            // texels are symmetric under the octahedral group, so the point rule's bands 1..3
            // cancel to rounding; probe pixels are not Gauss nodes, leaving O(h^2) (measured
            // 1.0e-3 for a 48-pixel probe).
            let tol = match m.layout() {
                EnvLayout::Probe => 2e-3,
                _ => 1e-6,
            };
            for (i, v) in p.iter().enumerate().skip(1) {
                assert!(
                    (*v / l00).abs().max_element() < tol,
                    "{:?} {i}: {v}",
                    m.layout()
                );
            }
        }
    }

    #[test]
    fn projection_reconstructs_band_limited_function() {
        let order = 5;
        let mut rng = Rng::new(4, 4);
        let coeffs: Vec<Vec3> = (0..sh_count(order))
            .map(|_| {
                Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                )
            })
            .collect();
        for m in [
            EnvMap::latlong_from_fn(256, 129, |d| eval_rgb(&coeffs, d)),
            EnvMap::cube_from_fn(48, |d| eval_rgb(&coeffs, d)),
            EnvMap::probe_from_fn(192, |d| eval_rgb(&coeffs, d)),
        ] {
            let p = project_env(&m, order);
            for (a, b) in p.iter().zip(&coeffs) {
                assert!(
                    (*a - *b).abs().max_element() < 3e-3,
                    "{:?}: {a} vs {b}",
                    m.layout()
                );
            }
        }
    }

    #[test]
    fn clamped_cosine_values() {
        use std::f32::consts::PI;
        assert!((clamped_cosine_zonal(0) - PI).abs() < 1e-6);
        assert!((clamped_cosine_zonal(1) - 2.0 * PI / 3.0).abs() < 1e-6);
        assert!((clamped_cosine_zonal(2) - PI / 4.0).abs() < 1e-6);
        assert!((clamped_cosine_zonal(4) + PI / 24.0).abs() < 1e-6);
        for l in (3..40).step_by(2) {
            assert_eq!(clamped_cosine_zonal(l), 0.0);
        }
        // Against numerical Funk-Hecke: A_l = 2 pi int_0^1 P_l(t) t dt.
        for l in 0..12 {
            let n = 20000;
            let mut acc = 0.0;
            for k in 0..n {
                let t = (k as f64 + 0.5) / n as f64;
                let (mut p0, mut p1) = (1.0, t);
                for j in 2..=l {
                    let p2 = ((2 * j - 1) as f64 * t * p1 - (j - 1) as f64 * p0) / j as f64;
                    p0 = p1;
                    p1 = p2;
                }
                let pl = if l == 0 { 1.0 } else { p1 };
                acc += pl * t / n as f64;
            }
            let a = 2.0 * std::f64::consts::PI * acc;
            assert!((a - clamped_cosine_zonal(l) as f64).abs() < 1e-6, "l={l}");
        }
    }

    #[test]
    fn irradiance_closed_form_vs_monte_carlo() {
        // Band-limited radiance (order 4, kept positive) lit onto a few normals.
        let order = 4;
        let mut rng = Rng::new(8, 1);
        let mut coeffs: Vec<Vec3> = (0..sh_count(order))
            .map(|_| Vec3::splat(0.3 * (rng.next_f32() - 0.5)))
            .collect();
        coeffs[0] = Vec3::splat(2.0);
        let e = irradiance_from_radiance(&coeffs);
        // Same through the zonal path.
        let e2 = convolve_zonal(&coeffs, &clamped_cosine_zonal_coeffs(order));
        for (a, b) in e.iter().zip(&e2) {
            assert!((*a - *b).abs().max_element() < 1e-5);
        }
        let n_samples = 1 << 18;
        for normal in random_dirs(6, 3) {
            let mut acc = 0.0f64;
            for i in 0..n_samples {
                let w = square_to_uniform_sphere(crate::warp::hammersley(i, n_samples));
                let c = normal.dot(w).max(0.0) as f64;
                acc += eval_rgb(&coeffs, w).x as f64 * c;
            }
            let mc = acc * 4.0 * std::f64::consts::PI / n_samples as f64;
            let closed = eval_rgb(&e, normal).x as f64;
            // 2^18 Hammersley points on a kink-continuous integrand: error ~1e-4 relative.
            assert!(
                (mc - closed).abs() < 2e-3 * closed,
                "{normal}: {mc} vs {closed}"
            );
        }
    }

    #[test]
    fn window_weights_monotone() {
        for order in [1, 2, 3, 8, 16] {
            for w in [
                Window::None,
                Window::Hann,
                Window::Lanczos,
                Window::Sloan { lambda: 0.01 },
            ] {
                let ws = window_weights(order, w);
                assert_eq!(ws.len(), order);
                assert_eq!(ws[0], 1.0, "{w:?}");
                assert!(ws.windows(2).all(|p| p[1] <= p[0]), "{w:?} {ws:?}");
                assert!(ws.iter().all(|&x| x > 0.0 || order == 1));
            }
        }
        let mut c = vec![Vec3::ONE; 9];
        apply_window(&mut c, 3, Window::Hann);
        assert_eq!(c[0], Vec3::ONE);
        assert!((c[4].x - 0.25).abs() < 1e-6, "{}", c[4]); // (1 + cos(2pi/3)) / 2
    }

    #[test]
    fn windows_parse_or_are_refused() {
        assert_eq!(
            "sloan:0.5".parse::<Window>().unwrap(),
            Window::Sloan { lambda: 0.5 }
        );
        assert_eq!("hann".parse::<Window>().unwrap(), Window::Hann);
        for bad in ["sloan:inf", "sloan:-1", "sloan:", "box"] {
            let e = bad.parse::<Window>().unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
