//! Decomposition of an environment into a low-order SH part plus a few cap lights: the
//! two-scale model of the hybrid thesis (ch. 4.3, Eq. 4.1), `E ~ P E + sum_j lambda_j phi_j`,
//! with two changes to the thesis' model (caps removed from the SH part, cosine over the
//! cap).
//!
//! # Algorithm (thesis 4.3.3, with the choices made here)
//! 1. **Sample** (4.3.3 "Spherical Function Sampling"). The map's quadrature samples
//!    `(dir_t, w_t, L_t)` ([`EnvMap::texel`], any layout) are the input: their weights are the
//!    texels' exact solid angles, so every integral below is the map's own quadrature and the
//!    energy bookkeeping is exact. The thesis supersamples when it renders its cube maps;
//!    [`cube_supersampled`] does that for procedural environments. Maps with more than
//!    [`MAX_DIRECT_TEXELS`] samples are box-filtered into the bins of a 1-degree icosahedron
//!    (frequency 64) before the smoothing, so its cost does not grow with the map.
//! 2. **Smooth and resample** (4.3.3 "Spherical Function Sampling"): the luminance is convolved
//!    with a spherical Gaussian `K(mu) = exp((mu - 1) / sigma^2)` (`sigma` =
//!    [`DecomposeSettings::kernel_deg`]) at the vertices of a geodesic icosahedron. The
//!    convolution is *culled*: each vertex only visits texels within `3 sigma` (a
//!    precomputed sparse table, the analogue of the thesis' bounding boxes on the cube faces)
//!    and is normalised by the kernel mass it met.
//! 3. **SH part** (4.3.3 "Computing the Spherical Harmonic Expansion", Fig. 4.4): projection
//!    of the texels with their quadrature weights (a precomputed `Y_k(dir_t) w_t` table; the
//!    thesis, too, projects the cube map's texels), then the [`Window`] of the settings. The
//!    SG smoothing is not applied to this part: at `sigma` = 2.5 degrees its band factors
//!    `exp(-l (l + 1) sigma^2 / 2)` are above 0.994 for `l <= 2`, and leaving it out keeps
//!    band 0 equal to the map's integral.
//! 4. **Maxima** (4.3.3 "Computing the SRBF Expansion"): local maxima of the residual
//!    `S(v) - P(v)` (smoothed luminance minus the SH luminance) on the icosahedron. A vertex
//!    whose value beats its whole one-ring is exactly an end point of the thesis' hill
//!    climbing (steepest ascent from every vertex ends at such a vertex, and each is reached
//!    from itself), so the fixed points are tested directly.
//! 5. **Quadric refinement** (same section, the temporal-aliasing fix): the residual on the
//!    one-ring is projected to the tangent plane (gnomonic) and fitted by least squares with
//!    `a + b x + c y + d x^2 + e xy + g y^2`; the cap is centred on the quadric's maximum, so
//!    a rotating environment moves its lights continuously. The light's direction is then the
//!    luminance centroid of the radiance its cap removed (step 6): on the rotation test of the
//!    tests (supersampled cube 6 x 64^2) the centroid stays within 0.05 degrees of the truth,
//!    the quadric maximum within 0.25 degrees.
//! 6. **Power** (4.3.3 "Constructing the Directional Light Approximation"): the thesis gives
//!    a light of fixed cap radius `R` the power `2 pi (1 - cos R) (lambda_i - P(Xi_i))`, i.e.
//!    the residual above the SH part times the cap's solid angle. We integrate that residual
//!    over the cap's texels instead of taking its peak value:
//!    * `remove_caps = false` (thesis): `power = sum_{t in cap} max(L_t - P(dir_t), 0) w_t`,
//!      and the SH part is the projection of the *whole* map: the lights' energy is counted
//!      twice (see [`Decomposition::double_counted`]).
//!    * `remove_caps = true` (default): the background inside the cap is the
//!      per-channel median of the ring `R < angle <= R_rim` around it
//!      (`R_rim = max(1.5 R, R + 2 texel spacings)`; a median ignores a neighbouring light in
//!      the ring); each cap texel gives
//!      `removed_t = max(L_t - B, 0)` to the light and keeps `L_t - removed_t`; the SH part is
//!      the projection of what is left. A texel belongs to at most one light.
//! 7. **Selection** (Fig. 4.5): lights sorted by luminance, descending; a light is kept while
//!    its luminance is more than `threshold` of the running total (the elbow rule), it carries
//!    at least `min_share` of the environment's luminous power, and at most `max_lights`.
//!
//! # What is conserved (`remove_caps = true`)
//! With `I = sum_t L_t w_t` the map's integral (RGB),
//! `I = sqrt(4 pi) sh[0] + sum_i power_i` to f32 rounding (the window keeps band 0). For the
//! irradiance on a normal `n` the lights are uniform caps ([`ExtractedLight::irradiance`], the
//! exact clamped-cosine integral over a cap, horizon included), so
//! [`Decomposition::irradiance`] differs from the map's `sum_t L_t max(0, n.dir_t) w_t` only by
//! the SH truncation of what is left (smooth, since its peaks went to the lights) and by the
//! light's shape inside its cap (a cap of `R` = 5 degrees: `1 - cos R` < 0.4 %). Measured
//! on a sky with two discs (tests, 6 x 64^2 cube, order 3, 64 normals): largest irradiance
//! error 0.3 % of `E(up)` here, 3.7 % for the SH projection alone, 52 % for the thesis'
//! `remove_caps = false` (its lights add their energy a second time).
//!
//! # Example
//! ```
//! use relight_sphere::decompose::{decompose, sky_with_discs, DecomposeSettings};
//! use relight_sphere::Vec3;
//! let sun = Vec3::new(0.3, 0.8, 0.2).normalize();
//! let map = sky_with_discs(32, &[(sun, 2.0, Vec3::splat(300.0))]); // 6 x 32 x 32 cube
//! let d = decompose(&map, &DecomposeSettings::default()).unwrap();
//! assert_eq!(d.lights.len(), 1);
//! assert!(d.lights[0].dir.dot(sun) > 0.9998); // within about a degree
//! // The SH part and the light share the map's energy exactly.
//! assert!(d.double_counted().abs().max_element() < 1e-4 * d.env_integral.max_element());
//! ```

