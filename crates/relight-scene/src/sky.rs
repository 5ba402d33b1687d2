//! Procedural sun and sky: Preetham, Shirley & Smits (1999), "A Practical Analytic Model for
//! Daylight", SIGGRAPH 99.
//!
//! * **Sky** (upper hemisphere): the Perez et al. (1993) all-weather luminance distribution
//!   (paper Eq. 3) `F(theta, gamma) = (1 + A e^(B / cos theta)) (1 + C e^(D gamma) + E cos^2 gamma)`,
//!   normalised at the zenith, `Y = Y_z F(theta, gamma) / F(0, theta_s)` (Eq. 4), for the
//!   luminance `Y` and the CIE chromaticities `x`, `y`; the coefficients `A..E` are linear in
//!   the turbidity `T` (Appendix A.2, Eq. A.2 / the two 5x2 tables), the zenith luminance is
//!   `Y_z = (4.0453 T - 4.9710) tan chi - 0.2155 T + 2.4192` kcd/m^2 with
//!   `chi = (4/9 - T/120)(pi - 2 theta_s)` and `x_z, y_z` are the cubic-in-`theta_s`,
//!   quadratic-in-`T` fits of Appendix A.2. `xyY` is converted to linear Rec. 709 RGB (D65).
//! * **Sun**: a disc of angular diameter 0.53 degrees whose spectral radiance is the
//!   extraterrestrial solar radiance attenuated along the relative optical mass
//!   `m = 1 / (cos theta_s + 0.15 (93.885 - theta_s[deg])^-1.253)` by Rayleigh scattering,
//!   `tau_R = exp(-0.008735 lambda^-4.08 m)`, and aerosols (Angstrom),
//!   `tau_a = exp(-beta lambda^-1.3 m)`, `beta = 0.04608 T - 0.04586` (`lambda` in um; paper
//!   Appendix A.1). The extraterrestrial spectrum is approximated by a 5778 K black body
//!   (which integrates to the solar constant 1361 W/m^2 at 1 AU), and the paper's tabulated
//!   ozone, mixed-gas and water-vapour absorptions are **omitted** (a few percent in the
//!   visible). The spectrum is integrated against the CIE 1931 colour matching functions in
//!   the analytic fit of Wyman, Sloan & Shirley (2013), JCGT 2(2), times 683 lm/W.
//! * **Ground** (below the horizon): uniform Lambertian radiance
//!   `albedo * E_h / pi`, with `E_h` the irradiance of sky and sun on a horizontal plane.
//!
//! **Absolute scale**: RGB values are luminance-calibrated in **kcd/m^2** (the unit of the
//! paper's `Y_z`): the Rec. 709 luminance of a texel is its luminance in units of
//! 1000 cd/m^2. A clear noon sky has a zenith of a few units and a sun of about 1.5e6.
//!
//! **Sun azimuth** is Mitsuba's latlong `phi` (see `relight_sphere`): the sun direction is
//! `(sin phi cos e, sin e, -cos phi cos e)` for elevation `e`, so azimuth 0 is -Z (the
//! latlong's left edge), 90 degrees is +X, 180 degrees is +Z.
//!
//! The sun is far smaller than a texel, so it is splatted: 32 x 32 sample directions over
//! its disc each deposit `L_sun * dOmega` onto the four texels of their bilinear lookup,
//! divided by each texel's quadrature weight. The map's quadrature then integrates the sun
//! to exactly `L_sun * Omega_sun` (less any part below the horizon, hidden by the ground).

use crate::error::SceneError;
use crate::Vec3;
use relight_sphere::{latlong, EnvMap};
use std::f64::consts::PI;

/// Angular diameter of the sun, degrees.
pub const SUN_DIAMETER_DEG: f64 = 0.53;

/// Parameters of [`Sky`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyParams {
    /// Sun elevation above the horizon, degrees, in `[0, 90]`.
    pub sun_elevation_deg: f32,
    /// Sun azimuth, degrees, as Mitsuba's latlong `phi` (0 = -Z, 90 = +X).
    pub sun_azimuth_deg: f32,
    /// Atmospheric turbidity `T` in `[2, 10]` (2 = very clear, 10 = hazy).
    pub turbidity: f32,
    /// Albedo of the ground, per channel in `[0, 1]`.
    pub ground_albedo: Vec3,
    /// Width of the latlong map rasterised by [`Sky::to_envmap`].
    pub width: usize,
    /// Height of that map.
    pub height: usize,
}

