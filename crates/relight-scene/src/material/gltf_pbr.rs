//! The glTF 2.0 metallic-roughness BRDF (glTF 2.0 specification, Appendix B, "BRDF
//! Implementation"), in the local shading frame (normal = +Z), cosine included as
//! [`super::Material::eval`].
//!
//! With `V = wi` (towards the viewer), `L = wo` (towards the light), `H = normalize(V + L)`:
//! * `alpha = roughness^2` (B.3.1), raised to at least [`MIN_ALPHA`];
//! * `D(H) = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2)` (B.3.2, Trowbridge-Reitz / GGX);
//! * `V_GGX = 1 / (2 (|N.L| sqrt(alpha^2 + (1 - alpha^2) (N.V)^2) + |N.V| sqrt(alpha^2 +
//!   (1 - alpha^2) (N.L)^2)))`, the height-correlated Smith visibility `G2 / (4 |N.L| |N.V|)`
//!   (B.3.2; Heitz 2014, "Understanding the Masking-Shadowing Function", eq. 99), zero
//!   unless `H.L > 0` and `H.V > 0`;
//! * `specular_brdf = V_GGX D` (B.3.2);
//! * `diffuse_brdf(c) = c / pi` (B.3.3);
//! * `F_schlick(f0, |V.H|) = f0 + (1 - f0) (1 - |V.H|)^5` (B.3.4);
//! * `dielectric = mix(diffuse_brdf(base), specular_brdf, F_schlick(0.04, |V.H|))`
//!   `= (1 - F) base / pi + F specular_brdf` (B.3.5, "fresnel_mix" with `ior = 1.5`);
//! * `metal = specular_brdf F_schlick(base, |V.H|)` (B.3.5, "conductor_fresnel");
//! * `material = mix(dielectric, metal, metallic)` (B.3.5).
//!
//! The result is split into two lobes whose sum is the BRDF (times `cos theta_o`): the
//! **glossy** lobe, every `specular_brdf` term, `[(1 - m) F(0.04) + m F(base)] V_GGX D`, and the
//! **diffuse** lobe `(1 - m) (1 - F(0.04)) base / pi`. The diffuse lobe depends on the view
//! through `F(|V.H|)`: it is not the product of a view factor and a light factor.
//!
//! Sampling mixes a cosine lobe and the GGX visible normals of `wi` (Heitz 2018) reflected
//! about `wi`, chosen with [`specular_probability`] (mean Fresnel at normal incidence against
//! the mean diffuse reflectance).

use super::microfacet as mf;
use crate::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// Smallest `alpha = roughness^2` used (a roughness of 0 is evaluated at this `alpha`).
pub const MIN_ALPHA: f32 = 1e-3;

/// glTF's dielectric reflectance at normal incidence (`ior = 1.5`: `((1.5 - 1) / (1.5 + 1))^2`).
pub const DIELECTRIC_F0: f32 = 0.04;

/// The cosine-weighted mean over both directions of the dielectric diffuse lobe's Fresnel
/// factor, `(1/pi^2) ∫∫ (1 - F_schlick(0.04, V.H)) cos_i cos_o dwi dwo` (checked by quadrature
/// in the tests): the diffuse lobe's hemispherical albedo is `(1 - metallic) base` times this.
pub const MEAN_DIFFUSE_TRANSMISSION: f32 = 0.956_464;

/// `alpha` of a glTF `roughness` (`roughness^2`, at least [`MIN_ALPHA`]).
#[inline]
pub fn alpha(roughness: f32) -> f32 {
    (roughness * roughness).max(MIN_ALPHA)
}

/// `F_schlick(f0, c) = f0 + (1 - f0) (1 - c)^5` (B.3.4), per channel.
#[inline]
pub fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    let k = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * k
}

/// `D(h)` (B.3.2) for unit `h`; zero below the horizon.
#[inline]
pub fn ggx_d(h: Vec3, alpha: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    // (N.H)^2 (alpha^2 - 1) + 1 written as (h_x^2 + h_y^2) + h_z^2 alpha^2 (h unit): the same
    // number without the cancellation near N.H = 1 that f32 cannot afford at small alpha.
    let a2 = alpha * alpha;
    let t = (h.x * h.x + h.y * h.y) + h.z * h.z * a2;
    a2 / (PI * t * t)
}

