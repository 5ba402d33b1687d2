//! Pinhole cameras following Mitsuba 3's `perspective` sensor with `look_at`.
//!
//! forward `f = normalize(target - origin)`, right `r = normalize(f x up)`, `up' = r x f`.
//! The ray through pixel (row `i` from the top, column `j` from the left) of a `W x H` image is
//! `d ∝ f + (2(j+0.5)/W - 1) tan(fov/2) r + (1 - 2(i+0.5)/H) tan(fov/2) (H/W) up'`,
//! `fov` horizontal, in degrees (Mitsuba's default `fov_axis = "x"`).

use crate::mesh::MAX_COORDINATE;
use crate::Vec3;
use serde::{Deserialize, Serialize};

/// Smallest field of view accepted, degrees: below, the image-plane scale `tan(fov / 2)` is so
/// small that projecting points overflows.
pub const MIN_FOV_DEG: f32 = 1e-3;

/// A perspective camera (Mitsuba `perspective` sensor, `fov_axis = "x"`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Eye position.
    pub origin: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up hint (need not be orthogonal to the view direction).
    pub up: [f32; 3],
    /// Horizontal field of view in degrees.
    pub fov_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// The orthonormal frame and scale factors of a camera, precomputed for ray generation.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    /// Eye position.
    pub origin: Vec3,
    /// Unit forward.
    pub forward: Vec3,
    /// Unit right.
    pub right: Vec3,
    /// Unit up (orthogonal to forward and right).
    pub up: Vec3,
    /// `tan(fov/2)`.
    pub tan_half_x: f32,
    /// `tan(fov/2) * H / W`.
    pub tan_half_y: f32,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
}

impl Camera {
    /// A camera at `origin` looking at `target` with +Y up, horizontal field of view
    /// `fov_deg` degrees, `width x height` pixels.
    pub fn look_at(
        origin: [f32; 3],
        target: [f32; 3],
        fov_deg: f32,
        width: u32,
        height: u32,
    ) -> Camera {
        Camera {
            origin,
            target,
            up: [0.0, 1.0, 0.0],
            fov_deg,
            width,
            height,
        }
    }

    /// Check the camera is usable: finite vectors within [`MAX_COORDINATE`], distinct origin
    /// and target, up not parallel to the view direction, fov from [`MIN_FOV_DEG`] up to (not
    /// including) 180 degrees, size in `1..=16384`. The message names the field.
    pub fn validate(&self) -> Result<(), crate::error::Invalid> {
        self.validate_msg().map_err(crate::error::Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        let o = Vec3::from(self.origin);
        let t = Vec3::from(self.target);
        let u = Vec3::from(self.up);
        for (name, v) in [("origin", o), ("target", t), ("up", u)] {
            if !(v.is_finite() && v.abs().max_element() <= MAX_COORDINATE) {
                return Err(format!(
                    "camera {name} {v} must be finite and within +-{MAX_COORDINATE:e}"
                ));
            }
        }
        let f = t - o;
        if f.length() <= 1e-12 {
            return Err("camera origin and target coincide".into());
        }
        if f.normalize().cross(u).length() <= 1e-6 {
            return Err("camera up vector is parallel to the view direction".into());
        }
        if !(self.fov_deg >= MIN_FOV_DEG && self.fov_deg < 180.0) {
            return Err(format!(
                "camera fov_deg {:?} is not in [{MIN_FOV_DEG}, 180) degrees",
                self.fov_deg
            ));
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(format!(
                "image size {}x{} is not in 1..=16384",
                self.width, self.height
            ));
        }
        Ok(())
    }

    /// The precomputed frame.
    pub fn frame(&self) -> CameraFrame {
        let origin = Vec3::from(self.origin);
        let forward = (Vec3::from(self.target) - origin).normalize();
        let right = forward.cross(Vec3::from(self.up)).normalize();
        let up = right.cross(forward);
        let tan_half_x = (self.fov_deg.to_radians() * 0.5).tan();
        CameraFrame {
            origin,
            forward,
            right,
            up,
            tan_half_x,
            tan_half_y: tan_half_x * self.height as f32 / self.width as f32,
            width: self.width,
            height: self.height,
        }
    }
}

impl CameraFrame {
    /// Unit direction through the image-plane point at continuous pixel coordinates
    /// (`x` from the left, `y` from the top, both in pixels; pixel centres at `+0.5`).
    #[inline]
    pub fn dir_at(&self, x: f32, y: f32) -> Vec3 {
        let sx = 2.0 * x / self.width as f32 - 1.0;
        let sy = 1.0 - 2.0 * y / self.height as f32;
        (self.forward + self.right * (sx * self.tan_half_x) + self.up * (sy * self.tan_half_y))
            .normalize()
    }

    /// Project a world point to continuous pixel coordinates `(x, y, depth)`; depth is the
    /// distance along `forward` (`None` when the point is behind the eye).
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let d = p - self.origin;
        let z = d.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let sx = d.dot(self.right) / (z * self.tan_half_x);
        let sy = d.dot(self.up) / (z * self.tan_half_y);
        Some((
            (sx + 1.0) * 0.5 * self.width as f32,
            (1.0 - sy) * 0.5 * self.height as f32,
            z,
        ))
    }
}

/// Horizontal field of view of a camera framed automatically ([`Camera::framing`]), degrees.
pub const FRAMING_FOV_DEG: f32 = 40.0;
/// Elevation of a framed camera above the bounds' centre, degrees.
pub const FRAMING_ELEVATION_DEG: f32 = 20.0;
/// Image size of a framed camera (4:3).
pub const FRAMING_SIZE: (u32, u32) = (640, 480);

