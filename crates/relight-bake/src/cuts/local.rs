//! The vertex function of local lighting (Cheslack-Postava et al. 2008, sec. 4.1 "we then
//! multiply the binary visibility with the proper geometric term of the light sample, which
//! depends on the type of lighting being used"; sec. 4.2 for the one-bounce use).
//!
//! ## The function towards a surface sample
//!
//! For vertex `p` with unit normal `n` and surface sample `s` ([`super::surface`]) at `x_s`
//! with normal `n_s` and area `A_s`, let `d = |x_s - p|`, `w = (x_s - p) / d`,
//! `cos_v = n . w`, `cos_s = -n_s . w`. The sample is a small diffuse emitter; the radiance it
//! sends to `p` from its area is its radiance `L_s` over the solid angle `A_s cos_s / d^2`.
//! The stored function is
//!
//! `g_s = V(p, x_s) [cos_s > 0] c(cos_v) cos_s A_s / (pi d^2 + A_s)`
//!
//! with `c(cos_v) = [cos_v > 0]` ([`CutFunction::Visibility`], the cosine then in the BRDF at
//! render time) or `max(0, cos_v)` ([`CutFunction::VisibilityCosine`]), so that the outgoing
//! radiance of one bounce is `B = sum_s f_r(w_s) cos(w_s) l_s g_s` with the sample's
//! **exitance** `l_s = pi L_s = rho_s E_s` (albedo times direct irradiance): the light
//! function of the light tree, as `L O` is for environments.
//!
//! **The clamp of `1 / d^2`.** `A_s / (pi d^2 + A_s)` replaces `A_s / (pi d^2)`: it is the
//! exact form factor from a point to a facing coaxial disc of area `A_s` at distance `d`
//! (`r^2 / (r^2 + d^2)`, `r^2 = A_s / pi`), i.e. the sample's area taken as the disc it stands
//! for rather than a point. It agrees with the point form to a relative `A_s / (pi d^2)`
//! (0.1 % at a distance of 18 sample radii), stays finite when a vertex is close to a sample
//! (where `A_s / d^2` diverges and would make one sample light a whole corner) and is at most
//! 1, so every `g_s` is in `[0, 1]` like the environment's visibility and quantises to 16 bits
//! the same way ([`super::cut::quantise`]).
//!
//! The shadow ray leaves `p` along its geometric normal ([`crate::transport::surface_ray`])
//! and stops short of the sample by a relative `1e-3` of `d`, so the sample's own surface
//! never hides it.

use super::surface::SurfaceSamples;
use super::tree::LightTree;
use super::visibility::{CutFunction, Scratch};
use crate::transport::surface_ray;
use glam::Vec3;
use std::f32::consts::PI;

/// Fraction of the distance to a sample the shadow ray stops short of it.
pub const SHADOW_SHORTEN: f32 = 1e-3;

/// `A / (pi d^2 + A)`: the clamped point-to-area geometric term of the module docs (the form
/// factor of a facing coaxial disc of area `A` at distance `d`), in `[0, 1]`.
///
/// # Panics
/// Debug builds: a negative or NaN area or squared distance.
#[inline]
pub fn disc_form_factor(area: f32, d2: f32) -> f32 {
    debug_assert!(area >= 0.0 && d2 >= 0.0, "area {area}, d^2 {d2}");
    if area <= 0.0 {
        return 0.0;
    }
    area / (PI * d2 + area)
}

/// Fill `s.rays`, `s.lights`, `s.cosines` with the shadow rays from vertex `p` (unit shading
/// normal `n`, geometric normal `ng`) towards every sample facing it and above its horizon,
/// with the unshadowed value `g_s` of each (module docs).
pub(super) fn point_rays(
    p: Vec3,
    n: Vec3,
    ng: Vec3,
    points: &SurfaceSamples,
    function: CutFunction,
    s: &mut Scratch,
) {
    for i in 0..points.len() {
        let to = points.positions[i] - p;
        let d2 = to.length_squared();
        if d2 <= 0.0 {
            continue;
        }
        let d = d2.sqrt();
        let w = to / d;
        let cos_v = n.dot(w);
        let cos_s = -points.normals[i].dot(w);
        if cos_v <= 0.0 || cos_s <= 0.0 {
            continue;
        }
        let c = match function {
            CutFunction::VisibilityCosine => cos_v.min(1.0),
            CutFunction::Visibility => 1.0,
        };
        let mut ray = surface_ray(p, ng, w);
        ray.tmax = d * (1.0 - SHADOW_SHORTEN);
        s.rays.push(ray);
        s.lights.push(i as u32);
        s.cosines
            .push(c * cos_s.min(1.0) * disc_form_factor(points.areas[i], d2));
    }
}

