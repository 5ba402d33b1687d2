//! The hybrid renderer (thesis section 4.4, Figure 4.6): PRT radiance of the smooth SH part of
//! the environment plus, per extracted light, a shadow-mapped direct term, added together.
//!
//! Per covered sample (deferred shading on [`raster::render_deferred`]):
//!
//! `L = L_prt + albedo / pi * sum_i E_i * f(n . l_i, a_i) * V_i`
//!
//! * `L_prt`: the per-vertex PRT radiance of the SH part, interpolated.
//! * `E_i` ([`HybridLight::power`]): irradiance the light's cap delivers at normal incidence.
//! * `f`: the cosine term. `area_light = false` (the thesis' point light): `max(0, n.l)`.
//!   `area_light = true`: the exact clipped-cap cosine [`cap_cosine`], the irradiance of a
//!   uniform spherical cap of angular radius `a` on a tilted plane (Snyder 1996, "Area light
//!   sources for real-time graphics"; the closed form as in Lagarde & de Rousiers 2014,
//!   "Moving Frostbite to PBR", eq. 19), normalised to 1 at normal incidence. It equals `n.l`
//!   while the cap is above the horizon and stays positive while it straddles it.
//! * `V_i`: [`ShadowMap::visibility`] with PCF (thesis 4.4; Reeves et al. 1987) or, for area
//!   lights, PCSS (Fernando 2005) with penumbrae sized to the cap.
//!
//! Conventions: light directions are world-frame unit vectors towards the light; the cosine
//! uses the interpolated shading normal and the shadow bias the geometric normal; surfaces
//! are one-sided (the normal's side is lit), as in the PRT bake.
//!
//! Parameters and defaults ([`ShadowSettings::default`]): shadow map 2048², PCF kernel
//! 5 texels, depth bias 1 texel, area lights on, 8 x 8 jittered taps for penumbrae wider
//! than 12 texels (5 x 5 for the blocker search). The SH order, kernel width, light radius
//! and threshold of the decomposition belong to `relight_sphere::decompose`; this module only
//! sees their result. The SH part must be the environment *with each light's cap removed*,
//! or the lights' energy is counted twice (the thesis' double counting, chapter 5).

use crate::image::Image;
use crate::raster::{self, RasterOptions};
use crate::shadowmap::{ShadowFilter, ShadowMap};
use glam::Vec3;
use rayon::prelude::*;
use relight_scene::camera::Camera;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use std::f32::consts::PI;

/// A distant light of small angular size, in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HybridLight {
    /// Unit world direction towards the light's centre.
    pub dir: Vec3,
    /// Irradiance delivered at normal incidence by the whole cap (RGB).
    pub power: Vec3,
    /// Angular radius of the cap, radians (0 = a point light).
    pub cap_radius: f32,
}

impl HybridLight {
    /// A light given in the environment map's frame (as `relight_sphere::decompose` returns
    /// it) moved to the world frame of `env` (its rotation and scale).
    pub fn from_map_frame(dir: Vec3, power: Vec3, cap_radius: f32, env: &Environment) -> Self {
        HybridLight {
            dir: (env.world_from_env() * dir).normalize(),
            power: power * env.scale,
            cap_radius,
        }
    }
}

/// Parameters of the shadow pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowSettings {
    /// Texels per side of each light's shadow map. Default 2048.
    pub map_size: u32,
    /// PCF kernel width in texels (the minimum filter width with area lights). Default 5.
    pub pcf_taps: u32,
    /// Constant depth bias in texels, scaled by `1 + slope` (see `shadowmap`). Default 1.
    pub depth_bias: f32,
    /// Treat lights as caps: clipped-cap cosine and PCSS penumbrae (default `true`); `false`
    /// is the thesis' point light (`max(0, n.l)`, fixed-width PCF).
    pub area_light: bool,
    /// Taps per axis (jittered) of PCSS penumbrae wider than 12 texels; narrower ones are
    /// filtered exactly, and the blocker search always uses 5 x 5 taps. Default 8.
    pub area_taps: u32,
}

impl Default for ShadowSettings {
    /// The defaults listed on each field (the thesis' PCF plus area lights).
    fn default() -> Self {
        ShadowSettings {
            map_size: 2048,
            pcf_taps: 5,
            depth_bias: 1.0,
            area_light: true,
            area_taps: 8,
        }
    }
}

