//! Mitsuba 3 ground truth: export a [`Scene`] to files Mitsuba reads, and run
//! `tools/mitsuba_reference.py` on them.
//!
//! [`export_mitsuba`] writes into a folder:
//! * `shape_<m>.ply`: the triangles of material `m` (binary little-endian PLY with vertex
//!   normals, loaded with `face_normals = false` so Mitsuba interpolates them as we do);
//! * `env.exr`: the environment as a float latlong in Mitsuba's placement (the map's own
//!   texels when it is a latlong, else resampled with [`EnvMap::to_latlong`]);
//! * `scene.json`: camera (`origin`, `target`, `up`, `fov` horizontal in degrees, `width`,
//!   `height`), `env` (`file`, `scale`, `rotate_y_deg`), `shapes` (`ply` and `bsdf` with
//!   `type` = `diffuse` | `roughconductor` | `roughplastic` and the plugin's parameter names),
//!   `spp`, `max_depth`, `hide_emitters`.
//!
//! Materials map to Mitsuba plugins as documented on [`Material`]: `Lambert` -> `diffuse`,
//! `GgxConductor` -> `roughconductor` (ggx, `material = "none"`), `GgxPlastic` ->
//! `roughplastic` (ggx, `ext_ior = 1`). Blinn-Phong and Ward have no Mitsuba counterpart and are refused,
//! as are materials with texture or normal maps (the export writes constant materials only).

use crate::image::Image;
use relight_scene::error::SceneError;
use relight_scene::material::{Material, MaterialError};
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Scene;
use relight_sphere::envmap::{EnvLayout, EnvMap};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Why exporting a scene to Mitsuba or running Mitsuba failed. Each message names the file,
/// material or program; wrapped errors are part of the message (not also its `source`).
#[derive(Debug, thiserror::Error)]
pub enum MitsubaError {
    /// A folder or file could not be created or written.
    #[error("{path}: {error}")]
    Io {
        /// The folder or file.
        path: PathBuf,
        /// The OS error.
        error: std::io::Error,
    },
    /// A mesh or image file could not be written or read.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The scene's camera is invalid (the message of `Camera::validate`).
    #[error("camera: {0}")]
    Camera(String),
    /// A material in use is out of range.
    #[error("material {index}: {error}")]
    Material {
        /// Material index in the scene.
        index: usize,
        /// What is wrong with it.
        error: MaterialError,
    },
    /// A material in use has texture or normal maps: the export writes constant materials
    /// only (refused rather than exported without its maps).
    #[error("material {index} has texture or normal maps: the Mitsuba export writes constant materials only (compare a textured scene against relight's path tracer)")]
    Textured {
        /// Material index in the scene.
        index: usize,
    },
    /// A material in use is a model Mitsuba 3 does not have (Blinn-Phong, Ward).
    #[error("material {index}: Mitsuba 3 has no {model} BSDF")]
    Unsupported {
        /// Material index in the scene.
        index: usize,
        /// The model's name.
        model: &'static str,
    },
    /// `scene.json` could not be serialised.
    #[error("scene.json: {0}")]
    Json(serde_json::Error),
    /// A program (Python) could not be started.
    #[error("cannot run {program}: {error}")]
    Run {
        /// The program.
        program: PathBuf,
        /// The OS error.
        error: std::io::Error,
    },
    /// The Python found cannot `import mitsuba`.
    #[error("{python} cannot import mitsuba: {stderr}")]
    NoMitsuba {
        /// The Python tried.
        python: PathBuf,
        /// What Python printed on stderr.
        stderr: String,
    },
    /// `tools/mitsuba_reference.py` exited with an error.
    #[error("mitsuba_reference.py failed: {stdout}\n{stderr}")]
    ScriptFailed {
        /// What the script printed on stdout.
        stdout: String,
        /// What the script printed on stderr.
        stderr: String,
    },
}

/// A light of [`export_mitsuba_lit`] as the script reads it.
fn light_json(l: &crate::light::PointLight) -> serde_json::Value {
    match l.spot {
        None => json!({
            "type": "point", "position": l.position.to_array(), "intensity": l.intensity.to_array(),
        }),
        Some(s) => json!({
            "type": "spot", "position": l.position.to_array(), "intensity": l.intensity.to_array(),
            "direction": s.direction.to_array(), "cutoff_deg": s.cutoff_deg,
            "beam_deg": s.cutoff_deg * crate::light::SPOT_BEAM_FRACTION,
        }),
    }
}