impl Camera {
    /// The camera relight gives a model without one of its own (the same rule for `bake`,
    /// `reference` and `view`, so their pictures agree): it looks at the centre `c` of the
    /// axis-aligned bounds `[min, max]` from the front (+Z, glTF's and OBJ's usual facing),
    /// [`FRAMING_ELEVATION_DEG`] above it, with +Y up, a [`FRAMING_FOV_DEG`] horizontal field
    /// of view at [`FRAMING_SIZE`] pixels, and far enough that the bounding sphere (radius
    /// `r`, half the diagonal) fits the narrower (vertical) field of view with 5 % to spare:
    /// distance `1.05 r / sin(fov_y / 2)`.
    pub fn framing(min: Vec3, max: Vec3) -> Camera {
        debug_assert!(min.is_finite() && max.is_finite() && min.cmple(max).all());
        let c = 0.5 * (min + max);
        let r = (0.5 * (max - min).length()).max(1e-6);
        let (w, h) = FRAMING_SIZE;
        let tan_x = (FRAMING_FOV_DEG.to_radians() * 0.5).tan();
        let half_y = (tan_x * h as f32 / w as f32).atan();
        let dist = 1.05 * r / half_y.sin();
        let e = FRAMING_ELEVATION_DEG.to_radians();
        let dir = Vec3::new(0.0, e.sin(), e.cos());
        Camera::look_at((c + dist * dir).into(), c.into(), FRAMING_FOV_DEG, w, h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    fn cam() -> Camera {
        Camera::look_at([0.3, 1.0, 4.0], [0.0, 0.2, 0.0], 40.0, 64, 48)
    }

    #[test]
    fn centre_ray_is_forward_and_right_is_plus_x_for_camera_on_plus_z() {
        let c = Camera {
            origin: [0.0, 0.0, 5.0],
            target: [0.0; 3],
            ..cam()
        };
        let f = c.frame();
        assert!((f.dir_at(32.0, 24.0) - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        // Looking down -Z with +Y up, the right of the image is +X (Mitsuba's look_at).
        assert!((f.right - Vec3::X).length() < 1e-6);
        // The top-left pixel looks up-left.
        let d = f.dir_at(0.5, 0.5);
        assert!(d.x < 0.0 && d.y > 0.0);
    }

    /// The framed camera sees the whole bounding sphere, not much more: every point of the
    /// sphere (sampled densely) projects inside the image, the centre onto the image centre,
    /// and the sphere spans at least 80 % of the image height.
    #[test]
    fn framing_fits_the_bounding_sphere() {
        for (min, max) in [
            (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0)),
            (Vec3::new(10.0, -3.0, 5.0), Vec3::new(10.5, 7.0, 5.2)),
            (Vec3::splat(-1e-3), Vec3::splat(1e-3)),
        ] {
            let cam = Camera::framing(min, max);
            cam.validate().unwrap();
            let f = cam.frame();
            let (c, r) = (0.5 * (min + max), 0.5 * (max - min).length());
            let (cx, cy, _) = f.project(c).unwrap();
            assert!((cx - 320.0).abs() < 1e-2 && (cy - 240.0).abs() < 1e-2);
            let (mut lo, mut hi) = (f32::MAX, f32::MIN);
            for i in 0..64 {
                for j in 0..32 {
                    let (t, p) = (PI * (j as f32 + 0.5) / 32.0, 2.0 * PI * i as f32 / 64.0);
                    let d = Vec3::new(t.sin() * p.cos(), t.cos(), t.sin() * p.sin());
                    let (x, y, _) = f.project(c + r * d).unwrap();
                    assert!((0.0..=640.0).contains(&x) && (0.0..=480.0).contains(&y));
                    (lo, hi) = (lo.min(y), hi.max(y));
                }
            }
            assert!(hi - lo >= 0.8 * 480.0, "{min} {max}: spans {lo}..{hi}");
        }
    }

    #[test]
    fn project_inverts_dir_at() {
        let f = cam().frame();
        for &(x, y) in &[(0.5f32, 0.5f32), (10.25, 40.75), (63.5, 12.0)] {
            let p = f.origin + f.dir_at(x, y) * 3.7;
            let (px, py, _) = f.project(p).unwrap();
            assert!(
                (px - x).abs() < 1e-3 && (py - y).abs() < 1e-3,
                "{px},{py} vs {x},{y}"
            );
        }
    }

    #[test]
    fn horizontal_fov_spans_the_image_width() {
        let f = cam().frame();
        let l = f.dir_at(0.0, 24.0);
        let r = f.dir_at(64.0, 24.0);
        let angle = l.dot(r).clamp(-1.0, 1.0).acos().to_degrees();
        assert!((angle - 40.0).abs() < 1e-3, "{angle}");
    }

    #[test]
    fn validate_rejects_bad_cameras() {
        assert!(cam().validate().is_ok());
        assert!(Camera {
            target: [0.3, 1.0, 4.0],
            ..cam()
        }
        .validate()
        .is_err());
        assert!(Camera {
            up: [0.0, 0.0, 1.0],
            origin: [0.0, 0.0, 4.0],
            target: [0.0; 3],
            ..cam()
        }
        .validate()
        .is_err());
        assert!(Camera {
            fov_deg: 0.0,
            ..cam()
        }
        .validate()
        .is_err());
        assert!(Camera { width: 0, ..cam() }.validate().is_err());
    }

    #[test]
    fn validate_rejects_tiny_fov_and_huge_coordinates_naming_the_field() {
        let e = Camera {
            fov_deg: 1e-30,
            ..cam()
        }
        .validate()
        .unwrap_err();
        assert!(e.contains("fov_deg") && e.contains("1e-30"), "{e}");
        let e = Camera {
            origin: [1e30, 0.0, 0.0],
            ..cam()
        }
        .validate()
        .unwrap_err();
        assert!(e.contains("origin"), "{e}");
    }
}
