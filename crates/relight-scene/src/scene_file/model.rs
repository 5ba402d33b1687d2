//! A model file as a scene: what `relight bake MODEL`, `relight reference MODEL` and
//! `relight view MODEL` build when given a `.glb`, `.gltf`, `.obj` or `.ply` instead of a
//! scene description.
//!
//! The one rule, so that bake, render and reference agree (the bundle records the
//! description it was baked from, camera included):
//! * the shapes: the model as it is (its materials, or the default Lambert 0.8), and with
//!   `ground` a square plane under it ([`ground_plane`]);
//! * the environment: the one given, else [`default_sky`];
//! * the camera: the model's own when it has one, else [`Camera::framing`] of the model's
//!   bounds (the ground plane is not framed).

use super::{EnvDesc, SceneDesc, ShapeDesc};
use crate::camera::Camera;
use crate::error::SceneError;
use crate::io::{self, files::LoadOptions};
use crate::material::Material;
use crate::Vec3;
use std::path::{Path, PathBuf};

/// The file extensions read as models (case-insensitive).
pub const MODEL_EXTENSIONS: [&str; 4] = ["glb", "gltf", "obj", "ply"];

/// Whether `path` names a model file (by its extension) rather than a scene description.
pub fn is_model(path: &Path) -> bool {
    MODEL_EXTENSIONS.contains(&io::extension(path).as_str())
}

/// The sky a model is lit by when no environment is given: the procedural sun and sky
/// ([`crate::sky`]) with the sun 35 degrees high, in front of the framed camera and to its
/// right (azimuth 135 degrees: between +X and +Z), clear air (turbidity 3) over a ground of
/// albedo 0.3: a bright, directional light that shows shape and shadows.
pub fn default_sky() -> EnvDesc {
    EnvDesc::Sky {
        sun_elevation_deg: 35.0,
        sun_azimuth_deg: 135.0,
        turbidity: 3.0,
        ground_albedo: [0.3, 0.3, 0.3],
        rotate_y_deg: None,
    }
}

/// Side of the ground plane, in radii of the model's bounding sphere.
pub const GROUND_SIZE_RADII: f32 = 8.0;
/// Quads per side of the ground plane (per-vertex methods shade it at its vertices: 64 x 64
/// quads keep a model's contact shadow smooth for 8.3K extra vertices).
pub const GROUND_DIVISIONS: u32 = 64;
/// Albedo of the ground plane (a mid grey, Lambert).
pub const GROUND_ALBEDO: f32 = 0.5;

/// A square plane touching the bottom of the bounds `[min, max]` from below, centred under
/// them, [`GROUND_SIZE_RADII`] bounding-sphere radii on a side.
pub fn ground_plane(min: Vec3, max: Vec3) -> ShapeDesc {
    let c = 0.5 * (min + max);
    let r = (0.5 * (max - min).length()).max(1e-6);
    ShapeDesc::Plane {
        center: [c.x, min.y, c.z],
        size: GROUND_SIZE_RADII * r,
        divisions: Some(GROUND_DIVISIONS),
        material: Some(
            Material::Lambert {
                albedo: Vec3::splat(GROUND_ALBEDO),
            }
            .into(),
        ),
        name: None,
    }
}

/// How a model scene was made up, for the user: which camera and which light.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelChoices {
    /// Where the camera comes from.
    pub camera: &'static str,
    /// Where the environment comes from.
    pub environment: &'static str,
}

