//! Materials and their BRDFs.
//!
//! Convention (as Mitsuba 3's `bsdf.h`): `eval(wi, wo)` returns the BRDF **times the cosine**
//! `max(0, cos theta_o)`; `wi` points towards the viewer, `wo` towards the light, both unit and
//! in the local shading frame (normal = +Z of that frame). Materials are one-sided: `eval` and
//! `pdf` are zero when either direction is below the shading horizon. `sample` returns the
//! direction, `eval / pdf` as the weight, and the pdf (solid-angle measure).
//!
//! Models (Mitsuba 3 has no Phong; the GGX ones reproduce Mitsuba 3.9's plugins, see the
//! probed values in the tests):
//! * `Lambert`: `albedo/pi cos_o`; cosine sampling.
//! * `BlinnPhong`: `(diffuse/pi + specular (n+8)/(8pi) cos^n theta_h) cos_o`; sampled by mixing
//!   a cosine lobe and a `cos^n theta_h` half-vector lobe, weighted by the mean reflectances.
//! * `GgxConductor` = `roughconductor` (ggx, `sample_visible = true`, `material = "none"`):
//!   `specular D(h) G1(wi) G1(wo) / (4 cos_i)` (Walter et al. 2007), visible-normal sampling
//!   (Heitz 2018).
//! * `GgxPlastic` = `roughplastic` (ggx, `nonlinear = false`, `ext_ior = 1`):
//!   `specular F(wi.h, eta) D G / (4 cos_i) + diffuse / (1 - Fdr) / eta^2 cos_o/pi t(cos_i) t(cos_o)`
//!   with `t` the energy transmitted by the rough interface and `Fdr` its internal
//!   cosine-weighted reflectance (both by quadrature, cached per `(alpha, eta)`; see
//!   [`microfacet::PlasticTables`]); specular vs diffuse sampling as Mitsuba's
//!   `specular_sampling_weight`.

#[path = "microfacet.rs"]
pub mod microfacet;

use crate::Vec3;
use glam::Vec2;
use microfacet::{self as mf, PlasticTables};
use serde::{Deserialize, Serialize};
use std::f32::consts::{FRAC_1_PI, PI};

/// A surface material. A closed set: every method matches it exhaustively.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Material {
    /// Lambertian diffuse (Mitsuba `diffuse`, `reflectance = albedo`).
    Lambert {
        /// Diffuse reflectance in [0, 1] per channel.
        albedo: Vec3,
    },
    /// Normalised Blinn-Phong: `diffuse/pi + specular (n+8)/(8 pi) cos^n theta_h`.
    BlinnPhong {
        /// Diffuse reflectance.
        diffuse: Vec3,
        /// Specular reflectance.
        specular: Vec3,
        /// Blinn-Phong exponent `n` (> 0).
        exponent: f32,
    },
    /// GGX microfacet conductor with Fresnel = `specular` (Mitsuba `roughconductor`,
    /// `distribution = "ggx"`, `material = "none"`, `specular_reflectance = specular`).
    GgxConductor {
        /// Specular reflectance (Fresnel replaced by this constant).
        specular: Vec3,
        /// GGX roughness `alpha` (Mitsuba's `alpha`, not squared).
        alpha: f32,
    },
    /// GGX microfacet dielectric coating over a diffuse base (Mitsuba `roughplastic`,
    /// `distribution = "ggx"`, `nonlinear = false`).
    GgxPlastic {
        /// Diffuse reflectance of the base.
        diffuse: Vec3,
        /// Specular reflectance factor of the coating.
        specular: Vec3,
        /// GGX roughness `alpha`.
        alpha: f32,
        /// Interior index of refraction (Mitsuba's default 1.49).
        ior: f32,
    },
}

impl Default for Material {
    fn default() -> Self {
        Material::Lambert { albedo: Vec3::splat(0.8) }
    }
}

/// A sampled direction of a BSDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled direction towards the light (local frame, unit).
    pub wo: Vec3,
    /// `eval(wi, wo) / pdf(wi, wo)` (cosine included).
    pub weight: Vec3,
    /// Density of `wo` in solid angle (the full mixture density, as [`Material::pdf`]).
    pub pdf: f32,
}

/// Cosine-weighted hemisphere sample (Malley's method), pdf `cos theta / pi`.
#[inline]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt())
}

/// Density of [`sample_cosine_hemisphere`].
#[inline]
pub fn cosine_hemisphere_pdf(w: Vec3) -> f32 {
    w.z.max(0.0) * FRAC_1_PI
}

/// Sample a Blinn-Phong half vector, density `(n + 1)/(2 pi) cos^n theta_h` (solid angle).
#[inline]
fn sample_phong_half(n: f32, u: Vec2) -> Vec3 {
    let c = u.x.powf(1.0 / (n + 1.0));
    let s = (1.0 - c * c).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(s * phi.cos(), s * phi.sin(), c)
}