impl Default for SkyParams {
    fn default() -> Self {
        SkyParams {
            sun_elevation_deg: 45.0,
            sun_azimuth_deg: 90.0,
            turbidity: 3.0,
            ground_albedo: Vec3::splat(0.2),
            width: 1024,
            height: 512,
        }
    }
}

impl SkyParams {
    /// Check every parameter is in its documented range (NaN is in no range); the message
    /// names the field.
    pub fn validate(&self) -> Result<(), crate::error::Invalid> {
        self.validate_msg().map_err(crate::error::Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        let p = self;
        if !(0.0..=90.0).contains(&p.sun_elevation_deg) {
            return Err(format!(
                "sun_elevation_deg {} is not in [0, 90]",
                p.sun_elevation_deg
            ));
        }
        if !p.sun_azimuth_deg.is_finite() {
            return Err(format!(
                "sun_azimuth_deg {} is not finite",
                p.sun_azimuth_deg
            ));
        }
        if !(2.0..=10.0).contains(&p.turbidity) {
            return Err(format!("turbidity {} is not in [2, 10]", p.turbidity));
        }
        if !(p.ground_albedo.min_element() >= 0.0 && p.ground_albedo.max_element() <= 1.0) {
            return Err(format!(
                "ground_albedo {} is not in [0, 1]",
                p.ground_albedo
            ));
        }
        if p.width < 4 || p.height < 3 || p.width > 16384 || p.height > 8192 {
            return Err(format!(
                "sky map size {}x{} is not in 4..=16384 x 3..=8192",
                p.width, p.height
            ));
        }
        Ok(())
    }
}

/// A Preetham sun and sky, ready to evaluate (see the module docs).
#[derive(Clone, Debug)]
pub struct Sky {
    params: SkyParams,
    sun_dir: Vec3,
    theta_s: f64,
    /// Perez coefficients `A..E` for `Y`, `x`, `y`.
    perez: [[f64; 5]; 3],
    /// Zenith `Y` (kcd/m^2), `x`, `y`.
    zenith: [f64; 3],
    sun_rgb: Vec3,
}

impl Sky {
    /// Check the parameters ([`SkyParams::validate`]) and precompute the model.
    pub fn new(params: SkyParams) -> Result<Sky, SceneError> {
        params
            .validate()
            .map_err(|msg| SceneError::InvalidParameter { msg: msg.0 })?;
        let p = params;
        let t = p.turbidity as f64;
        let theta_s = (90.0 - p.sun_elevation_deg as f64).to_radians();
        let phi = (p.sun_azimuth_deg as f64).to_radians();
        let sun_dir = Vec3::new(
            (phi.sin() * theta_s.sin()) as f32,
            theta_s.cos() as f32,
            (-phi.cos() * theta_s.sin()) as f32,
        );
        // Appendix A.2: distribution coefficients, linear in T.
        let lin = |c: [[f64; 2]; 5]| c.map(|[a, b]| a * t + b);
        let perez = [
            lin([
                [0.1787, -1.4630],
                [-0.3554, 0.4275],
                [-0.0227, 5.3251],
                [0.1206, -2.5771],
                [-0.0670, 0.3703],
            ]),
            lin([
                [-0.0193, -0.2592],
                [-0.0665, 0.0008],
                [-0.0004, 0.2125],
                [-0.0641, -0.8989],
                [-0.0033, 0.0452],
            ]),
            lin([
                [-0.0167, -0.2608],
                [-0.0950, 0.0092],
                [-0.0079, 0.2102],
                [-0.0441, -1.6537],
                [-0.0109, 0.0529],
            ]),
        ];
        // Zenith luminance (kcd/m^2) and chromaticity.
        let chi = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * theta_s);
        let y_z = (4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192;
        let poly = |m: [[f64; 4]; 3]| {
            let th = [theta_s.powi(3), theta_s.powi(2), theta_s, 1.0];
            let tt = [t * t, t, 1.0];
            (0..3)
                .map(|i| tt[i] * (0..4).map(|j| m[i][j] * th[j]).sum::<f64>())
                .sum::<f64>()
        };
        let x_z = poly([
            [0.00166, -0.00375, 0.00209, 0.0],
            [-0.02903, 0.06377, -0.03202, 0.00394],
            [0.11693, -0.21196, 0.06052, 0.25886],
        ]);
        let yc_z = poly([
            [0.00275, -0.00610, 0.00317, 0.0],
            [-0.04214, 0.08970, -0.04153, 0.00516],
            [0.15346, -0.26756, 0.06670, 0.26688],
        ]);
        let sun_rgb = xyz_to_rgb(sun_xyz(theta_s, t));
        Ok(Sky {
            params: p,
            sun_dir,
            theta_s,
            perez,
            zenith: [y_z.max(0.0), x_z, yc_z],
            sun_rgb,
        })
    }

