//! The viewer's camera moves: orbit about a target, pan, zoom, and the framing of the whole
//! scene.
//!
//! Conventions: +Y is up (the scene files' and Mitsuba's `look_at` up); the orbit's yaw is
//! measured about +Y from +Z towards +X and its pitch from the XZ plane towards +Y, so the
//! eye sits at `target + d (cos p sin y, sin p, cos p cos y)`. A camera whose up is not +Y
//! (a bundle's own camera may have any up) is re-expressed with +Y up on its first move.

use glam::Vec3;
use relight_scene::camera::Camera;

/// Largest pitch of an orbit, degrees: at 90 the view direction is parallel to up.
pub const MAX_PITCH_DEG: f32 = 89.0;

/// Closest the eye may come to the target (scene units): keeps the camera valid (origin and
/// target distinct) however far one zooms in.
pub const MIN_DISTANCE: f32 = 1e-4;

/// A camera as orbit parameters about its target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// The point orbited.
    pub target: Vec3,
    /// Distance from the target to the eye.
    pub distance: f32,
    /// Yaw about +Y, degrees.
    pub yaw_deg: f32,
    /// Pitch above the XZ plane, degrees.
    pub pitch_deg: f32,
}

impl Orbit {
    /// The orbit of `camera` (its up is dropped for +Y).
    pub fn of(camera: &Camera) -> Orbit {
        let target = Vec3::from(camera.target);
        let d = Vec3::from(camera.origin) - target;
        let distance = d.length().max(MIN_DISTANCE);
        let pitch = (d.y / distance).clamp(-1.0, 1.0).asin().to_degrees();
        let yaw = d.x.atan2(d.z).to_degrees();
        Orbit {
            target,
            distance,
            yaw_deg: yaw,
            pitch_deg: pitch.clamp(-MAX_PITCH_DEG, MAX_PITCH_DEG),
        }
    }

    /// Unit vector from the target to the eye.
    pub fn eye_dir(&self) -> Vec3 {
        let (y, p) = (self.yaw_deg.to_radians(), self.pitch_deg.to_radians());
        Vec3::new(p.cos() * y.sin(), p.sin(), p.cos() * y.cos())
    }

    /// The camera of this orbit, with the field of view and size of `like`.
    pub fn camera(&self, like: &Camera) -> Camera {
        let origin = self.target + self.eye_dir() * self.distance;
        Camera {
            origin: origin.into(),
            target: self.target.into(),
            up: [0.0, 1.0, 0.0],
            ..*like
        }
    }
}

/// `camera` orbited by `dyaw_deg` about +Y and `dpitch_deg` upwards (pitch clamped to
/// +-[`MAX_PITCH_DEG`]).
pub fn orbit(camera: &Camera, dyaw_deg: f32, dpitch_deg: f32) -> Camera {
    let mut o = Orbit::of(camera);
    o.yaw_deg = (o.yaw_deg + dyaw_deg).rem_euclid(360.0);
    o.pitch_deg = (o.pitch_deg + dpitch_deg).clamp(-MAX_PITCH_DEG, MAX_PITCH_DEG);
    o.camera(camera)
}

/// `camera` and its target moved in the image plane by `dx` view widths to the right and
/// `dy` view heights up, measured at the target's depth (so the target moves on screen by
/// exactly that fraction).
pub fn pan(camera: &Camera, dx: f32, dy: f32) -> Camera {
    let f = camera.frame();
    let depth = (Vec3::from(camera.target) - f.origin).length();
    let shift =
        f.right * (dx * 2.0 * f.tan_half_x * depth) + f.up * (dy * 2.0 * f.tan_half_y * depth);
    Camera {
        origin: (f.origin + shift).into(),
        target: (Vec3::from(camera.target) + shift).into(),
        ..*camera
    }
}

/// `camera` with its distance to the target multiplied by `factor` (at least
/// [`MIN_DISTANCE`]).
pub fn zoom(camera: &Camera, factor: f32) -> Camera {
    let t = Vec3::from(camera.target);
    let d = Vec3::from(camera.origin) - t;
    let len = (d.length() * factor).max(MIN_DISTANCE);
    Camera {
        origin: (t + d.normalize_or(Vec3::Z) * len).into(),
        ..*camera
    }
}