/// The height-correlated Smith visibility `V_GGX` (B.3.2) for `cos_i, cos_o > 0`.
#[inline]
pub fn v_ggx(cos_i: f32, cos_o: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let gv = (a2 + (1.0 - a2) * cos_i * cos_i).sqrt();
    let gl = (a2 + (1.0 - a2) * cos_o * cos_o).sqrt();
    0.5 / (cos_o * gv + cos_i * gl)
}

/// `[glossy, diffuse]` lobes of the BRDF times `cos theta_o` (module docs); zero when either
/// direction is below the horizon. `alpha` is [`alpha`]`(roughness)`.
#[inline]
pub fn lobes(wi: Vec3, wo: Vec3, base: Vec3, metallic: f32, alpha: f32) -> [Vec3; 2] {
    let (ci, co) = (wi.z, wo.z);
    if ci <= 0.0 || co <= 0.0 {
        return [Vec3::ZERO; 2];
    }
    let h = (wi + wo).normalize();
    let vh = wi.dot(h);
    // H.L = H.V for a reflection half vector; both positive here.
    let spec = if vh > 0.0 {
        v_ggx(ci, co, alpha) * ggx_d(h, alpha)
    } else {
        0.0
    };
    let f_d = schlick(Vec3::splat(DIELECTRIC_F0), vh).x;
    let f_m = schlick(base, vh);
    let fresnel = Vec3::splat((1.0 - metallic) * f_d) + f_m * metallic;
    [
        fresnel * (spec * co),
        base * ((1.0 - metallic) * (1.0 - f_d) * FRAC_1_PI * co),
    ]
}