/// Export `scene` for `tools/mitsuba_reference.py` into `dir` (created if needed); returns
/// the path of `scene.json`. `max_depth` has Mitsuba's meaning (2 = direct only, -1 =
/// unlimited).
///
/// # Errors
/// An invalid camera or material, a Blinn-Phong material in use, or a file that cannot be
/// written.
pub fn export_mitsuba(
    scene: &Scene,
    dir: &Path,
    spp: u32,
    max_depth: i32,
) -> Result<PathBuf, MitsubaError> {
    export_mitsuba_lit(scene, dir, spp, max_depth, &[])
}

/// [`export_mitsuba`] with point and spot `lights` besides the environment (Mitsuba's
/// `point` and `spot` emitters: `intensity` in W/sr, a spot's `cutoff_angle` and
/// `beam_width = 3/4` of it, as [`crate::light`] defines them). An all-black environment is
/// left out of Mitsuba's scene (`env_black`).
///
/// # Errors
/// As [`export_mitsuba`].
pub fn export_mitsuba_lit(
    scene: &Scene,
    dir: &Path,
    spp: u32,
    max_depth: i32,
    lights: &[crate::light::PointLight],
) -> Result<PathBuf, MitsubaError> {
    std::fs::create_dir_all(dir).map_err(|error| MitsubaError::Io {
        path: dir.to_path_buf(),
        error,
    })?;
    scene
        .camera
        .validate()
        .map_err(|e| MitsubaError::Camera(e.to_string()))?;
    let mut shapes = Vec::new();
    for (m, material) in scene.materials.iter().enumerate() {
        let sub = submesh(&scene.mesh, m as u32);
        if sub.indices.is_empty() {
            continue;
        }
        material
            .validate()
            .map_err(|error| MitsubaError::Material { index: m, error })?;
        if scene.maps.of(m as u32).is_some() {
            return Err(MitsubaError::Textured { index: m });
        }
        let bsdf =
            bsdf_json(material).map_err(|model| MitsubaError::Unsupported { index: m, model })?;
        let name = format!("shape_{m}.ply");
        relight_scene::io::ply::write_ply(&dir.join(&name), &sub)?;
        shapes.push(json!({ "ply": name, "bsdf": bsdf }));
    }
    let env = &scene.env;
    let latlong = latlong_of(&env.map);
    relight_scene::io::write_exr(
        &dir.join("env.exr"),
        latlong.width(),
        latlong.height(),
        latlong.texels(),
    )?;
    let c = &scene.camera;
    let doc = json!({
        "camera": {
            "origin": c.origin, "target": c.target, "up": c.up,
            "fov": c.fov_deg, "width": c.width, "height": c.height,
        },
        "env": { "file": "env.exr", "scale": env.scale, "rotate_y_deg": env.rotate_y_deg },
        "shapes": shapes,
        "spp": spp,
        "max_depth": max_depth,
        "hide_emitters": false,
        "env_black": env.scale == 0.0
            || (0..env.map.texel_count()).all(|i| env.map.texel(i).value == glam::Vec3::ZERO),
        "lights": lights.iter().map(light_json).collect::<Vec<_>>(),
    });
    let path = dir.join("scene.json");
    let text = serde_json::to_string_pretty(&doc).map_err(MitsubaError::Json)?;
    std::fs::write(&path, text).map_err(|error| MitsubaError::Io {
        path: path.clone(),
        error,
    })?;
    Ok(path)
}

/// The Mitsuba BSDF description of a material (see the module docs); the model's name for
/// Blinn-Phong and Ward, which Mitsuba 3 does not have.
fn bsdf_json(m: &Material) -> Result<Value, &'static str> {
    Ok(match *m {
        Material::Lambert { albedo } => {
            json!({ "type": "diffuse", "reflectance": albedo.to_array() })
        }
        Material::GgxConductor { specular, alpha } => json!({
            "type": "roughconductor", "alpha": alpha, "specular_reflectance": specular.to_array(),
        }),
        Material::GgxPlastic {
            diffuse,
            specular,
            alpha,
            ior,
        } => json!({
            "type": "roughplastic", "alpha": alpha, "int_ior": ior, "ext_ior": 1.0,
            "diffuse_reflectance": diffuse.to_array(), "specular_reflectance": specular.to_array(),
        }),
        Material::BlinnPhong { .. } => return Err("Blinn-Phong"),
        Material::Ward { .. } => return Err("Ward"),
    })
}

