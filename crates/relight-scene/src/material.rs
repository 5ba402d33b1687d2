//! Materials and their BRDFs.
//!
//! Convention (as Mitsuba 3's `bsdf.h`): `eval(wi, wo)` returns the BRDF **times the cosine**
//! `max(0, cos theta_o)`; `wi` points towards the viewer, `wo` towards the light, both unit and
//! in the local shading frame (normal = +Z of that frame). Materials are one-sided: `eval` and
//! `pdf` are zero when either direction is below the shading horizon. `sample` returns the
//! direction, `eval / pdf` as the weight, and the pdf (solid-angle measure).

use crate::Vec3;
use serde::{Deserialize, Serialize};

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
