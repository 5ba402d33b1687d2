//! The point or spot light of a `cuts` frame over a bake of surface samples (local lighting,
//! Cheslack-Postava et al. 2008 sec. 4.2; the shading is `relight_render::shade_local`),
//! given at render time:
//! `--point-light x,y,z --light-intensity r,g,b [--spot-dir x,y,z --spot-angle deg]`.
//! The same options light `relight reference` (the path tracer's next-event estimation).

use crate::MethodError;
use glam::Vec3;
use relight_render::light::{PointLight, Spot};

/// Which terms of local lighting a frame renders (to time or check one term alone). A
/// closed set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum LocalTerms {
    /// Direct light and one bounce.
    #[default]
    All,
    /// The light's direct light only.
    Direct,
    /// One bounce of indirect light only.
    Indirect,
}

impl LocalTerms {
    /// The shader's terms.
    pub fn terms(self) -> relight_render::shade_local::Terms {
        relight_render::shade_local::Terms {
            direct: self != LocalTerms::Indirect,
            indirect: self != LocalTerms::Direct,
        }
    }
}

/// A point or spot light from options (all optional: a frame without `point_light` has no
/// local light).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct PointLightArgs {
    /// Point light position `x,y,z` (world frame): lights a bake of surface samples
    /// (`relight bake --cut-samples surface`) with direct light and one bounce.
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true))]
    pub point_light: Option<Vec3>,
    /// Radiant intensity of the point light, `r,g,b` W/sr (needed with --point-light).
    #[cfg_attr(feature = "cli", arg(long, value_name = "R,G,B", value_parser = parse_vec3))]
    pub light_intensity: Option<Vec3>,
    /// Axis of a spot light `x,y,z` (with --spot-angle).
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true))]
    pub spot_dir: Option<Vec3>,
    /// Cut-off half-angle of a spot light, degrees in (0, 180] (full intensity within 3/4
    /// of it, Mitsuba's `spot`).
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "DEG", allow_hyphen_values = true)
    )]
    pub spot_angle: Option<f32>,
}

impl PointLightArgs {
    /// The light, validated; `None` when no option is given.
    ///
    /// # Errors
    /// [`MethodError::Settings`]: an intensity or spot option without `--point-light`, a
    /// point light without intensity, a spot direction without angle or the reverse, or a
    /// value out of range (NaN position, zero intensity, angle outside (0, 180]).
    pub fn light(&self) -> Result<Option<PointLight>, MethodError> {
        let err = |m: String| Err(MethodError::Settings(m));
        let Some(position) = self.point_light else {
            if self.light_intensity.is_some()
                || self.spot_dir.is_some()
                || self.spot_angle.is_some()
            {
                return err(
                    "--light-intensity, --spot-dir and --spot-angle need --point-light".into(),
                );
            }
            return Ok(None);
        };
        let Some(intensity) = self.light_intensity else {
            return err("--point-light needs --light-intensity r,g,b (W/sr)".into());
        };
        let spot = match (self.spot_dir, self.spot_angle) {
            (None, None) => None,
            (Some(direction), Some(cutoff_deg)) => Some(Spot {
                direction,
                cutoff_deg,
            }),
            _ => return err("a spot light needs both --spot-dir and --spot-angle".into()),
        };
        PointLight {
            position,
            intensity,
            spot,
        }
        .validated()
        .map(Some)
        .map_err(|e| MethodError::Settings(e.to_string()))
    }
}

impl PointLightArgs {
    /// The lights of the options (none or one) in a scene of `mesh` (`caster` built over
    /// it), each validated and refused inside geometry
    /// ([`relight_render::light::check_not_inside`]).
    ///
    /// # Errors
    /// As [`PointLightArgs::light`], and [`MethodError::Settings`] for a light inside
    /// geometry.
    pub fn lights_in(
        &self,
        mesh: &relight_scene::mesh::TriMesh,
        caster: &dyn relight_scene::accel::RayCaster,
    ) -> Result<Vec<PointLight>, MethodError> {
        let lights: Vec<PointLight> = self.light()?.into_iter().collect();
        for l in &lights {
            relight_render::light::check_not_inside(l, mesh, caster)
                .map_err(|e| MethodError::Settings(e.to_string()))?;
        }
        Ok(lights)
    }
}

/// `x,y,z` as a vector (three finite or not numbers: ranges are checked with the light).
///
/// # Errors
/// A message naming the text.
pub fn parse_vec3(text: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = text
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("'{text}' is not three numbers x,y,z: {e}"))?;
    match v[..] {
        [x, y, z] => Ok(Vec3::new(x, y, z)),
        _ => Err(format!(
            "'{text}' has {} numbers, not three (x,y,z)",
            v.len()
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_make_a_light_or_a_clear_error() {
        let p = PointLightArgs {
            point_light: Some(Vec3::new(0.0, 1.0, 0.0)),
            light_intensity: Some(Vec3::ONE),
            ..Default::default()
        };
        assert!(p.light().unwrap().is_some());
        assert!(PointLightArgs::default().light().unwrap().is_none());
        let msg = |a: PointLightArgs| a.light().unwrap_err().to_string();
        assert!(msg(PointLightArgs {
            light_intensity: None,
            ..p
        })
        .contains("--light-intensity"));
        assert!(msg(PointLightArgs {
            point_light: None,
            ..p
        })
        .contains("need --point-light"));
        assert!(msg(PointLightArgs {
            light_intensity: Some(Vec3::ZERO),
            ..p
        })
        .contains("intensity"));
        assert!(msg(PointLightArgs {
            point_light: Some(Vec3::new(f32::NAN, 0.0, 0.0)),
            ..p
        })
        .contains("position"));
        for angle in [0.0, 200.0] {
            assert!(msg(PointLightArgs {
                spot_dir: Some(-Vec3::Y),
                spot_angle: Some(angle),
                ..p
            })
            .contains("spot angle"));
        }
        assert!(msg(PointLightArgs {
            spot_dir: Some(-Vec3::Y),
            ..p
        })
        .contains("both"));
        assert_eq!(parse_vec3("1, -2,3.5").unwrap(), Vec3::new(1.0, -2.0, 3.5));
        assert!(parse_vec3("1,2").is_err() && parse_vec3("a,b,c").is_err());
    }
}
