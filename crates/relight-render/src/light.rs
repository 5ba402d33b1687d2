//! Point and spot lights (local lighting of the `cuts` method, Cheslack-Postava et al. 2008
//! sec. 4.2; the path
//! tracer's next-event estimation uses the same definitions).
//!
//! Conventions (stated once, here):
//! * A point light at `p` has a radiant **intensity** `I` (RGB, W/sr): the irradiance it gives
//!   a surface point `x` with unit normal `n` is `E = I(w) max(0, n . (p - x)) / d^3`, i.e.
//!   `I(w) cos / d^2` with `d = |p - x|`, `w = (x - p) / d` the direction leaving the light.
//!   It is a delta light: no surface sees it, only next-event estimation reaches it.
//! * A **spot** light multiplies `I` by Mitsuba 3's `spot` falloff around its unit axis `a`:
//!   with `theta = acos(a . w)`, cut-off half-angle `theta_c` and beam width
//!   `theta_b = 3/4 theta_c` (Mitsuba's default), the factor is 1 for `theta <= theta_b`,
//!   `(theta_c - theta) / (theta_c - theta_b)` between and 0 beyond `theta_c`: a smooth (linear
//!   in angle) edge. `theta_c` is in `(0, 180]` degrees; at 180 every direction is lit, fading beyond 135 degrees.

use glam::Vec3;
use relight_scene::accel::{Ray, RayCaster};
use relight_scene::mesh::TriMesh;

/// Rays cast from a light to tell whether it sits inside a closed object.
pub const INSIDE_RAYS: usize = 64;

/// Fraction of the cut-off angle inside which a spot light is at full intensity (Mitsuba 3's
/// default `beam_width = 3/4 cutoff_angle`).
pub const SPOT_BEAM_FRACTION: f32 = 0.75;

/// The cone of a spot light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    /// Unit axis (world frame), the direction the light points to.
    pub direction: Vec3,
    /// Cut-off half-angle, degrees, in `(0, 180]`.
    pub cutoff_deg: f32,
}

/// A point light, or a spot light with [`PointLight::spot`] (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position, world frame.
    pub position: Vec3,
    /// Radiant intensity, W/sr (RGB), finite, non-negative, not all zero.
    pub intensity: Vec3,
    /// The cone of a spot light (`None`: every direction).
    pub spot: Option<Spot>,
}

/// Why a light is refused (user input).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LightError {
    /// The position is NaN or infinite.
    #[error("point light position {0} is not finite")]
    Position(Vec3),
    /// The intensity is NaN, infinite, negative or zero.
    #[error("light intensity {0} must be finite, non-negative and not all zero (W/sr)")]
    Intensity(Vec3),
    /// The spot axis is zero or not finite.
    #[error("spot direction {0} must be a finite non-zero vector")]
    SpotDirection(Vec3),
    /// The spot angle is outside `(0, 180]`.
    #[error("spot angle {0} degrees is not in (0, 180]")]
    SpotAngle(f32),
    /// The light sits inside a closed object.
    #[error("point light at {position} is inside geometry or outside closed walls ({back} of {rays} rays from it hit the back of a surface first)")]
    InsideGeometry {
        /// The light's position.
        position: Vec3,
        /// Rays that met a back face first.
        back: usize,
        /// Rays cast.
        rays: usize,
    },
}

impl PointLight {
    /// A light of intensity `intensity` at `position`, in every direction.
    pub fn new(position: Vec3, intensity: Vec3) -> PointLight {
        PointLight {
            position,
            intensity,
            spot: None,
        }
    }

    /// Check the ranges of the module docs; a spot's axis is normalised.
    ///
    /// # Errors
    /// The [`LightError`] naming the bad value.
    pub fn validated(mut self) -> Result<PointLight, LightError> {
        if !self.position.is_finite() {
            return Err(LightError::Position(self.position));
        }
        let i = self.intensity;
        if !i.is_finite() || i.min_element() < 0.0 || i.max_element() <= 0.0 {
            return Err(LightError::Intensity(i));
        }
        if let Some(s) = &mut self.spot {
            let d = s.direction;
            if !d.is_finite() || d.length_squared() <= 0.0 {
                return Err(LightError::SpotDirection(d));
            }
            s.direction = d.normalize();
            if !(s.cutoff_deg > 0.0 && s.cutoff_deg <= 180.0) {
                return Err(LightError::SpotAngle(s.cutoff_deg));
            }
        }
        Ok(self)
    }

    /// Radiant intensity towards unit direction `w` leaving the light (the spot falloff
    /// applied).
    #[inline]
    pub fn intensity_towards(&self, w: Vec3) -> Vec3 {
        match self.spot {
            None => self.intensity,
            Some(s) => self.intensity * spot_falloff(&s, w),
        }
    }

    /// Unshadowed irradiance at `x` (unit normal `n`, one-sided) with the unit direction
    /// towards the light and the distance to it; `None` when the light is behind the surface,
    /// outside the spot's cone or at `x`.
    #[inline]
    pub fn irradiance(&self, x: Vec3, n: Vec3) -> Option<(Vec3, Vec3, f32)> {
        let to = self.position - x;
        let d2 = to.length_squared();
        if d2 <= 0.0 {
            return None;
        }
        let d = d2.sqrt();
        let w = to / d;
        let cos = n.dot(w);
        if cos <= 0.0 {
            return None;
        }
        let i = self.intensity_towards(-w);
        if i == Vec3::ZERO {
            return None;
        }
        Some((i * (cos / d2), w, d))
    }
}