    /// Unit direction towards the sun's centre.
    pub fn sun_direction(&self) -> Vec3 {
        self.sun_dir
    }

    /// RGB radiance of the sun disc (kcd/m^2 luminance scale).
    pub fn sun_radiance(&self) -> Vec3 {
        self.sun_rgb
    }

    /// Solid angle of the sun disc, steradians.
    pub fn sun_solid_angle() -> f64 {
        2.0 * PI * (1.0 - (0.5 * SUN_DIAMETER_DEG).to_radians().cos())
    }

    /// Sky radiance (without the sun) from unit direction `dir` with `dir.y >= 0`; for
    /// `dir.y < 0` the sky at the horizon in that azimuth.
    pub fn sky_radiance(&self, dir: Vec3) -> Vec3 {
        let cos_theta = (dir.y as f64).max(1e-3); // Perez's e^(B / cos theta) is singular at the horizon
        let theta = cos_theta.acos();
        let gamma = (dir.dot(self.sun_dir) as f64).clamp(-1.0, 1.0).acos();
        let perez = |c: &[f64; 5], theta: f64, gamma: f64| {
            (1.0 + c[0] * (c[1] / theta.cos().max(1e-3)).exp())
                * (1.0 + c[2] * (c[3] * gamma).exp() + c[4] * gamma.cos().powi(2))
        };
        let v: [f64; 3] = std::array::from_fn(|k| {
            self.zenith[k] * perez(&self.perez[k], theta, gamma)
                / perez(&self.perez[k], 0.0, self.theta_s)
        });
        let (big_y, x, y) = (v[0].max(0.0), v[1], v[2].max(1e-6));
        let xyz = [x * big_y / y, big_y, (1.0 - x - y) * big_y / y];
        xyz_to_rgb(xyz).max(Vec3::ZERO)
    }