impl SceneDesc {
    /// The scene of a model file by the module's rule: the model (loaded once here under
    /// `opts`, for its bounds and camera; an error names the file and the problem), the
    /// ground plane if `ground`, `environment` or [`default_sky`], and the camera. Paths are
    /// made absolute, as [`SceneDesc::read`] does.
    pub fn for_model(
        model: &Path,
        environment: Option<EnvDesc>,
        ground: bool,
        opts: &LoadOptions,
    ) -> Result<(SceneDesc, ModelChoices), SceneError> {
        let loaded = io::load_mesh_with(model, opts)?;
        let (min, max) = loaded.mesh.bounds().ok_or_else(|| {
            SceneError::malformed(model, "the model has no triangles".to_string())
        })?;
        let file: PathBuf = model.canonicalize().unwrap_or_else(|_| model.to_path_buf());
        let mut shapes = vec![ShapeDesc::Mesh {
            file,
            fit: None,
            weld: None,
            material: None,
            subdivide: None,
            name: None,
        }];
        if ground {
            shapes.push(ground_plane(min, max));
        }
        let (camera, which) = match loaded.camera {
            Some(c) => (c, "the model's own (its first glTF camera)"),
            None => (Camera::framing(min, max), "framed on the model's bounds"),
        };
        let choices = ModelChoices {
            camera: which,
            environment: if environment.is_some() {
                "as given"
            } else {
                "the default sky"
            },
        };
        let mut desc = SceneDesc {
            shapes,
            environment: environment.unwrap_or_else(default_sky),
            camera,
        };
        desc.resolve_paths(Path::new("."));
        desc.validate()
            .map_err(|m| SceneError::malformed(model, m))?;
        Ok((desc, choices))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_obj(dir: &Path) -> PathBuf {
        let p = dir.join("tri.obj");
        std::fs::write(&p, "v 0 1 0\nv 2 1 0\nv 0 3 0\nv 0 1 1\nf 1 2 3\nf 1 4 2\n").unwrap();
        p
    }

    #[test]
    fn a_model_gets_the_framed_camera_the_default_sky_and_an_optional_ground() {
        let dir = std::env::temp_dir().join(format!("relight-model-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let obj = write_obj(&dir);
        assert!(is_model(&obj) && is_model(Path::new("a.GLB")));
        assert!(!is_model(Path::new("scene.json")));
        let opts = LoadOptions::default();
        let (d, why) = SceneDesc::for_model(&obj, None, false, &opts).unwrap();
        assert_eq!(d.shapes.len(), 1);
        assert_eq!(d.environment, default_sky());
        assert_eq!(why.environment, "the default sky");
        let (min, max) = (Vec3::new(0.0, 1.0, 0.0), Vec3::new(2.0, 3.0, 1.0));
        assert_eq!(d.camera, Camera::framing(min, max));
        let scene = d.build(&obj).unwrap();
        assert_eq!(scene.mesh.triangle_count(), 2);

        let env = EnvDesc::Constant {
            radiance: [1.0, 1.0, 1.0],
        };
        let (g, _) = SceneDesc::for_model(&obj, Some(env.clone()), true, &opts).unwrap();
        assert_eq!(g.environment, env);
        assert_eq!(g.camera, d.camera, "the ground is not framed");
        let scene = g.build(&obj).unwrap();
        let (lo, hi) = scene.mesh.bounds().unwrap();
        assert_eq!(lo.y, 1.0, "the ground touches the model's bottom");
        assert_eq!(hi.y, 3.0);
        let r = 0.5 * (max - min).length();
        assert!((hi.x - lo.x - GROUND_SIZE_RADII * r).abs() < 1e-4);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A glTF with a camera keeps it (the reader's conversion is tested in io/gltf).
    #[test]
    fn a_gltf_camera_is_the_scenes_camera() {
        let dir = std::env::temp_dir().join(format!("relight-model-c-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // One triangle (positions as base64 f32) seen by a camera at z = 5.
        let mut bytes = Vec::new();
        for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        let uri = crate::io::test_util::base64_encode(&bytes);
        let json = format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0,
            "scenes": [{{"nodes": [0, 1]}}],
            "nodes": [{{"mesh": 0}}, {{"camera": 0, "translation": [0, 0, 5]}}],
            "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.6, "aspectRatio": 1.5, "znear": 0.1}}}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
            "buffers": [{{"byteLength": 36, "uri": "data:application/octet-stream;base64,{uri}"}}],
            "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                            "min": [0, 0, 0], "max": [1, 1, 0]}}]}}"#
        );
        let p = dir.join("cam.gltf");
        std::fs::write(&p, json).unwrap();
        let (d, why) = SceneDesc::for_model(&p, None, false, &LoadOptions::default()).unwrap();
        assert!(why.camera.contains("own"), "{why:?}");
        assert_eq!(d.camera.origin, [0.0, 0.0, 5.0]);
        assert_ne!(
            d.camera,
            Camera::framing(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0))
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_missing_or_empty_model_is_an_error_naming_it() {
        let dir = std::env::temp_dir().join(format!("relight-model-e-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("nope.glb");
        let e = SceneDesc::for_model(&missing, None, false, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("nope.glb"), "{e}");
        let empty = dir.join("empty.obj");
        std::fs::write(&empty, "v 0 0 0\n").unwrap();
        let e = SceneDesc::for_model(&empty, None, false, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("empty.obj"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
