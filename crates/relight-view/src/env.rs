//! Where the viewer's environment comes from: the bundle's own, a file, or the procedural
//! sky (`relight_scene::sky`, Preetham et al. 1999) with its sun placed by the user. The
//! rotation about +Y and the radiance scale are the viewer's, applied on top.

use relight_scene::scene::Environment;
use relight_scene::scene_file::SceneDesc;
use relight_scene::sky::{Sky, SkyParams};
use std::path::{Path, PathBuf};

/// Size of the procedural sky's latlong map in the viewer: 512 x 256 texels (0.7 degrees per
/// texel; the sun is splatted to keep its integral exact at any size) keeps re-building the
/// sky while the sun is dragged within a few tens of milliseconds.
pub const SKY_SIZE: (usize, usize) = (512, 256);

/// The environment's source.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvSource {
    /// The environment of the bundle's scene description.
    Bundle,
    /// An image file (`.hdr` / `.exr`; latlong, cross or probe, detected from its shape).
    File(PathBuf),
    /// The procedural sky.
    Sky {
        /// Sun elevation, degrees in `[0, 90]`.
        elevation_deg: f32,
        /// Sun azimuth, degrees (Mitsuba's latlong phi: 0 = -Z, 90 = +X).
        azimuth_deg: f32,
        /// Turbidity in `[2, 10]`.
        turbidity: f32,
    },
}

impl EnvSource {
    /// A short name for the status line.
    pub fn label(&self) -> String {
        match self {
            EnvSource::Bundle => "the bundle's environment".into(),
            EnvSource::File(p) => p.display().to_string(),
            EnvSource::Sky {
                elevation_deg,
                azimuth_deg,
                turbidity,
            } => format!(
                "sky, sun at elevation {elevation_deg:.0} azimuth {azimuth_deg:.0}, turbidity {turbidity:.1}"
            ),
        }
    }

    /// Build the environment, unrotated and of scale 1, from `desc` (the bundle's scene) and
    /// `bundle` (named in errors).
    ///
    /// # Errors
    /// The file cannot be read or holds a NaN, infinite or negative texel (named with its
    /// position), the sky's parameters are out of range.
    pub fn build(&self, desc: Option<&SceneDesc>, bundle: &Path) -> Result<Environment, String> {
        let mut env = match self {
            EnvSource::Bundle => {
                let desc = desc.ok_or_else(|| {
                    format!(
                        "{}: no bundle loaded, so no environment of its own",
                        bundle.display()
                    )
                })?;
                relight_scene::scene_file::build_env(&desc.environment).map_err(|e| {
                    format!(
                        "{}: the baked scene's environment: {e} (open another environment)",
                        bundle.display()
                    )
                })?
            }
            EnvSource::File(p) => {
                Environment::new(relight_scene::io::load_env(p, None).map_err(|e| e.to_string())?)
            }
            EnvSource::Sky {
                elevation_deg,
                azimuth_deg,
                turbidity,
            } => {
                let params = SkyParams {
                    sun_elevation_deg: *elevation_deg,
                    sun_azimuth_deg: *azimuth_deg,
                    turbidity: *turbidity,
                    width: SKY_SIZE.0,
                    height: SKY_SIZE.1,
                    ..SkyParams::default()
                };
                let sky = Sky::new(params).map_err(|e| format!("procedural sky: {e}"))?;
                Environment::new(sky.to_envmap())
            }
        };
        env.rotate_y_deg = 0.0;
        env.scale = 1.0;
        Ok(env)
    }
}

/// The bundle's environment's own rotation and scale (the starting values of the viewer's
/// sliders), `(0, 1)` when it cannot be built.
pub fn bundle_rotation_and_scale(desc: &SceneDesc) -> (f32, f32) {
    relight_scene::scene_file::build_env(&desc.environment)
        .map(|e| (e.rotate_y_deg, e.scale))
        .unwrap_or((0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sky_builds_and_a_bad_file_is_named() {
        let sky = EnvSource::Sky {
            elevation_deg: 30.0,
            azimuth_deg: 90.0,
            turbidity: 3.0,
        };
        let env = sky.build(None, Path::new("b.relight")).unwrap();
        assert!(env.map.average_luminance() > 0.0);
        let e = EnvSource::File(PathBuf::from("/nonexistent/e.exr"))
            .build(None, Path::new("b.relight"))
            .unwrap_err();
        assert!(e.contains("/nonexistent/e.exr"), "{e}");
        let e = EnvSource::Bundle
            .build(None, Path::new("b.relight"))
            .unwrap_err();
        assert!(e.contains("b.relight"), "{e}");
        let bad = EnvSource::Sky {
            elevation_deg: 30.0,
            azimuth_deg: 90.0,
            turbidity: 50.0,
        };
        assert!(bad
            .build(None, Path::new("b"))
            .unwrap_err()
            .contains("turbidity"));
    }
}