/// Probability of sampling the GGX lobe rather than the cosine lobe: `s / (s + d)` with
/// `s` the mean reflectance at normal incidence, `mix(0.04, mean(base), metallic)`, and `d`
/// the diffuse one, `(1 - metallic) (1 - 0.04) mean(base)`.
#[inline]
pub fn specular_probability(base: Vec3, metallic: f32) -> f32 {
    let b = (base.x + base.y + base.z) / 3.0;
    let s = DIELECTRIC_F0 + (b - DIELECTRIC_F0) * metallic;
    let d = (1.0 - metallic) * (1.0 - DIELECTRIC_F0) * b;
    if s + d > 0.0 {
        (s / (s + d)).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Solid-angle density of the GGX half of the mixture: visible normals of `wi` reflected,
/// `D_wi(h) / (4 wo.h)` with `D_wi(h) = G1(wi) max(0, wi.h) D(h) / cos_i` (Heitz 2018).
#[inline]
pub fn ggx_pdf(wi: Vec3, wo: Vec3, alpha: f32) -> f32 {
    let h = (wi + wo).normalize();
    let d = wo.dot(h);
    if d <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    mf::visible_normal_pdf(wi, h, alpha) / (4.0 * d)
}

#[cfg(test)]
mod tests {
    use super::super::Material;
    use super::*;
    use glam::Vec2;

    fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    /// This file's `D` is Walter 2007's GGX `D` written differently (`microfacet::ggx_d`).
    #[test]
    fn d_is_walters_ggx() {
        for alpha in [0.01, 0.1, 0.5, 1.0] {
            for t in 0..9 {
                let h = dir(10.0 * t as f32, 30.0);
                let (a, b) = (ggx_d(h, alpha), mf::ggx_d(h, alpha));
                assert!((a - b).abs() <= 1e-4 * b.max(1.0), "{alpha} {t}: {a} {b}");
            }
        }
    }

    /// `V_GGX` is Heitz's height-correlated `G2 = 1 / (1 + Lambda(wi) + Lambda(wo))` over
    /// `4 cos_i cos_o`, with `Lambda = (sqrt(1 + alpha^2 tan^2) - 1) / 2` (Heitz 2014, eq. 72
    /// and 99).
    #[test]
    fn v_is_height_correlated_smith() {
        let lambda = |c: f32, a: f32| {
            let tan2 = (1.0 - c * c) / (c * c);
            0.5 * ((1.0 + a * a * tan2).sqrt() - 1.0)
        };
        for alpha in [0.02, 0.3, 0.8] {
            for (ci, co) in [(0.9, 0.2), (0.5, 0.5), (0.1, 0.95)] {
                let g2 = 1.0 / (1.0 + lambda(ci, alpha) + lambda(co, alpha));
                let want = g2 / (4.0 * ci * co);
                let got = v_ggx(ci, co, alpha);
                assert!((got - want).abs() <= 1e-5 * want, "{got} {want}");
            }
        }
    }

    fn gltf(base: f32, metallic: f32, roughness: f32) -> Material {
        Material::Gltf {
            base_color: Vec3::splat(base),
            metallic,
            roughness,
        }
    }

    /// Stratified Monte Carlo albedo `∫ eval(wi, wo) dwo` by importance sampling.
    fn albedo(m: &Material, wi: Vec3, n: usize) -> f32 {
        let k = (n as f64).sqrt() as usize;
        let mut sum = 0.0f64;
        for i in 0..k {
            for j in 0..k {
                let u = Vec2::new((i as f32 + 0.37) / k as f32, (j as f32 + 0.61) / k as f32);
                let ul = ((i * 7919 + j * 104_729) % 1000) as f32 / 1000.0;
                sum += m.sample(wi, u, ul).map_or(0.0, |s| s.weight.x) as f64;
            }
        }
        (sum / (k * k) as f64) as f32
    }

    /// A white metal (`metallic = 1`, `base = 1`, so `F = 1`) against the direct microfacet
    /// formula `D G2 / (4 cos_i cos_o) cos_o` written with Walter's `D`
    /// ([`mf::ggx_d`]) and Heitz's `Lambda`.
    #[test]
    fn white_metal_is_the_direct_formula() {
        let lambda = |c: f32, a: f32| 0.5 * ((1.0 + a * a * (1.0 - c * c) / (c * c)).sqrt() - 1.0);
        for roughness in [0.15f32, 0.4, 0.8] {
            let m = gltf(1.0, 1.0, roughness);
            let a = roughness * roughness;
            for (ti, to, phi) in [(10.0, 50.0, 180.0), (60.0, 20.0, 90.0), (75.0, 75.0, 170.0)] {
                let (wi, wo) = (dir(ti, 0.0), dir(to, phi));
                let h = (wi + wo).normalize();
                let g2 = 1.0 / (1.0 + lambda(wi.z, a) + lambda(wo.z, a));
                let want = mf::ggx_d(h, a) * g2 / (4.0 * wi.z);
                let got = m.eval(wi, wo);
                assert!(
                    (got - Vec3::splat(want)).abs().max_element() <= 1e-5 * want.max(1e-3),
                    "r={roughness} {ti} {to}: {got} vs {want}"
                );
            }
        }
    }

    /// Roughness 1 is `alpha = 1`: `D = 1/pi` and `V = 1 / (2 (cos_i + cos_o))`; roughness 0
    /// is evaluated at [`MIN_ALPHA`]; a black dielectric is its `F(0.04)` specular lobe only.
    #[test]
    fn roughness_special_cases() {
        let (wi, wo) = (dir(30.0, 0.0), dir(50.0, 120.0));
        let h = (wi + wo).normalize();
        let f = schlick(Vec3::splat(0.6), wi.dot(h)).x;
        let want = f * wo.z / (2.0 * PI * (wi.z + wo.z));
        let got = gltf(0.6, 1.0, 1.0).eval(wi, wo).x;
        assert!((got - want).abs() < 1e-6, "{got} {want}");
        let tiny = MIN_ALPHA.sqrt();
        assert_eq!(
            gltf(0.6, 0.3, 0.0).eval(wi, wo),
            gltf(0.6, 0.3, tiny).eval(wi, wo)
        );
        let black = gltf(0.0, 0.0, 1.0).eval(wi, wo).x;
        let f04 = schlick(Vec3::splat(0.04), wi.dot(h)).x;
        assert!((black - f04 * wo.z / (2.0 * PI * (wi.z + wo.z))).abs() < 1e-7);
        // A rough white dielectric at alpha = 1 is the diffuse lobe plus that specular lobe.
        let white = gltf(1.0, 0.0, 1.0).eval(wi, wo).x;
        let diffuse = (1.0 - f04) * FRAC_1_PI * wo.z;
        assert!((white - diffuse - black).abs() < 1e-6);
    }

    /// A smooth metal is a mirror of reflectance `F_schlick(base, cos_i)`: its albedo tends to
    /// it as roughness goes to 0 (`G2 -> 1`).
    #[test]
    fn smooth_metal_is_a_schlick_mirror() {
        for (base, theta) in [(0.9f32, 0.0f32), (0.5, 45.0), (0.3, 70.0)] {
            let wi = dir(theta, 0.0);
            let a = albedo(&gltf(base, 1.0, 0.0), wi, 40_000);
            let want = schlick(Vec3::splat(base), wi.z).x;
            // alpha = 1e-3: the masking loss is below 1e-3 at 70 degrees.
            assert!(
                (a - want).abs() < 2e-3,
                "base {base} theta {theta}: {a} vs {want}"
            );
        }
    }

    /// The hemispherical albedo of the diffuse lobe, averaged over cosine-weighted views, is
    /// [`Material::diffuse_albedo`].
    #[test]
    fn diffuse_albedo_is_the_mean_diffuse_lobe() {
        let m = Material::Gltf {
            base_color: Vec3::new(0.9, 0.5, 0.1),
            metallic: 0.3,
            roughness: 0.5,
        };
        let n = 48;
        let mut sum = [0.0f64; 3];
        for i in 0..n {
            for j in 0..n {
                let wi = super::super::sample_cosine_hemisphere(Vec2::new(
                    (i as f32 + 0.5) / n as f32,
                    (j as f32 + 0.5) / n as f32,
                ));
                for k in 0..n {
                    for l in 0..n / 2 {
                        let u = Vec2::new(
                            (k as f32 + 0.5) / n as f32,
                            (l as f32 + 0.5) / (n / 2) as f32,
                        );
                        let wo = super::super::sample_cosine_hemisphere(u);
                        // eval / (cos_o / pi) of the diffuse lobe.
                        let f = m.lobes(wi, wo)[1] * PI / wo.z.max(1e-9);
                        for c in 0..3 {
                            sum[c] += f[c] as f64;
                        }
                    }
                }
            }
        }
        let mean = Vec3::from(sum.map(|x| (x / (n * n * n * (n / 2)) as f64) as f32));
        let want = m.diffuse_albedo();
        assert!((mean - want).abs().max_element() < 2e-3, "{mean} vs {want}");
    }

    /// [`MEAN_DIFFUSE_TRANSMISSION`] by midpoint quadrature over `(sin^2 theta_i, sin^2
    /// theta_o, phi)` (uniform in the cosine-weighted measure).
    #[test]
    fn mean_diffuse_transmission_by_quadrature() {
        let n = 160;
        let mut sum = 0.0f64;
        for i in 0..n {
            let ci = (1.0 - (i as f64 + 0.5) / n as f64).sqrt();
            for j in 0..n {
                let co = (1.0 - (j as f64 + 0.5) / n as f64).sqrt();
                for k in 0..2 * n {
                    let phi = (k as f64 + 0.5) / (2 * n) as f64 * std::f64::consts::TAU;
                    let vl = ci * co + (1.0 - ci * ci).sqrt() * (1.0 - co * co).sqrt() * phi.cos();
                    let vh = ((1.0 + vl) / 2.0).sqrt();
                    sum += 0.96 * (1.0 - (1.0 - vh).powi(5));
                }
            }
        }
        let mean = sum / (2 * n * n * n) as f64;
        // Midpoint quadrature error at this resolution is below 1e-5.
        assert!(
            (mean - MEAN_DIFFUSE_TRANSMISSION as f64).abs() < 2e-5,
            "{mean}"
        );
    }
}