/// The triangles of material `m` with their vertices, compacted, material id 0.
fn submesh(mesh: &TriMesh, m: u32) -> TriMesh {
    let mut remap = vec![u32::MAX; mesh.positions.len()];
    let mut out = TriMesh::default();
    let mut uvs = Vec::new();
    for (t, tri) in mesh.indices.iter().enumerate() {
        if mesh.material_ids.get(t) != Some(&m) {
            continue;
        }
        let idx = tri.map(|v| {
            let v = v as usize;
            if remap[v] == u32::MAX {
                remap[v] = out.positions.len() as u32;
                out.positions.push(mesh.positions[v]);
                out.normals.push(mesh.normals[v]);
                if let Some(u) = &mesh.uvs {
                    uvs.push(u[v]);
                }
            }
            remap[v]
        });
        out.indices.push(idx);
        out.material_ids.push(0);
    }
    if mesh.uvs.is_some() {
        out.uvs = Some(uvs);
    }
    out
}

/// The map as a latlong: itself, or resampled (cube `n`: `4n x 2n+1`; probe `n`: `2n x n+1`).
fn latlong_of(map: &EnvMap) -> EnvMap {
    match map.layout() {
        EnvLayout::LatLong => map.clone(),
        EnvLayout::Cube => map.to_latlong(4 * map.width(), 2 * map.width() + 1),
        EnvLayout::Probe => map.to_latlong(2 * map.width(), map.width() + 1),
    }
}

/// `tools/mitsuba_reference.py`, built into the binary so that an installed `relight` runs
/// it from anywhere (the build tree is not read at run time).
pub const REFERENCE_SCRIPT: &str = include_str!("../../../tools/mitsuba_reference.py");

/// Write [`REFERENCE_SCRIPT`] into `dir` (beside the export it renders) and return its path.
fn write_reference_script(dir: &Path) -> std::io::Result<PathBuf> {
    let p = dir.join("mitsuba_reference.py");
    std::fs::create_dir_all(dir)?;
    std::fs::write(&p, REFERENCE_SCRIPT)?;
    Ok(p)
}

/// The Python that runs Mitsuba: `$RELIGHT_MITSUBA_PYTHON`, else
/// `$RELIGHT_VENV/bin/python`, else `$HOME/.cache/relight/venv/bin/python` (where
/// `scripts/setup.sh` puts it), if it can `import mitsuba`.
///
/// # Errors
/// [`MitsubaError::Run`] if that Python cannot be started, [`MitsubaError::NoMitsuba`] if it
/// cannot import Mitsuba.
pub fn mitsuba_python() -> Result<PathBuf, MitsubaError> {
    let py = std::env::var_os("RELIGHT_MITSUBA_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let venv = std::env::var_os("RELIGHT_VENV")
                .map(PathBuf::from)
                .unwrap_or_else(|| {
                    let home = std::env::var_os("HOME")
                        .map(PathBuf::from)
                        .unwrap_or_else(|| "/root".into());
                    home.join(".cache/relight/venv")
                });
            venv.join("bin/python")
        });
    let out = Command::new(&py)
        .args(["-c", "import mitsuba"])
        .output()
        .map_err(|error| MitsubaError::Run {
            program: py.clone(),
            error,
        })?;
    if !out.status.success() {
        return Err(MitsubaError::NoMitsuba {
            python: py,
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        });
    }
    Ok(py)
}