/// Every tree node's mean sample position weighted by `weight` (one per light, >= 0): where
/// a cluster's light comes from, at which the BRDF of a pixel is evaluated (the paper's
/// "cluster centre", weighted like [`super::light_cut::LightCut::direction`]). The tree's
/// unweighted centre where a cluster's weights sum to 0.
///
/// # Panics
/// If `weight` is shorter than the tree's light count.
pub fn weighted_positions(tree: &LightTree, weight: &[f64]) -> Vec<Vec3> {
    let sums = super::light_cut::weighted_sums(tree, weight, |i| tree.center(i));
    sums.iter()
        .enumerate()
        .map(|(i, (s, w))| {
            if *w > 0.0 {
                Vec3::new((s[0] / w) as f32, (s[1] / w) as f32, (s[2] / w) as f32)
            } else {
                tree.center(i as u32)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cuts::visibility::LightTargets;
    use crate::cuts::visibility::VisibilitySampler;
    use relight_scene::accel::{build, Backend};
    use relight_scene::mesh::TriMesh;
    use relight_scene::shapes::ground_plane;

    /// Two parallel facing square plates of side `size`: the floor (facing +Y) at y = 0 and a
    /// plate facing -Y at height `h` (the floor mirrored in z and lifted).
    fn plates(size: f32, h: f32, div: u32) -> TriMesh {
        let mut m = ground_plane(Vec3::ZERO, size, div);
        let mut top = ground_plane(Vec3::ZERO, size, div);
        for p in &mut top.positions {
            *p = Vec3::new(p.x, h, -p.z);
        }
        for n in &mut top.normals {
            *n = -*n;
        }
        // Mirroring z turns the winding: the plate faces down (-Y).
        m.append(&top, 0);
        m
    }

    #[test]
    fn disc_form_factor_is_the_point_form_far_away_and_bounded_near() {
        let a = 0.01;
        for d in [1.0f32, 3.0, 10.0] {
            let point = a as f64 / (std::f64::consts::PI * (d * d) as f64);
            let rel = (disc_form_factor(a, d * d) as f64 - point).abs() / point;
            // Exact: rel = A / (pi d^2 + A) < A / (pi d^2); 1e-6: f32 rounding of g.
            assert!(rel <= point + 1e-6, "d {d}: {rel}");
        }
        assert!(disc_form_factor(a, 0.0) == 1.0);
        assert_eq!(disc_form_factor(0.0, 1.0), 0.0);
    }

    #[test]
    fn sum_over_a_facing_plate_is_its_form_factor() {
        // Centre of the floor under a square plate of side a at height h: the point-to-square
        // form factor (parallel, centred) is the double integral of cos cos / (pi d^2) =
        // h^2 / (pi (x^2 + y^2 + h^2)^2) over the square, computed here by a 400^2 midpoint
        // rule (error ~1e-6). The samples' sum must agree within the disc clamp's bias
        // (A_s / (pi h^2) relative, 2e-4 here) plus the stratified points' quadrature error
        // (a few 1e-3 for 8192 points over two plates).
        let (size, h) = (2.0, 1.0);
        let mesh = plates(size, h, 8);
        let caster = build(&mesh, Backend::Bvh).unwrap();
        let points = SurfaceSamples::spread(&mesh, 8192, 0).unwrap();
        points.validate(&mesh).unwrap();
        let sampler = VisibilitySampler::with_targets(
            &mesh,
            caster.as_ref(),
            LightTargets::Points(&points),
            CutFunction::VisibilityCosine,
        )
        .unwrap();
        let centre = (0..mesh.vertex_count())
            .position(|v| mesh.positions[v].length() < 1e-6)
            .unwrap();
        let mut out = vec![0.0; points.len()];
        sampler.sample(centre, &mut out, &mut Scratch::default());
        let sum: f64 = out.iter().map(|&x| x as f64).sum();
        let m = 400;
        let mut exact = 0.0f64;
        let (hh, step) = (h as f64, size as f64 / m as f64);
        for i in 0..m {
            for j in 0..m {
                let x = -1.0 + (i as f64 + 0.5) * step;
                let y = -1.0 + (j as f64 + 0.5) * step;
                let r2 = x * x + y * y + hh * hh;
                exact += hh * hh / (std::f64::consts::PI * r2 * r2) * step * step;
            }
        }
        assert!(
            (sum - exact).abs() < 5e-3 * exact,
            "sum {sum}, exact {exact}"
        );
        // The floor's own samples (coplanar) add nothing.
        for (k, &x) in out.iter().enumerate() {
            if points.normals[k].y > 0.0 {
                assert_eq!(x, 0.0);
            }
        }
    }

    #[test]
    fn an_occluder_between_the_plates_hides_the_samples_above_it() {
        let mut mesh = plates(2.0, 1.0, 4);
        // A small plate facing down at mid-height above the centre blocks the middle.
        let mut blocker = ground_plane(Vec3::ZERO, 0.5, 1);
        for p in &mut blocker.positions {
            *p = Vec3::new(p.x, 0.5, -p.z);
        }
        for n in &mut blocker.normals {
            *n = -*n;
        }
        mesh.append(&blocker, 0);
        let caster = build(&mesh, Backend::Bvh).unwrap();
        let points = SurfaceSamples::spread(&mesh, 4096, 0).unwrap();
        let sampler = VisibilitySampler::with_targets(
            &mesh,
            caster.as_ref(),
            LightTargets::Points(&points),
            CutFunction::Visibility,
        )
        .unwrap();
        let centre = (0..mesh.vertex_count())
            .position(|v| mesh.positions[v].length() < 1e-6)
            .unwrap();
        let mut out = vec![0.0; points.len()];
        sampler.sample(centre, &mut out, &mut Scratch::default());
        for (k, &x) in out.iter().enumerate() {
            let q = points.positions[k];
            // Ceiling samples whose line to the origin crosses y = 0.5 inside the blocker
            // (|x|, |z| < 0.25 there: |q.x|, |q.z| < 0.5 at the ceiling) are hidden; the
            // blocker's own samples face the floor and are seen.
            if q.y > 0.99 && q.x.abs() < 0.49 && q.z.abs() < 0.49 {
                assert_eq!(x, 0.0, "sample {k} at {q} should be hidden");
            }
            if q.y > 0.99 && (q.x.abs() > 0.51 || q.z.abs() > 0.51) {
                assert!(x > 0.0, "sample {k} at {q} should be seen");
            }
        }
    }
}