impl ShadowSettings {
    /// The visibility filter for a light of cap radius `cap_radius`.
    pub fn filter(&self, cap_radius: f32) -> ShadowFilter {
        let kernel = self.pcf_taps.max(1) as f32;
        if self.area_light {
            ShadowFilter::Area {
                cap_radius,
                kernel,
                taps: self.area_taps.max(2),
            }
        } else {
            ShadowFilter::Pcf { kernel }
        }
    }
}

/// Irradiance of a uniform spherical cap of angular radius `cap_radius` centred at angle
/// `acos(cos_theta)` from a plane's normal, divided by its irradiance at normal incidence
/// (`pi sin^2 a` times the radiance): the cosine over the clipped cap. Equals
/// `max(0, cos_theta)` for `cap_radius = 0` and while the cap is above the horizon; smooth and
/// positive while it straddles the horizon; 0 once it is below.
///
/// # Panics
/// Debug builds: if `cos_theta` is outside `[-1, 1]` (beyond rounding) or
/// `cap_radius` outside `[0, pi/2]`.
pub fn cap_cosine(cos_theta: f32, cap_radius: f32) -> f32 {
    debug_assert!(cos_theta.abs() <= 1.0 + 1e-4 && (0.0..=PI / 2.0).contains(&cap_radius));
    let c = cos_theta.clamp(-1.0, 1.0);
    let s2 = cap_radius.sin().powi(2);
    if c * c >= s2 || s2 < 1e-12 {
        return c.max(0.0);
    }
    // Straddling the horizon: the closed form lives once, in the decomposition (Snyder 1996;
    // Lagarde & de Rousiers 2014, eq. 19), normalised there by the cap's solid angle.
    let per_solid_angle = relight_sphere::decompose::cap_cosine(c, cap_radius.min(PI / 2.0 - 1e-6));
    per_solid_angle * relight_sphere::decompose::cap_solid_angle(cap_radius) / (PI * s2)
}

/// Hybrid render (see the module docs): builds one shadow map per light, then shades.
///
/// `sh_vertex_radiance` is the PRT radiance of the SH part per vertex (`shade_sh::shade`
/// under the residual environment), `albedo` the diffuse albedo per vertex.
///
/// # Panics
/// If the per-vertex arrays do not match the mesh, `supersample == 0` or the image is empty.
#[allow(clippy::too_many_arguments)]
pub fn render_hybrid(
    mesh: &TriMesh,
    camera: &Camera,
    sh_vertex_radiance: &[Vec3],
    albedo: &[Vec3],
    lights: &[HybridLight],
    s: &ShadowSettings,
    background: Option<&Environment>,
    supersample: u32,
) -> Image {
    let maps = build_shadow_maps(mesh, lights, s);
    render_hybrid_with_maps(
        mesh,
        camera,
        sh_vertex_radiance,
        albedo,
        lights,
        &maps,
        s,
        background,
        supersample,
    )
    .image
}

/// One shadow map per light (empty for a light with zero power: it is skipped in shading).
pub fn build_shadow_maps(
    mesh: &TriMesh,
    lights: &[HybridLight],
    s: &ShadowSettings,
) -> Vec<ShadowMap> {
    lights
        .iter()
        .map(|l| {
            let size = if l.power.max_element() > 0.0 {
                s.map_size
            } else {
                1
            };
            ShadowMap::build(mesh, l.dir, size, s.depth_bias)
        })
        .collect()
}