use crate::envmap::EnvMap;
use crate::sh::{self, Window};
use crate::Vec3;
use std::f32::consts::PI;

mod decomposer;
pub use decomposer::{Decomposer, MAX_DIRECT_TEXELS};

/// Parameters of the decomposition (defaults: see [`Default`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecomposeSettings {
    /// SH order of the slowly varying part (`order^2` coefficients); default 3.
    pub sh_order: usize,
    /// Standard deviation `sigma` of the spherical Gaussian smoothing kernel, degrees;
    /// default 2.5.
    pub kernel_deg: f32,
    /// Geodesic frequency of the icosahedron the residual lives on (`10 f^2 + 2` vertices,
    /// spacing about `63.4 / f` degrees); default 24 (5762 vertices, 2.6 degrees).
    pub icosphere_frequency: usize,
    /// Radius `R` of every light's cap, degrees (thesis: a fixed radius); default 5.
    pub light_radius_deg: f32,
    /// Elbow threshold of Fig. 4.5: light `i` is kept while `lum_i / sum_{j <= i} lum_j`
    /// exceeds it; default 0.05.
    pub threshold: f32,
    /// At most this many lights; default 8.
    pub max_lights: usize,
    /// A light must carry at least this fraction of the map's luminous power
    /// `int luminance(L) dw`; default 0.01 (keeps a smooth sky from yielding lights).
    pub min_share: f32,
    /// Window applied to the SH part (thesis: windowing against ringing); default
    /// [`Window::None`], since removing the caps removes what rings.
    pub window: Window,
    /// Subtract each light's cap from the environment before the SH projection (default
    /// `true`); `false` is the thesis' behaviour (the SH part keeps the lights' energy).
    pub remove_caps: bool,
}

impl Default for DecomposeSettings {
    fn default() -> Self {
        DecomposeSettings {
            sh_order: 3,
            kernel_deg: 2.5,
            icosphere_frequency: 24,
            light_radius_deg: 5.0,
            threshold: 0.05,
            max_lights: 8,
            min_share: 0.01,
            window: Window::None,
            remove_caps: true,
        }
    }
}