/// Render an exported `scene.json` with Mitsuba through `tools/mitsuba_reference.py`, once
/// per sampler seed in `seeds` (one Python process), and load the images. `out_stem` names
/// the files (`<out_stem>_s<seed>.exr`); `spp` overrides the file's when `Some`. Returns the
/// images (in `seeds` order) and the script's report line (variant, time).
///
/// # Errors
/// Python cannot be started, the script fails, or an image it wrote cannot be read.
pub fn render_mitsuba(
    python: &Path,
    scene_json: &Path,
    out_stem: &Path,
    seeds: &[u32],
    spp: Option<u32>,
) -> Result<(Vec<Image>, String), MitsubaError> {
    if seeds.is_empty() {
        return Ok((Vec::new(), String::new()));
    }
    let list: Vec<String> = seeds.iter().map(|s| s.to_string()).collect();
    let out_exr = out_stem.with_extension("exr");
    let script_dir = scene_json.parent().unwrap_or(Path::new("."));
    let script = write_reference_script(script_dir).map_err(|error| MitsubaError::Io {
        path: script_dir.join("mitsuba_reference.py"),
        error,
    })?;
    let mut cmd = Command::new(python);
    cmd.arg(&script)
        .arg(scene_json)
        .arg(&out_exr)
        .args(["--seeds", &list.join(",")]);
    if let Some(s) = spp {
        cmd.args(["--spp", &s.to_string()]);
    }
    let out = cmd.output().map_err(|error| MitsubaError::Run {
        program: python.to_path_buf(),
        error,
    })?;
    let stdout = String::from_utf8_lossy(&out.stdout).trim().to_string();
    if !out.status.success() {
        return Err(MitsubaError::ScriptFailed {
            stdout,
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        });
    }
    let mut images = Vec::new();
    for s in seeds {
        let stem = out_stem
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let path = out_stem.with_file_name(format!("{stem}_s{s}.exr"));
        let (w, h, px) = relight_scene::io::image::read_exr(&path)?;
        images.push(Image {
            width: w,
            height: h,
            pixels: px,
        });
    }
    Ok((images, stdout))
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::camera::Camera;
    use relight_scene::scene::Environment;
    use relight_scene::shapes::{ground_plane, uv_sphere};
    use relight_scene::Vec3;

    #[test]
    fn export_writes_one_ply_per_used_material_and_a_complete_json() {
        let mut mesh = uv_sphere(Vec3::Y, 1.0, 8, 16);
        let ground = ground_plane(Vec3::ZERO, 6.0, 2);
        mesh.append(&ground, 2);
        let scene = Scene {
            maps: Default::default(),
            mesh,
            materials: vec![
                Material::Lambert {
                    albedo: Vec3::splat(0.5),
                },
                Material::BlinnPhong {
                    diffuse: Vec3::ZERO,
                    specular: Vec3::ONE,
                    exponent: 9.0,
                }, // unused
                Material::GgxPlastic {
                    diffuse: Vec3::splat(0.3),
                    specular: Vec3::ONE,
                    alpha: 0.2,
                    ior: 1.5,
                },
            ],
            env: Environment {
                rotate_y_deg: 30.0,
                scale: 2.0,
                ..Environment::new(EnvMap::constant(Vec3::ONE))
            },
            camera: Camera::look_at([0.0, 1.0, 5.0], [0.0, 1.0, 0.0], 40.0, 8, 6),
        };
        let dir =
            std::env::temp_dir().join(format!("relight-mitsuba-export-{}", std::process::id()));
        let json_path = export_mitsuba(&scene, &dir, 16, 3).unwrap();
        let doc: Value =
            serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
        let shapes = doc["shapes"].as_array().unwrap();
        assert_eq!(shapes.len(), 2);
        assert_eq!(shapes[0]["bsdf"]["type"], "diffuse");
        assert_eq!(shapes[1]["bsdf"]["type"], "roughplastic");
        assert_eq!(shapes[1]["bsdf"]["ext_ior"], 1.0);
        assert_eq!(doc["env"]["rotate_y_deg"], 30.0);
        assert_eq!(doc["max_depth"], 3);
        assert!(dir.join("shape_0.ply").is_file() && dir.join("shape_2.ply").is_file());
        assert!(!dir.join("shape_1.ply").exists());
        let (w, h, px) = relight_scene::io::image::read_exr(&dir.join("env.exr")).unwrap();
        assert_eq!((w, h), (scene.env.map.width(), scene.env.map.height()));
        assert!(px.iter().all(|p| *p == Vec3::ONE));
        // A textured material is refused by name, not exported without its maps.
        let mut textured = scene.clone();
        let maps = relight_scene::material::maps::MaterialMaps {
            diffuse: Some(relight_scene::texture::Texture::constant(Vec3::splat(0.5)).unwrap()),
            ..Default::default()
        };
        textured.maps = relight_scene::material::maps::SceneMaps::new(
            &textured.mesh,
            vec![None, None, Some(std::sync::Arc::new(maps))],
        )
        .unwrap();
        let e = export_mitsuba(&textured, &dir, 16, 3).unwrap_err();
        assert!(matches!(e, MitsubaError::Textured { index: 2 }), "{e:?}");
        assert!(e.to_string().contains("texture or normal maps"), "{e}");
        // Blinn-Phong in use is refused.
        let mut bp = scene.clone();
        bp.mesh.material_ids.iter_mut().for_each(|m| *m = 1);
        let e = export_mitsuba(&bp, &dir, 16, 3).unwrap_err();
        assert!(
            matches!(
                e,
                MitsubaError::Unsupported {
                    index: 1,
                    model: "Blinn-Phong"
                }
            ),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "material 1: Mitsuba 3 has no Blinn-Phong BSDF"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