/// The shading pass of [`render_hybrid`] with prebuilt shadow maps (`maps[i]` for
/// `lights[i]`); returns coverage too.
///
/// # Panics
/// If the per-vertex arrays do not match the mesh or `maps.len() != lights.len()`.
#[allow(clippy::too_many_arguments)]
pub fn render_hybrid_with_maps(
    mesh: &TriMesh,
    camera: &Camera,
    sh_vertex_radiance: &[Vec3],
    albedo: &[Vec3],
    lights: &[HybridLight],
    maps: &[ShadowMap],
    s: &ShadowSettings,
    background: Option<&Environment>,
    supersample: u32,
) -> raster::Rendered {
    assert_eq!(
        sh_vertex_radiance.len(),
        mesh.vertex_count(),
        "PRT radiance per vertex"
    );
    assert_eq!(albedo.len(), mesh.vertex_count(), "albedo per vertex");
    assert_eq!(maps.len(), lights.len(), "one shadow map per light");
    let lights: Vec<(HybridLight, ShadowFilter, &ShadowMap)> = lights
        .par_iter()
        .zip(maps)
        .filter(|(l, _)| l.power.max_element() > 0.0)
        .map(|(l, m)| (*l, s.filter(l.cap_radius), m))
        .collect();
    let opts = RasterOptions { supersample };
    raster::render_deferred(mesh, camera, background, &opts, |f| {
        let mut direct = Vec3::ZERO;
        for (l, filter, map) in &lights {
            let cos = f.shading_normal.dot(l.dir);
            let g = if s.area_light {
                cap_cosine(cos, l.cap_radius.min(PI / 2.0))
            } else {
                cos.max(0.0)
            };
            if g > 0.0 {
                direct += l.power * (g * map.visibility(f.position, f.geometric_normal, filter));
            }
        }
        f.interpolate(mesh, sh_vertex_radiance) + f.interpolate(mesh, albedo) / PI * direct
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::shapes::{aabb_box, ground_plane, uv_sphere};
    use relight_sphere::warp::hammersley;

    #[test]
    fn cap_cosine_matches_monte_carlo_over_the_cap() {
        for a in [0.05f32, 0.3, 0.8, 1.4] {
            // Tilts from overhead through straddling the horizon to below it.
            for theta in [
                0.0f32,
                0.7,
                PI / 2.0 - a - 0.01,
                PI / 2.0 - 0.5 * a,
                PI / 2.0,
                PI / 2.0 + 0.5 * a,
                PI / 2.0 + a + 0.01,
            ] {
                let n = Vec3::new(theta.sin(), 0.0, theta.cos()); // cap centred on +Z
                let count = 1 << 16;
                let (ca, mut sum) = (a.cos() as f64, 0.0f64);
                for i in 0..count {
                    // Uniform directions in the cap: cos uniform in [cos a, 1].
                    let u = hammersley(i, count);
                    let c = 1.0 - u.x as f64 * (1.0 - ca);
                    let s = (1.0 - c * c).max(0.0).sqrt();
                    let phi = std::f64::consts::TAU * u.y as f64;
                    let w = Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, c as f32);
                    sum += n.dot(w).max(0.0) as f64;
                }
                // Irradiance / unit radiance = solid angle x mean cosine; normalise by pi sin^2 a.
                let mc = sum / count as f64 * std::f64::consts::TAU * (1.0 - ca)
                    / (std::f64::consts::PI * (a.sin() as f64).powi(2));
                let got = cap_cosine(theta.cos(), a) as f64;
                // 1e-3: QMC error of 2^16 Hammersley points on a kinked integrand, plus f32.
                assert!(
                    (got - mc).abs() < 1e-3,
                    "a {a} theta {theta}: {got} vs MC {mc}"
                );
            }
        }
        assert_eq!(cap_cosine(0.3, 0.0), 0.3);
        assert_eq!(cap_cosine(-0.3, 0.0), 0.0);
    }

    /// Plane (8 x 8 at y = 0) under a slab `[-1, 1] x [1, 1.02] x [-1, 1]`, a camera looking
    /// down from above the +Z side, 64 x 64.
    fn scene() -> (TriMesh, Camera) {
        let mut m = ground_plane(Vec3::ZERO, 8.0, 16);
        m.append(
            &aabb_box(Vec3::new(-1.0, 1.0, -1.0), Vec3::new(1.0, 1.02, 1.0), 1),
            0,
        );
        let camera = Camera::look_at([0.0, 5.0, 6.0], [0.0, 0.0, 0.0], 60.0, 64, 64);
        (m, camera)
    }

    #[test]
    fn shadowed_and_lit_pixels_have_the_closed_form_values() {
        let (mesh, camera) = scene();
        // PRT part: any smooth per-vertex radiance; albedo varies per vertex too.
        let prt: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| Vec3::splat(0.1) + p.abs() * 0.01)
            .collect();
        let albedo: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| Vec3::new(0.5, 0.3 + 0.01 * p.x.abs(), 0.2))
            .collect();
        let power = Vec3::new(3.0, 2.0, 1.0);
        let g = raster::gbuffer(&mesh, &camera, &RasterOptions::default());
        for area_light in [false, true] {
            let s = ShadowSettings {
                map_size: 1024,
                area_light,
                ..Default::default()
            };
            let light = HybridLight {
                dir: Vec3::Y,
                power,
                cap_radius: 0.05,
            };
            let img = render_hybrid(&mesh, &camera, &prt, &albedo, &[light], &s, None, 1);
            let (mut lit, mut dark) = (0, 0);
            for (k, f) in g.fragments.iter().enumerate() {
                let Some(f) = f else { continue };
                let p = f.position;
                if p.y.abs() > 1e-3 {
                    continue; // the slab
                }
                let base = f.interpolate(&mesh, &prt);
                let got = img.pixels[k];
                let outside = p.x.abs().max(p.z.abs());
                // Penumbra of the cap: 1.02 tan(0.05) = 0.051 each side of the edge.
                if outside < 0.9 {
                    assert!(
                        (got - base).abs().max_element() < 1e-6,
                        "{p}: {got} vs {base}"
                    );
                    dark += 1;
                } else if outside > 1.1 {
                    let expect = base + f.interpolate(&mesh, &albedo) / PI * power;
                    // 1e-6 relative: f32 rounding only (cosine and visibility are exactly 1).
                    assert!(
                        (got - expect).abs().max_element() < 1e-6 * expect.max_element(),
                        "{p}: {got} vs {expect}"
                    );
                    lit += 1;
                }
            }
            assert!(lit > 1000 && dark > 50, "{lit} lit, {dark} dark");
        }
    }

    #[test]
    fn no_lights_is_prt_only() {
        let (mesh, camera) = scene();
        let prt: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| Vec3::splat(0.2) + p.abs() * 0.05)
            .collect();
        let albedo = vec![Vec3::splat(0.5); mesh.vertex_count()];
        let a = render_hybrid(
            &mesh,
            &camera,
            &prt,
            &albedo,
            &[],
            &ShadowSettings::default(),
            None,
            2,
        );
        let opts = RasterOptions { supersample: 2 };
        let b = raster::render_with(&mesh, &camera, &prt, None, &opts).image;
        for (p, q) in a.pixels.iter().zip(&b.pixels) {
            // 1e-5 relative: interpolation order differs (f32 rounding).
            assert!((*p - *q).abs().max_element() <= 1e-5 * q.max_element().max(1.0));
        }
    }

    #[test]
    fn area_light_lights_surfaces_the_point_light_misses() {
        // A sphere lit from the side: the cap straddling the terminator adds light just past
        // it, where max(0, n.l) is 0, and never changes the fully lit side.
        let mesh = uv_sphere(Vec3::ZERO, 1.0, 48, 96);
        let camera = Camera::look_at([0.0, 0.0, 4.0], [0.0; 3], 40.0, 64, 64);
        let zero = vec![Vec3::ZERO; mesh.vertex_count()];
        let albedo = vec![Vec3::ONE; mesh.vertex_count()];
        let light = HybridLight {
            dir: Vec3::X,
            power: Vec3::ONE,
            cap_radius: 0.3,
        };
        let render = |area_light| {
            let s = ShadowSettings {
                map_size: 512,
                area_light,
                ..Default::default()
            };
            render_hybrid(&mesh, &camera, &zero, &albedo, &[light], &s, None, 1)
        };
        let (point, area) = (render(false), render(true));
        let g = raster::gbuffer(&mesh, &camera, &RasterOptions::default());
        let mut beyond = 0;
        for (k, f) in g.fragments.iter().enumerate() {
            let Some(f) = f else { continue };
            let c = f.shading_normal.dot(Vec3::X);
            if c > 0.35 {
                // Cap above the horizon: identical cosine (visibility 1: a convex sphere).
                assert!((point.pixels[k] - area.pixels[k]).abs().max_element() < 1e-5);
            } else if c < -0.05 && c > -0.25 {
                assert_eq!(point.pixels[k], Vec3::ZERO);
                assert!(area.pixels[k].x > 0.0, "cap past the terminator lights {c}");
                beyond += 1;
            }
        }
        assert!(beyond > 10);
    }
}