impl DecomposeSettings {
    /// Checks every field's range.
    ///
    /// # Errors
    /// The first field out of range.
    pub fn validate(&self) -> Result<(), DecomposeSettingsError> {
        use DecomposeSettingsError as E;
        let s = self;
        if !(1..=sh::MAX_ORDER).contains(&s.sh_order) {
            return Err(E::ShOrder(s.sh_order));
        }
        if !(s.kernel_deg > 0.0 && s.kernel_deg <= 30.0) {
            return Err(E::KernelDeg(s.kernel_deg));
        }
        if !(1..=128).contains(&s.icosphere_frequency) {
            return Err(E::IcosphereFrequency(s.icosphere_frequency));
        }
        if !(s.light_radius_deg > 0.0 && s.light_radius_deg <= 45.0) {
            return Err(E::LightRadiusDeg(s.light_radius_deg));
        }
        if !(0.0..=1.0).contains(&s.threshold) {
            return Err(E::Threshold(s.threshold));
        }
        if !(0.0..=1.0).contains(&s.min_share) {
            return Err(E::MinShare(s.min_share));
        }
        if let Window::Sloan { lambda } = s.window {
            if !(lambda >= 0.0 && lambda.is_finite()) {
                return Err(E::SloanLambda(lambda));
            }
        }
        Ok(())
    }

    /// Cap radius `R` in radians.
    pub fn cap_radius(&self) -> f32 {
        self.light_radius_deg.to_radians()
    }

    /// Solid angle of a light's cap, `2 pi (1 - cos R)` (thesis 4.3.3, `D(Xi_i, R)`).
    pub fn cap_solid_angle(&self) -> f32 {
        cap_solid_angle(self.cap_radius())
    }
}

/// Solid angle `2 pi (1 - cos r)` of a spherical cap of angular radius `r`.
#[inline]
pub fn cap_solid_angle(r: f32) -> f32 {
    // 1 - cos r = 2 sin^2(r / 2), without cancellation for small r.
    4.0 * PI * (0.5 * r).sin().powi(2)
}

/// A [`DecomposeSettings`] field out of range ([`DecomposeSettings::validate`]); the message
/// names the field as written in the struct.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum DecomposeSettingsError {
    /// `sh_order` is not in `1..=MAX_ORDER`.
    #[error("sh_order {0} is not in 1..={max}", max = sh::MAX_ORDER)]
    ShOrder(usize),
    /// `kernel_deg` is not in `(0, 30]`.
    #[error("kernel_deg {0} is not in (0, 30]")]
    KernelDeg(f32),
    /// `icosphere_frequency` is not in `1..=128`.
    #[error("icosphere_frequency {0} is not in 1..=128")]
    IcosphereFrequency(usize),
    /// `light_radius_deg` is not in `(0, 45]`.
    #[error("light_radius_deg {0} is not in (0, 45]")]
    LightRadiusDeg(f32),
    /// `threshold` is not in `[0, 1]`.
    #[error("threshold {0} is not in [0, 1]")]
    Threshold(f32),
    /// `min_share` is not in `[0, 1]`.
    #[error("min_share {0} is not in [0, 1]")]
    MinShare(f32),
    /// The `lambda` of a [`Window::Sloan`] is negative or not finite.
    #[error("Sloan window lambda {0} is not finite and >= 0")]
    SloanLambda(f32),
}

/// Why a decomposition failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DecomposeError {
    /// A setting is out of range (its message is part of this one's, so it is not also
    /// reported as the error's source).
    #[error("decomposition settings: {0}")]
    Settings(DecomposeSettingsError),
    /// The map's layout or size differs from the one the [`Decomposer`] was built for.
    #[error("decomposition: {0}")]
    Layout(String),
    /// A texel is NaN, infinite or negative (programmatic maps; files are checked on load).
    #[error("environment pixel {pixel} is {value}: radiance must be finite and >= 0")]
    BadTexel {
        /// Pixel index into [`EnvMap::texels`].
        pixel: usize,
        /// The offending value.
        value: Vec3,
    },
}