/// Density of `wo` when its half vector follows [`sample_phong_half`] (Jacobian `1/(4 wo.h)`).
#[inline]
fn phong_half_pdf(n: f32, wi: Vec3, wo: Vec3) -> f32 {
    let h = (wi + wo).normalize_or_zero();
    let c = h.z;
    let d = wo.dot(h);
    if c <= 0.0 || d <= 0.0 {
        return 0.0;
    }
    (n + 1.0) * 0.5 * FRAC_1_PI * c.powf(n) / (4.0 * d)
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) / 3.0
}

/// Power heuristic with exponent 2 (Veach 1997, eq. 9.13) for a sample drawn from the
/// strategy of density `pdf_a`, the other strategy having density `pdf_b`.
#[inline]
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b > 0.0 && a.is_finite() {
        a / (a + b)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

impl Material {
    /// The BSDF times `max(0, cos theta_o)`: `f(wi, wo) cos theta_o` (see the module docs).
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let (ci, co) = (wi.z, wo.z);
        if ci <= 0.0 || co <= 0.0 {
            return Vec3::ZERO;
        }
        match *self {
            Material::Lambert { albedo } => albedo * (FRAC_1_PI * co),
            Material::BlinnPhong { diffuse, specular, exponent } => {
                let h = (wi + wo).normalize();
                let lobe = (exponent + 8.0) * (FRAC_1_PI / 8.0) * h.z.max(0.0).powf(exponent);
                (diffuse * FRAC_1_PI + specular * lobe) * co
            }
            Material::GgxConductor { specular, alpha } => {
                let h = (wi + wo).normalize();
                let g = mf::smith_g1(wi, h, alpha) * mf::smith_g1(wo, h, alpha);
                specular * (mf::ggx_d(h, alpha) * g / (4.0 * ci))
            }
            Material::GgxPlastic { diffuse, specular, alpha, ior } => {
                let t = PlasticTables::get(alpha, ior);
                let h = (wi + wo).normalize();
                let g = mf::smith_g1(wi, h, alpha) * mf::smith_g1(wo, h, alpha);
                let f = mf::fresnel_dielectric(wi.dot(h), ior);
                let spec = specular * (f * mf::ggx_d(h, alpha) * g / (4.0 * ci));
                let diff = diffuse / (1.0 - t.internal_reflectance)
                    * (FRAC_1_PI / (ior * ior) * co * t.transmittance(ci) * t.transmittance(co));
                spec + diff
            }
        }
    }

    /// Solid-angle density with which [`Material::sample`] produces `wo` given `wi`.
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let (ci, co) = (wi.z, wo.z);
        if ci <= 0.0 || co <= 0.0 {
            return 0.0;
        }
        match *self {
            Material::Lambert { .. } => cosine_hemisphere_pdf(wo),
            Material::BlinnPhong { diffuse, specular, exponent } => {
                let ps = blinn_specular_probability(diffuse, specular);
                ps * phong_half_pdf(exponent, wi, wo) + (1.0 - ps) * cosine_hemisphere_pdf(wo)
            }
            Material::GgxConductor { alpha, .. } => {
                let h = (wi + wo).normalize();
                if wo.dot(h) <= 0.0 {
                    return 0.0;
                }
                mf::visible_normal_pdf(wi, h, alpha) / (4.0 * wo.dot(h))
            }
            Material::GgxPlastic { diffuse, specular, alpha, ior } => {
                let ps = plastic_specular_probability(diffuse, specular, alpha, ior, ci);
                let h = (wi + wo).normalize();
                let spec = if wo.dot(h) > 0.0 {
                    mf::visible_normal_pdf(wi, h, alpha) / (4.0 * wo.dot(h))
                } else {
                    0.0
                };
                ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wo)
            }
        }
    }

    /// Importance-sample `wo` given `wi`: `u` drives the lobe's 2D warp, `u_lobe` the choice of
    /// lobe in mixtures. `None` when `wi` is below the horizon or the sample falls below it.
    pub fn sample(&self, wi: Vec3, u: Vec2, u_lobe: f32) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let wo = match *self {
            Material::Lambert { albedo } => {
                let wo = sample_cosine_hemisphere(u);
                if wo.z <= 0.0 {
                    return None;
                }
                // eval / pdf = albedo exactly; skip the division.
                return Some(BsdfSample { wo, weight: albedo, pdf: cosine_hemisphere_pdf(wo) });
            }
            Material::BlinnPhong { diffuse, specular, exponent } => {
                if u_lobe < blinn_specular_probability(diffuse, specular) {
                    mf::reflect(wi, sample_phong_half(exponent, u))
                } else {
                    sample_cosine_hemisphere(u)
                }
            }
            Material::GgxConductor { specular, alpha } => {
                let m = mf::sample_visible_normal(wi, alpha, u);
                let wo = mf::reflect(wi, m);
                if wo.z <= 0.0 {
                    return None;
                }
                // eval / pdf = F G1(wo, m) for visible-normal sampling (Heitz 2018, eq. 19).
                let pdf = self.pdf(wi, wo);
                let weight = specular * mf::smith_g1(wo, m, alpha);
                return (pdf > 0.0).then_some(BsdfSample { wo, weight, pdf });
            }
            Material::GgxPlastic { diffuse, specular, alpha, ior } => {
                if u_lobe < plastic_specular_probability(diffuse, specular, alpha, ior, wi.z) {
                    mf::reflect(wi, mf::sample_visible_normal(wi, alpha, u))
                } else {
                    sample_cosine_hemisphere(u)
                }
            }
        };
        if wo.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wi, wo);
        if !(pdf > 0.0) {
            return None;
        }
        Some(BsdfSample { wo, weight: self.eval(wi, wo) / pdf, pdf })
    }

    /// Diffuse (view-independent) reflectance, used by the SH bake for interreflections:
    /// Lambert `albedo`, Blinn-Phong `diffuse`, GGX conductor zero, GGX plastic the
    /// cosine-weighted hemispherical average of its diffuse lobe's albedo,
    /// `diffuse / (1 - Fdr) / eta^2 * tbar^2` with `tbar = 2 ∫ t(mu) mu dmu`.
    pub fn diffuse_albedo(&self) -> Vec3 {
        match *self {
            Material::Lambert { albedo } => albedo,
            Material::BlinnPhong { diffuse, .. } => diffuse,
            Material::GgxConductor { .. } => Vec3::ZERO,
            Material::GgxPlastic { diffuse, alpha, ior, .. } => {
                let t = PlasticTables::get(alpha, ior);
                diffuse / (1.0 - t.internal_reflectance) / (ior * ior)
                    * (t.mean_transmittance * t.mean_transmittance)
            }
        }
    }

    /// Whether the material is purely Lambertian (no view-dependent lobe).
    pub fn is_diffuse_only(&self) -> bool {
        match *self {
            Material::Lambert { .. } => true,
            Material::BlinnPhong { specular, .. } => specular == Vec3::ZERO,
            Material::GgxConductor { .. } | Material::GgxPlastic { .. } => false,
        }
    }

    /// Check parameter ranges: reflectances finite in `[0, 1]` (Blinn-Phong: `diffuse +
    /// specular <= 1` per channel), exponent finite and `> 0`, `alpha` in `[1e-4, 2]`, `ior`
    /// in `(1, 4]`.
    pub fn validate(&self) -> Result<(), String> {
        fn refl(name: &str, v: Vec3) -> Result<(), String> {
            if !v.is_finite() || v.min_element() < 0.0 || v.max_element() > 1.0 {
                return Err(format!("{name} {v} must be finite and in [0, 1]"));
            }
            Ok(())
        }
        fn rough(alpha: f32) -> Result<(), String> {
            if !(mf::MIN_ALPHA..=2.0).contains(&alpha) {
                return Err(format!("GGX alpha {alpha} must be in [1e-4, 2]"));
            }
            Ok(())
        }
        match *self {
            Material::Lambert { albedo } => refl("albedo", albedo),
            Material::BlinnPhong { diffuse, specular, exponent } => {
                refl("diffuse", diffuse)?;
                refl("specular", specular)?;
                if (diffuse + specular).max_element() > 1.0 + 1e-6 {
                    return Err(format!("diffuse + specular {} exceeds 1", diffuse + specular));
                }
                if !(exponent.is_finite() && exponent > 0.0) {
                    return Err(format!("Blinn-Phong exponent {exponent} must be finite and > 0"));
                }
                Ok(())
            }
            Material::GgxConductor { specular, alpha } => {
                refl("specular", specular)?;
                rough(alpha)
            }
            Material::GgxPlastic { diffuse, specular, alpha, ior } => {
                refl("diffuse", diffuse)?;
                refl("specular", specular)?;
                rough(alpha)?;
                if !(ior > 1.0 && ior <= 4.0) {
                    return Err(format!("plastic ior {ior} must be in (1, 4]"));
                }
                Ok(())
            }
        }
    }
}

/// Probability of sampling the Blinn-Phong specular lobe: mean specular over mean total.
#[inline]
fn blinn_specular_probability(diffuse: Vec3, specular: Vec3) -> f32 {
    let (d, s) = (mean(diffuse), mean(specular));
    if d + s > 0.0 {
        s / (d + s)
    } else {
        0.0
    }
}

/// Mitsuba 3 `roughplastic`'s probability of sampling the specular lobe:
/// `w = s/(s + d)` (means of the reflectances), then `(1 - t_i) w` against `t_i (1 - w)`.
#[inline]
fn plastic_specular_probability(diffuse: Vec3, specular: Vec3, alpha: f32, ior: f32, cos_i: f32) -> f32 {
    let (d, s) = (mean(diffuse), mean(specular));
    if d + s <= 0.0 {
        return 0.0;
    }
    let w = s / (d + s);
    let t_i = PlasticTables::get(alpha, ior).transmittance(cos_i);
    let ps = (1.0 - t_i) * w;
    let pd = t_i * (1.0 - w);
    if ps + pd > 0.0 {
        ps / (ps + pd)
    } else {
        0.0
    }
}