/// The framing of `positions` from the direction of `camera`: the target at the centre of
/// their bounding box, the eye far enough back that the bounding sphere fits the smaller
/// field of view (with 10 % margin). `camera` itself when there are no positions.
pub fn frame_all(camera: &Camera, positions: &[Vec3]) -> Camera {
    if positions.is_empty() {
        return *camera;
    }
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let centre = 0.5 * (lo + hi);
    let radius = (0.5 * (hi - lo).length()).max(MIN_DISTANCE);
    let f = camera.frame();
    let half = f.tan_half_x.min(f.tan_half_y).atan();
    let mut o = Orbit::of(camera);
    o.target = centre;
    o.distance = 1.1 * radius / half.sin();
    o.camera(camera)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera::look_at([1.0, 2.0, 4.0], [0.0, 0.5, 0.0], 40.0, 64, 48)
    }

    fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        (Vec3::from(a) - Vec3::from(b)).abs().max_element() < tol
    }

    #[test]
    fn the_orbit_of_a_camera_gives_the_camera_back() {
        let c = cam();
        let back = Orbit::of(&c).camera(&c);
        // f32 trigonometry on a distance of ~4.3: a few ulps of the coordinates.
        assert!(close(back.origin, c.origin, 1e-5), "{back:?}");
        assert_eq!(back.target, c.target);
        assert_eq!((back.width, back.fov_deg), (c.width, c.fov_deg));
    }

    #[test]
    fn orbiting_keeps_the_distance_and_a_full_turn_comes_back() {
        let c = cam();
        let d0 = (Vec3::from(c.origin) - Vec3::from(c.target)).length();
        let mut o = c;
        for _ in 0..12 {
            o = orbit(&o, 30.0, 0.0);
            let d = (Vec3::from(o.origin) - Vec3::from(o.target)).length();
            assert!((d - d0).abs() < 1e-4, "{d} vs {d0}");
        }
        assert!(close(o.origin, c.origin, 1e-4), "{o:?}");
        // Yaw 90 about +Y takes the eye's +Z offset to +X.
        let q = orbit(
            &Camera::look_at([0.0, 0.0, 3.0], [0.0; 3], 40.0, 8, 8),
            90.0,
            0.0,
        );
        assert!(close(q.origin, [3.0, 0.0, 0.0], 1e-5), "{q:?}");
    }

    #[test]
    fn pitch_stops_short_of_the_pole_and_the_camera_stays_valid() {
        let o = orbit(&cam(), 0.0, 500.0);
        assert!((Orbit::of(&o).pitch_deg - MAX_PITCH_DEG).abs() < 1e-3);
        o.validate().unwrap();
    }

    #[test]
    fn panning_moves_the_target_by_the_asked_fraction_of_the_view() {
        let c = cam();
        let p = pan(&c, 0.25, 0.0);
        // The old target, seen from the panned camera, sits a quarter of the width to the left
        // of the centre.
        let (x, y, _) = p.frame().project(Vec3::from(c.target)).unwrap();
        assert!((x - (0.5 - 0.25) * 64.0).abs() < 1e-3, "{x}");
        assert!((y - 24.0).abs() < 1e-3, "{y}");
    }

    #[test]
    fn zoom_scales_the_distance_and_keeps_the_direction() {
        let c = cam();
        let z = zoom(&c, 0.5);
        let (d0, d1) = (
            Vec3::from(c.origin) - Vec3::from(c.target),
            Vec3::from(z.origin) - Vec3::from(z.target),
        );
        assert!((d1.length() - 0.5 * d0.length()).abs() < 1e-5);
        assert!(d1.normalize().dot(d0.normalize()) > 1.0 - 1e-6);
        zoom(&c, 0.0).validate().unwrap();
    }

    #[test]
    fn framing_puts_every_point_in_view() {
        let pts: Vec<Vec3> = (0..50)
            .map(|i| Vec3::new((i % 5) as f32 - 10.0, (i / 5) as f32 * 0.3, (i % 7) as f32))
            .collect();
        let f = frame_all(&cam(), &pts);
        let fr = f.frame();
        for p in &pts {
            let (x, y, _) = fr.project(*p).expect("in front of the eye");
            assert!(
                (0.0..=64.0).contains(&x) && (0.0..=48.0).contains(&y),
                "{p} at {x},{y}"
            );
        }
    }
}