/// One light taken out of the environment: a uniform cap of radius `cap_radius` around `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExtractedLight {
    /// Unit direction towards the light (map frame): the luminance centroid (first moment) of
    /// the radiance removed from the cap, so that a cap above the horizon delivers exactly the
    /// removed radiance's irradiance.
    pub dir: Vec3,
    /// The quadric-refined maximum of the smoothed residual (thesis 4.3.3), the cap's centre.
    pub peak: Vec3,
    /// The radiance removed, integrated over the cap, `int_cap removed(w) dw` (RGB): the
    /// thesis' `2 pi (1 - cos R) (lambda_i - P(Xi_i))` summed over the cap's texels. As a
    /// directional light it is the irradiance delivered at normal incidence; as a uniform cap
    /// ([`ExtractedLight::irradiance`]) `power * (1 + cos R) / 2` there.
    pub power: Vec3,
    /// Cap radius `R`, radians.
    pub cap_radius: f32,
    /// Cap solid angle `2 pi (1 - cos R)`, steradians.
    pub solid_angle: f32,
    /// Rec. 709 luminance of `power` (the sort key).
    pub luminance: f32,
    /// Angular radius (radians) of the removed radiance itself, `sqrt(2 E[theta^2])` of its
    /// luminance about `peak` (a uniform disc of radius `rho` gives `rho`), at most
    /// `cap_radius`: the size to give soft shadows.
    pub extent: f32,
}

impl ExtractedLight {
    /// Mean radiance over the cap, `power / solid_angle`.
    pub fn radiance(&self) -> Vec3 {
        self.power / self.solid_angle
    }

    /// Irradiance on a surface of unit normal `n` from the light as a uniform cap (horizon
    /// clipping included): `power * cap_cosine(n . dir, cap_radius)`.
    pub fn irradiance(&self, n: Vec3) -> Vec3 {
        self.power * cap_cosine(n.dot(self.dir), self.cap_radius)
    }
}

/// Mean of `max(0, n . w)` over a uniform cap of radius `r` whose centre makes
/// `cos_alpha = n . centre` with the normal: `(1 + cos r) cos_alpha / 2` when the cap is above
/// the horizon, otherwise the horizon-clipped form factor of a spherical cap (Snyder 1996;
/// Lagarde & de Rousiers 2014, "Moving Frostbite to PBR", eq. 18), divided by the cap's solid
/// angle. Multiply a light's `power` by it to get irradiance (the cosine integrated over
/// the cap instead of taken at its centre).
///
/// # Panics
/// Debug builds assert `0 < r < pi / 2`.
pub fn cap_cosine(cos_alpha: f32, r: f32) -> f32 {
    debug_assert!(r > 0.0 && r < 0.5 * PI);
    let c = cos_alpha.clamp(-1.0, 1.0) as f64;
    let s2 = ((r as f64).sin()).powi(2);
    let e = if c * c > s2 {
        std::f64::consts::PI * s2 * c.max(0.0)
    } else {
        let s = (1.0 - c * c).sqrt();
        let x = (1.0 / s2 - 1.0).sqrt();
        let y = (-x * c / s).clamp(-1.0, 1.0);
        let sy = s * (1.0 - y * y).sqrt();
        ((c * y.acos() - x * sy) * s2 + (sy / x).atan()).max(0.0)
    };
    (e / cap_solid_angle(r) as f64) as f32
}

/// The result: the SH part and the lights.
#[derive(Clone, Debug, PartialEq)]
pub struct Decomposition {
    /// SH coefficients (order `sh_order`, RGB, map frame) of what the lights left: the
    /// lighting of the SH PRT pass.
    pub sh: Vec<Vec3>,
    /// The lights, sorted by luminance, descending.
    pub lights: Vec<ExtractedLight>,
    /// The map's luminous power `int luminance(L) dw` (luminance share of a light =
    /// `light.luminance / total_luminance`).
    pub total_luminance: f32,
    /// The map's integral `int L dw` (RGB).
    pub env_integral: Vec3,
}

impl Decomposition {
    /// Radiance of the decomposition from `dir`: SH part plus the radiance of every cap
    /// containing `dir` (for pictures).
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        let caps = self
            .lights
            .iter()
            .filter(|l| l.dir.dot(dir) >= l.cap_radius.cos());
        sh::eval_rgb(&self.sh, dir) + caps.map(|l| l.radiance()).sum::<Vec3>()
    }

    /// Irradiance on unit normal `n`: the SH part's (R&H 2001 `A_l` convolution) plus every
    /// light's as a uniform cap.
    pub fn irradiance(&self, n: Vec3) -> Vec3 {
        let e = sh::eval_rgb(&sh::irradiance_from_radiance(&self.sh), n);
        e + self.lights.iter().map(|l| l.irradiance(n)).sum::<Vec3>()
    }

    /// `sqrt(4 pi) sh[0] + sum power - env_integral`: zero (to rounding) with
    /// `remove_caps = true`, the lights' energy counted twice with the thesis' `false`.
    pub fn double_counted(&self) -> Vec3 {
        let sh0 = self.sh.first().copied().unwrap_or(Vec3::ZERO) * (4.0 * PI).sqrt();
        sh0 + self.lights.iter().map(|l| l.power).sum::<Vec3>() - self.env_integral
    }
}