/// Refuse a light inside a closed object of `mesh` (`caster` built over it): of
/// [`INSIDE_RAYS`] rays from it (a Fibonacci sphere), more than half of those that hit
/// something meet the back of a surface (one-sided surfaces face their outside).
///
/// # Errors
/// [`LightError::InsideGeometry`].
pub fn check_not_inside(
    light: &PointLight,
    mesh: &TriMesh,
    caster: &dyn RayCaster,
) -> Result<(), LightError> {
    let (mut back, mut hits) = (0, 0);
    let golden = (1.0 + 5f64.sqrt()) / 2.0;
    for i in 0..INSIDE_RAYS {
        // The Fibonacci sphere: y = 1 - (2i + 1) / n, azimuth 2 pi i / golden ratio.
        let y = 1.0 - (2.0 * i as f64 + 1.0) / INSIDE_RAYS as f64;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * (i as f64 / golden).fract();
        let d = Vec3::new((r * phi.cos()) as f32, y as f32, (r * phi.sin()) as f32);
        if let Some(h) = caster.intersect(&Ray::new(light.position, d, 0.0, f32::INFINITY)) {
            hits += 1;
            if mesh.geometric_normal(h.tri as usize).dot(d) > 0.0 {
                back += 1;
            }
        }
    }
    if hits > 0 && 2 * back > hits {
        return Err(LightError::InsideGeometry {
            position: light.position,
            back,
            rays: INSIDE_RAYS,
        });
    }
    Ok(())
}

/// Mitsuba 3's spot falloff (module docs) towards unit `w`.
#[inline]
pub fn spot_falloff(s: &Spot, w: Vec3) -> f32 {
    let cutoff = s.cutoff_deg.to_radians();
    let beam = cutoff * SPOT_BEAM_FRACTION;
    let cos = s.direction.dot(w).clamp(-1.0, 1.0);
    if cos <= cutoff.cos() && s.cutoff_deg < 180.0 {
        return 0.0;
    }
    if cos >= beam.cos() {
        return 1.0;
    }
    ((cutoff - cos.acos()) / (cutoff - beam)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn irradiance_on_an_unoccluded_plane_is_i_cos_over_d2() {
        let l = PointLight::new(Vec3::new(0.3, 2.0, -0.4), Vec3::new(1.0, 2.0, 3.0));
        for x in [
            Vec3::ZERO,
            Vec3::new(1.5, 0.0, 0.7),
            Vec3::new(-3.0, 0.0, 2.0),
        ] {
            let (e, w, d) = l.irradiance(x, Vec3::Y).unwrap();
            let to = l.position - x;
            let expect = l.intensity * (to.y / to.length()) / to.length_squared();
            assert!((e - expect).abs().max_element() < 1e-6 * expect.max_element());
            assert!((w - to.normalize()).length() < 1e-6 && (d - to.length()).abs() < 1e-6);
        }
        // Behind the surface: nothing.
        assert!(l.irradiance(Vec3::ZERO, -Vec3::Y).is_none());
    }

    #[test]
    fn spot_falloff_is_one_in_the_beam_zero_outside_and_linear_between() {
        let s = Spot {
            direction: -Vec3::Y,
            cutoff_deg: 40.0,
        };
        let at = |deg: f32| {
            let t = deg.to_radians();
            spot_falloff(&s, Vec3::new(t.sin(), -t.cos(), 0.0))
        };
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(29.0), 1.0);
        assert!((at(35.0) - 0.5).abs() < 1e-4, "{}", at(35.0));
        assert_eq!(at(41.0), 0.0);
        assert_eq!(at(120.0), 0.0);
        let all = Spot {
            cutoff_deg: 180.0,
            ..s
        };
        assert_eq!(spot_falloff(&all, Vec3::X), 1.0);
        assert!(spot_falloff(&all, -Vec3::Y) == 1.0);
    }

    #[test]
    fn bad_lights_are_refused_by_name() {
        let ok = PointLight::new(Vec3::ONE, Vec3::ONE);
        assert!(ok.validated().is_ok());
        let bad = |l: PointLight| l.validated().unwrap_err().to_string();
        assert!(
            bad(PointLight::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE)).contains("position")
        );
        assert!(bad(PointLight::new(Vec3::ONE, Vec3::ZERO)).contains("intensity"));
        assert!(bad(PointLight::new(Vec3::ONE, Vec3::new(1.0, -1.0, 1.0))).contains("intensity"));
        for angle in [0.0, -5.0, 180.5, f32::NAN] {
            let l = PointLight {
                spot: Some(Spot {
                    direction: Vec3::Y,
                    cutoff_deg: angle,
                }),
                ..ok
            };
            assert!(bad(l).contains("spot angle"), "{angle}");
        }
        let l = PointLight {
            spot: Some(Spot {
                direction: Vec3::ZERO,
                cutoff_deg: 30.0,
            }),
            ..ok
        };
        assert!(bad(l).contains("spot direction"));
    }
}