    /// Rasterise sky, sun and ground to a latlong [`EnvMap`] of the parameters' size.
    pub fn to_envmap(&self) -> EnvMap {
        let (w, h) = (self.params.width, self.params.height);
        let mut texels = vec![Vec3::ZERO; w * h];
        let mut e_rgb = [0.0f64; 3]; // horizontal irradiance from the sky
        for row in 0..h {
            let weight = latlong::row_weight(w, h, row);
            for col in 0..w {
                let d = latlong::texel_dir(w, h, col, row);
                if d.y > 0.0 {
                    let l = self.sky_radiance(d);
                    texels[row * w + col] = l;
                    for k in 0..3 {
                        e_rgb[k] += (l[k] as f64) * weight * d.y as f64;
                    }
                }
            }
        }
        let visible = splat_sun(&mut texels, w, h, self.sun_dir, self.sun_rgb, 32);
        let sun_e = visible * self.theta_s.cos();
        let e_h: [f64; 3] = std::array::from_fn(|k| e_rgb[k] + self.sun_rgb[k] as f64 * sun_e);
        let ground = Vec3::new(
            (e_h[0] / PI) as f32,
            (e_h[1] / PI) as f32,
            (e_h[2] / PI) as f32,
        ) * self.params.ground_albedo;
        for row in 0..h {
            for col in 0..w {
                if latlong::texel_dir(w, h, col, row).y <= 0.0 {
                    texels[row * w + col] += ground;
                }
            }
        }
        EnvMap::latlong(w, h, texels)
    }
}

/// Convenience: [`Sky::new`] then [`Sky::to_envmap`].
pub fn sun_sky_envmap(params: SkyParams) -> Result<EnvMap, SceneError> {
    Ok(Sky::new(params)?.to_envmap())
}

/// Splat a disc of radiance `l` and angular diameter [`SUN_DIAMETER_DEG`] centred on `dir`
/// into a `w x h` latlong map, `n x n` samples (polar grid, equal solid angle), conserving
/// `sum(texel * weight) = l * (visible solid angle)`. Samples below the horizon are dropped.
/// Returns the visible solid angle.
pub fn splat_sun(texels: &mut [Vec3], w: usize, h: usize, dir: Vec3, l: Vec3, n: usize) -> f64 {
    let omega = Sky::sun_solid_angle();
    let cos_max = (0.5 * SUN_DIAMETER_DEG).to_radians().cos();
    // Frame around the sun direction.
    let up = if dir.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
    let t1 = up.cross(dir).normalize();
    let t2 = dir.cross(t1);
    let d_omega = omega / (n * n) as f64;
    let mut visible = 0.0;
    for i in 0..n {
        // Equal solid-angle rings: cos(angle) uniform in [cos_max, 1].
        let c = 1.0 - (1.0 - cos_max) * (i as f64 + 0.5) / n as f64;
        let s = (1.0 - c * c).sqrt();
        for j in 0..n {
            let a = 2.0 * PI * (j as f64 + 0.5 * (i % 2) as f64) / n as f64;
            let q = (dir * c as f32 + (t1 * a.cos() as f32 + t2 * a.sin() as f32) * s as f32)
                .normalize();
            if q.y < 0.0 {
                continue;
            }
            visible += d_omega;
            for (k, b) in latlong::bilinear(w, h, q) {
                let row = k / w;
                texels[k] += l * (b as f64 * d_omega / latlong::row_weight(w, h, row)) as f32;
            }
        }
    }
    visible
}

/// CIE XYZ (kcd/m^2) of the attenuated sun (module docs), for sun zenith angle `theta_s`.
fn sun_xyz(theta_s: f64, t: f64) -> [f64; 3] {
    let m = 1.0 / (theta_s.cos() + 0.15 * (93.885 - theta_s.to_degrees()).powf(-1.253));
    let beta = 0.04608365822050 * t - 0.04586025928522;
    let mut xyz = [0.0; 3];
    let step = 5.0; // nm
    let mut lambda_nm: f64 = 360.0;
    while lambda_nm <= 830.0 {
        let um = lambda_nm * 1e-3;
        let tau = (-0.008735 * um.powf(-4.08) * m).exp() * (-beta * um.powf(-1.3) * m).exp();
        let l = planck(lambda_nm * 1e-9, 5778.0) * 1e-9 * tau; // W / (m^2 sr nm)
        let cmf = cie_xyz(lambda_nm);
        for k in 0..3 {
            xyz[k] += 683.0 * l * cmf[k] * step / 1000.0; // kcd / m^2
        }
        lambda_nm += step;
    }
    xyz
}

/// Black-body spectral radiance, W / (m^2 sr m), wavelength in metres.
fn planck(lambda: f64, temp: f64) -> f64 {
    const H: f64 = 6.626_070_15e-34;
    const C: f64 = 2.997_924_58e8;
    const K: f64 = 1.380_649e-23;
    2.0 * H * C * C / lambda.powi(5) / ((H * C / (lambda * K * temp)).exp() - 1.0)
}

/// CIE 1931 2-degree colour matching functions, multi-lobe fit of Wyman, Sloan & Shirley
/// (2013), Eq. 2 and Table 1.
pub(crate) fn cie_xyz(lambda_nm: f64) -> [f64; 3] {
    let g = |mu: f64, s1: f64, s2: f64| {
        let s = if lambda_nm < mu { s1 } else { s2 };
        (-0.5 * ((lambda_nm - mu) / s).powi(2)).exp()
    };
    [
        1.056 * g(599.8, 37.9, 31.0) + 0.362 * g(442.0, 16.0, 26.7) - 0.065 * g(501.1, 20.4, 26.2),
        0.821 * g(568.8, 46.9, 40.5) + 0.286 * g(530.9, 16.3, 31.1),
        1.217 * g(437.0, 11.8, 36.0) + 0.681 * g(459.0, 26.0, 13.8),
    ]
}

/// CIE XYZ to linear Rec. 709 RGB (D65 white), IEC 61966-2-1.
fn xyz_to_rgb(c: [f64; 3]) -> Vec3 {
    let [x, y, z] = c;
    Vec3::new(
        (3.2404542 * x - 1.5371385 * y - 0.4985314 * z) as f32,
        (-0.9692660 * x + 1.8760108 * y + 0.0415560 * z) as f32,
        (0.0556434 * x - 0.2040259 * y + 1.0572252 * z) as f32,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sky(elev: f32, t: f32) -> Sky {
        Sky::new(SkyParams {
            sun_elevation_deg: elev,
            turbidity: t,
            width: 256,
            height: 128,
            ..Default::default()
        })
        .unwrap()
    }

    fn lum(c: Vec3) -> f64 {
        relight_sphere::luminance(c) as f64
    }

    #[test]
    fn cmf_fit_integrates_like_cie_1931() {
        // The CIE 1931 functions each integrate to ~106.86 over 360-830 nm (equal-energy
        // white has x = y = 1/3); the fit's published max error is a few percent per sample.
        let mut s = [0.0; 3];
        for l in 360..=830 {
            let c = cie_xyz(l as f64);
            (0..3).for_each(|k| s[k] += c[k]);
        }
        for v in s {
            assert!((v / 106.86 - 1.0).abs() < 0.02, "{s:?}");
        }
    }

    #[test]
    fn parameters_are_checked() {
        for p in [
            SkyParams {
                turbidity: 1.0,
                ..Default::default()
            },
            SkyParams {
                turbidity: 11.0,
                ..Default::default()
            },
            SkyParams {
                sun_elevation_deg: -5.0,
                ..Default::default()
            },
            SkyParams {
                ground_albedo: Vec3::splat(1.5),
                ..Default::default()
            },
            SkyParams {
                width: 0,
                ..Default::default()
            },
        ] {
            assert!(
                matches!(Sky::new(p), Err(SceneError::InvalidParameter { .. })),
                "{p:?}"
            );
        }
    }

    #[test]
    fn sun_direction_follows_mitsuba_azimuth() {
        let s = Sky::new(SkyParams {
            sun_elevation_deg: 0.0,
            sun_azimuth_deg: 90.0,
            ..Default::default()
        })
        .unwrap();
        assert!((s.sun_direction() - Vec3::X).length() < 1e-6);
        let s = Sky::new(SkyParams {
            sun_elevation_deg: 30.0,
            sun_azimuth_deg: 0.0,
            ..Default::default()
        })
        .unwrap();
        let d = s.sun_direction();
        assert!((d - Vec3::new(0.0, 0.5, -(0.75f32).sqrt())).length() < 1e-6);
        // It lands in the latlong at u = phi / 2pi = 0, v = 60/180.
        let uv = latlong::dir_to_uv(d);
        assert!((uv.x.min(1.0 - uv.x)) < 1e-6 && (uv.y - 1.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn zenith_luminance_is_the_papers() {
        // Y_z = (4.0453 T - 4.9710) tan chi - 0.2155 T + 2.4192, chi = (4/9 - T/120)(pi - 2 theta_s).
        let (t, theta_s) = (3.0f64, 45f64.to_radians());
        let chi = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * theta_s);
        let yz = (4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192;
        let l = lum(sky(45.0, 3.0).sky_radiance(Vec3::Y));
        // Rec. 709 luminance of the RGB equals Y up to the matrices' 7-digit rounding.
        assert!((l / yz - 1.0).abs() < 1e-4, "{l} vs {yz}");
    }

    #[test]
    fn sky_is_symmetric_about_the_solar_meridian_and_brightest_near_the_sun() {
        let s = sky(30.0, 3.0);
        let sun = s.sun_direction();
        for d in [
            Vec3::new(0.3, 0.4, 0.5),
            Vec3::new(-0.7, 0.2, 0.1),
            Vec3::new(0.1, 0.9, -0.3),
        ] {
            let d = d.normalize();
            // Mirror about the vertical plane containing the sun (azimuth 90 deg: the x-y plane).
            let m = Vec3::new(d.x, d.y, -d.z);
            assert!(
                (s.sky_radiance(d) - s.sky_radiance(m)).length()
                    <= 1e-5 * s.sky_radiance(d).length()
            );
        }
        let near = (sun + Vec3::Y * 0.05).normalize();
        let anti = Vec3::new(-sun.x, sun.y, -sun.z);
        assert!(lum(s.sky_radiance(near)) > 3.0 * lum(s.sky_radiance(anti)));
    }

    #[test]
    fn sun_is_plausibly_bright_and_reddens_at_low_elevation() {
        // Direct normal illuminance of a clear noon sun is about 100 klux; our model omits
        // ozone and water vapour, so allow 90..135 klux.
        let high = sky(90.0, 2.0);
        let e_n = lum(high.sun_radiance()) * Sky::sun_solid_angle();
        assert!((90.0..135.0).contains(&e_n), "{e_n} klux");
        let low = sky(5.0, 2.0);
        let (h, l) = (high.sun_radiance(), low.sun_radiance());
        assert!(lum(l) < 0.5 * lum(h));
        assert!(l.x / l.z > 1.5 * h.x / h.z, "{h} vs {l}");
        // More haze, less direct sun.
        assert!(lum(sky(90.0, 8.0).sun_radiance()) < 0.8 * lum(h));
    }

    #[test]
    fn sun_splat_conserves_energy() {
        let (w, h) = (128, 64);
        for dir in [
            Vec3::new(0.3, 0.5, -0.8),
            Vec3::Y,
            Vec3::new(0.0, 0.999, 0.04),
            Vec3::new(1.0, 0.2, 0.0),
        ] {
            let dir = dir.normalize();
            let mut t = vec![Vec3::ZERO; w * h];
            let vis = splat_sun(&mut t, w, h, dir, Vec3::ONE, 32);
            assert!((vis / Sky::sun_solid_angle() - 1.0).abs() < 1e-9);
            let total: f64 = t
                .iter()
                .enumerate()
                .map(|(i, v)| v.x as f64 * latlong::row_weight(w, h, i / w))
                .sum();
            // f32 accumulation: 1e-5 relative.
            assert!((total / vis - 1.0).abs() < 1e-5, "{dir}: {total} vs {vis}");
        }
        // A sun on the horizon is half hidden by the ground.
        let mut t = vec![Vec3::ZERO; w * h];
        let vis = splat_sun(&mut t, w, h, Vec3::X, Vec3::ONE, 32);
        assert!((vis / Sky::sun_solid_angle() - 0.5).abs() < 0.05);
    }

    #[test]
    fn ground_is_albedo_times_horizontal_irradiance_over_pi() {
        let p = SkyParams {
            sun_elevation_deg: 40.0,
            ground_albedo: Vec3::new(0.1, 0.3, 0.5),
            width: 512,
            height: 256,
            ..Default::default()
        };
        let s = Sky::new(p).unwrap();
        let map = s.to_envmap();
        // Independent horizontal irradiance: sky by a fine quasi-Monte Carlo integral over the
        // upper hemisphere (cosine-weighted Fibonacci points), sun analytically.
        let n = 200_000;
        let mut e = Vec3::ZERO;
        for i in 0..n {
            let r2 = (i as f32 + 0.5) / n as f32;
            let a = i as f32 * 2.399_963;
            let d = Vec3::new(r2.sqrt() * a.cos(), (1.0 - r2).sqrt(), r2.sqrt() * a.sin());
            e += s.sky_radiance(d) * (std::f32::consts::PI / n as f32);
        }
        e += s.sun_radiance() * (Sky::sun_solid_angle() as f32 * s.sun_direction().y);
        let expect = p.ground_albedo * e / std::f32::consts::PI;
        let got = map.eval(-Vec3::Y);
        // The map integrates the sky at its 512x256 texel centres (bilinear tents in theta):
        // ~1 % from the horizon band, where the point-sampled sky is brightest.
        assert!(
            ((got - expect) / expect).abs().max_element() < 0.02,
            "{got} vs {expect}"
        );
    }
}