/// Decompose `map` with `s` (builds a [`Decomposer`]; build one yourself to decompose many
/// maps of one layout and size, e.g. every frame).
pub fn decompose(map: &EnvMap, s: &DecomposeSettings) -> Result<Decomposition, DecomposeError> {
    Decomposer::new(s, map.layout(), map.width(), map.height())?.run(map)
}

/// The elbow point of Fig. 4.5: the number of leading entries of `lums` (sorted descending)
/// to keep. Entry 0 is kept if positive; entry `i` is kept while
/// `lums[i] / sum_{j <= i} lums[j] > threshold`.
///
/// # Panics
/// Debug builds assert that `lums` is sorted descending.
pub fn elbow(lums: &[f32], threshold: f32) -> usize {
    debug_assert!(
        lums.windows(2).all(|w| w[0] >= w[1]),
        "elbow: unsorted luminances"
    );
    match lums.first() {
        Some(&l0) if l0 > 0.0 => {
            let (mut total, mut n) = (l0, 1);
            while n < lums.len() {
                total += lums[n];
                if lums[n] / total <= threshold {
                    break;
                }
                n += 1;
            }
            n
        }
        _ => 0,
    }
}

/// A sun-and-sky-like test environment as a `6 x n x n` cube map: a sky brighter towards the
/// zenith and a dim ground, plus small bright soft-edged discs `(centre, radius_deg, radiance)`.
pub fn sky_with_discs(n: usize, discs: &[(Vec3, f32, Vec3)]) -> EnvMap {
    EnvMap::cube_from_fn(n, |d| sky_with_discs_fn(d, discs))
}

/// The radiance of [`sky_with_discs`] from `d`: sky `(0.3, 0.5, 0.9) (0.4 + 0.6 y)` above the
/// horizon, ground `0.1` below, plus each disc with a smoothstep edge one degree wide.
pub fn sky_with_discs_fn(d: Vec3, discs: &[(Vec3, f32, Vec3)]) -> Vec3 {
    let sky = if d.y > 0.0 {
        Vec3::new(0.3, 0.5, 0.9) * (0.4 + 0.6 * d.y)
    } else {
        Vec3::splat(0.1)
    };
    sky + discs
        .iter()
        .map(|&(c, r, l)| l * disc_profile(d, c, r))
        .sum::<Vec3>()
}

/// `1` inside a disc of radius `radius_deg` around `c`, `0` outside, smoothstep over one
/// degree across the edge (so point-sampled texels do not alias as the disc moves).
pub fn disc_profile(d: Vec3, c: Vec3, radius_deg: f32) -> f32 {
    let a = d.dot(c).clamp(-1.0, 1.0).acos().to_degrees();
    let t = ((radius_deg + 0.5 - a) / 1.0).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A `6 x n x n` cube map of `f` supersampled as in thesis 4.3.3 ("rendering the faces of the
/// cube map to a larger resolution than the target and applying an averaging box filter"):
/// each texel is the solid-angle-weighted mean of `f` over a `k x k` grid inside it.
///
/// # Panics
/// Debug builds assert `n >= 1` and `k >= 1`.
pub fn cube_supersampled(n: usize, k: usize, f: impl Fn(Vec3) -> Vec3) -> EnvMap {
    debug_assert!(n >= 1 && k >= 1);
    let texels = (0..6 * n * n)
        .map(|i| {
            let (face, row, col) = crate::cubemap::texel_coords(n, i);
            let (mut acc, mut wsum) = (Vec3::ZERO, 0.0f32);
            for a in 0..k {
                for b in 0..k {
                    let s = (col as f32 + (b as f32 + 0.5) / k as f32) / n as f32;
                    let t = (row as f32 + (a as f32 + 0.5) / k as f32) / n as f32;
                    let p = face.plane_point(2.0 * s - 1.0, 2.0 * t - 1.0);
                    // Solid angle per unit face area: 1 / |p|^3.
                    let w = p.length_squared().powf(-1.5);
                    acc += f(p.normalize()) * w;
                    wsum += w;
                }
            }
            acc / wsum
        })
        .collect();
    EnvMap::cube(n, texels)
}

#[cfg(test)]
mod tests;
