//! Mitsuba 3 ground truth: export a [`Scene`] to files Mitsuba reads, and run
//! `tools/mitsuba_reference.py` on them.
//!
//! [`export_mitsuba`] writes into a folder:
//! * `shape_<m>.ply`: the triangles of material `m` (binary little-endian PLY with vertex
//!   normals and, when the mesh has them, texture coordinates `u v` in Mitsuba's convention
//!   below; loaded with `face_normals = false` so Mitsuba interpolates the normals as we do);
//! * `tex_<m>_<kind>.exr`: the maps of material `m` as Mitsuba reads them (below);
//! * `env.exr`: the environment as a float latlong in Mitsuba's placement (the map's own
//!   texels when it is a latlong, else resampled with [`EnvMap::to_latlong`]);
//! * `scene.json`: camera (`origin`, `target`, `up`, `fov` horizontal in degrees, `width`,
//!   `height`), `env` (`file`, `scale`, `rotate_y_deg`), `shapes` (`ply` and `bsdf` with
//!   `type` = `diffuse` | `roughconductor` | `roughplastic` | `gltf` | `normalmap` and the plugin's
//!   parameter names; a textured parameter is `{"bitmap": file}`, plus `"channel": 0` for a
//!   scalar read from the first channel; a `normalmap` has `normalmap` and the nested `bsdf`),
//!   `spp`, `max_depth`, `hide_emitters`.
//!
//! Materials map to Mitsuba plugins as documented on [`Material`]: `Lambert` -> `diffuse`,
//! `GgxConductor` -> `roughconductor` (ggx, `material = "none"`), `GgxPlastic` ->
//! `roughplastic` (ggx, `ext_ior = 1`), `Gltf` -> `gltf` (`base_color`, `metallic`,
//! `roughness`), which `tools/mitsuba_reference.py` renders with the `gltf_pbr` plugin of
//! `tools/mitsuba_gltf_bsdf.py` (glTF 2.0 Appendix B in Dr.Jit; Mitsuba 3 has no such BSDF).
//! Blinn-Phong and Ward have no Mitsuba counterpart and are refused.
//!
//! Mitsuba's own BSDFs are not Appendix B (the script's `--gltf-as blend | principled`
//! renders them for comparison). Measured against relight's path tracer (direct light, a
//! glTF ground and sphere under a smooth environment, 48 x 48, relight 256 spp, Mitsuba
//! 2 x 128; ratio = relRMSE over the noise floor, mean = relight / Mitsuba): the plugin
//! 0.99-1.02 (mean 1.000 +- 0.001); `blendbsdf` of `roughplastic` and `roughconductor`
//! 2.1-12.5 (mean 1.06-1.98), because `roughplastic` sends its diffuse base through a rough
//! dielectric interface (single-scattering transmittance and internal reflection of GGX at
//! `alpha = roughness^2`: albedo 0.32 for a base of 0.8 at roughness 0.9) where Appendix B
//! keeps `1 - F_schlick(V.H) ~ 0.96`, and uses the exact dielectric Fresnel and separable
//! Smith shadowing; `principled` 1.24-1.42 (Mitsuba 4-5 % brighter: its Disney diffuse with
//! roughness-dependent retro-reflection, and exact Fresnel for the dielectric specular).
//!
//! # Texture and normal maps
//!
//! Maps (`relight_scene::material::maps`) are exported where Mitsuba 3 expresses them
//! exactly, and refused by material and map ([`MitsubaError::MapUnsupported`]) otherwise:
//! * **Placement.** relight's `v` grows upwards (texel `(x, y)` from the top-left is centred
//!   at `u = (x + 0.5) / w`, `v = 1 - (y + 0.5) / h`, `relight_scene::texture`); Mitsuba's
//!   `bitmap` centres it at `((x + 0.5) / w, (y + 0.5) / h)` and its `ply` shape reads `u v`
//!   as stored (both probed in Mitsuba 3.9: `Texture::eval` at texel centres and between them
//!   across the edges, `SurfaceInteraction::uv` of a PLY triangle). The PLY therefore stores
//!   `(u, 1 - v)` and the EXR the texels unchanged, row 0 at the top; Mitsuba's bilinear,
//!   repeat-wrapped lookup then reads the texels relight's reads, with the same weights.
//! * **Sampling.** Mitsuba's `bitmap` wraps and filters as relight does (probed in Mitsuba
//!   3.9 on a 2 x 2 bitmap across its edges: `repeat`, `clamp` and `mirror` wrap the texel
//!   index as [`relight_scene::texture::Wrap`]'s `Repeat`, `ClampToEdge` and
//!   `MirroredRepeat`; `nearest` reads the texel containing the point, `bilinear` the four
//!   around it, texel centres at `(x + 0.5) / w`), and its `to_uv` maps the lookup's uv by
//!   `uv' = M uv` before all that. Since the PLY's uv is relight's image space `(s, t)`, in
//!   which `KHR_texture_transform` is defined, `to_uv` is that transform's matrix as it is
//!   (`[[cos r sx, sin r sy, ox], [-sin r sx, cos r sy, oy], [0, 0, 1]]`). A texture whose
//!   two axes wrap differently is refused (one `wrap_mode` for both). A normal map read
//!   through a transform keeps its frame from the mesh's uv in both renderers.
//! * **Textures** are linear float EXR (the already-decoded texels), read with `raw = true`,
//!   `filter_type = bilinear` and `wrap_mode = repeat` unless the texture's sampler says
//!   otherwise (above). A `diffuse` map on Lambert
//!   (`reflectance`) or plastic (`diffuse_reflectance`) and a `specular` map on the conductor
//!   or plastic (`specular_reflectance`) are written pre-multiplied by the constant
//!   reflectance (the product of a constant and a bilinear lookup is the lookup of the
//!   products). A conductor's `roughness` map is its `alpha` texture (the first channel);
//!   refused when a texel is below `MIN_MAP_ALPHA` (relight raises the interpolated alpha,
//!   Mitsuba would interpolate the texels as they are). A `roughness` map on the plastic is
//!   refused: Mitsuba 3's `roughplastic` takes a scalar `alpha` only.
//! * **Normal maps** become a `normalmap` BSDF around the material, loaded with
//!   `use_shadowing_function = false` and `flip_invalid_normals = false`: Mitsuba 3.9 turns
//!   both on by default (found in the plugin, behaviour probed with `BSDF::eval` and
//!   `sample`): the first multiplies every evaluation by a shadowing factor of the outgoing
//!   direction and of the angle between the interpolated and the perturbed normal (relight:
//!   none; it made relight 1.1 % brighter on the test's ripple-mapped quad), the second
//!   changes the normal where the incident direction is below the perturbed one (relight: no
//!   contribution). With both off,
//!   Mitsuba's `eval` is relight's cosine-weighted perturbed BSDF to float rounding. Mitsuba
//!   perturbs the normal in the hit's shading frame, `s` = `dp/du` of the *triangle* made
//!   orthogonal to the interpolated normal `n` and `t = n x s`; relight in `(T, sign N x T,
//!   N)` with `T` the interpolated *per-vertex* tangent (Gram-Schmidt). Both BSDFs are
//!   isotropic, so only the perturbed normal matters. With `v` flipped, `dp/du` is unchanged
//!   and `t` is relight's bitangent when `sign = +1`; when every corner has `sign = -1`
//!   (mirrored UVs, e.g. `shapes::ground_plane`) the map is written with its green channel
//!   flipped (`g -> 1 - g`). The frames are the same, and the export exact, where every
//!   corner's normal is the face normal and its tangent the triangle's `dp/du` direction
//!   (planar quads with affine UVs); anything else is refused (mixed handedness, a curved or
//!   smooth-shaded mesh, a UV shear across triangles). Curved meshes were measured before
//!   that refusal: a UV sphere (24 x 48) with the test's ripple map, Lambert, differs from
//!   Mitsuba by about 1.5 % relative RMS, within the noise at 512 spp (1.12 x the floor) but
//!   not at 4096 (1.53 x).

use crate::image::Image;
use relight_scene::error::SceneError;
use relight_scene::material::maps::vertex_tangents;
use relight_scene::material::{Material, MaterialError};
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Scene;
use relight_sphere::envmap::{EnvLayout, EnvMap};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

mod maps;

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
    /// A map of a material in use has no exact Mitsuba counterpart (module docs): refused
    /// rather than exported as something else.
    #[error("material {index}: its {map} map cannot be exported to Mitsuba: {reason}")]
    MapUnsupported {
        /// Material index in the scene.
        index: usize,
        /// The map's kind (`diffuse`, `specular`, `roughness`, `normal`).
        map: &'static str,
        /// Why Mitsuba cannot express it.
        reason: String,
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
    // Per-vertex tangents, computed once if a normal map asks for its handedness.
    let mut tangents: Option<Option<Vec<glam::Vec4>>> = None;
    for (m, material) in scene.materials.iter().enumerate() {
        let sub = submesh(&scene.mesh, m as u32);
        if sub.indices.is_empty() {
            continue;
        }
        material
            .validate()
            .map_err(|error| MitsubaError::Material { index: m, error })?;
        let mut bsdf =
            bsdf_json(material).map_err(|model| MitsubaError::Unsupported { index: m, model })?;
        if let Some(maps) = scene.maps.of(m as u32) {
            let frames = || {
                let t = tangents.get_or_insert_with(|| vertex_tangents(&scene.mesh));
                maps::normal_map_frames(&scene.mesh, t.as_deref().unwrap_or(&[]), m as u32)
            };
            bsdf = maps::textured_bsdf(dir, m, material, bsdf, maps, frames)?;
        }
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
        Material::Gltf {
            base_color,
            metallic,
            roughness,
        } => json!({
            "type": "gltf", "base_color": base_color.to_array(), "metallic": metallic,
            "roughness": roughness,
        }),
        Material::BlinnPhong { .. } => return Err("Blinn-Phong"),
        Material::Ward { .. } => return Err("Ward"),
    })
}

/// The triangles of material `m` with their vertices, compacted, material id 0, texture
/// coordinates in Mitsuba's convention (`v' = 1 - v`).
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
                    // Mitsuba's v grows downwards (module docs).
                    uvs.push(glam::Vec2::new(u[v].x, 1.0 - u[v].y));
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

/// `tools/mitsuba_gltf_bsdf.py`, the glTF BRDF as a Mitsuba plugin, which
/// [`REFERENCE_SCRIPT`] imports from its own folder.
pub const GLTF_BSDF_SCRIPT: &str = include_str!("../../../tools/mitsuba_gltf_bsdf.py");

/// Write [`REFERENCE_SCRIPT`] and [`GLTF_BSDF_SCRIPT`] into `dir` (beside the export they
/// render) and return the reference script's path.
fn write_reference_script(dir: &Path) -> std::io::Result<PathBuf> {
    let p = dir.join("mitsuba_reference.py");
    std::fs::create_dir_all(dir)?;
    std::fs::write(&p, REFERENCE_SCRIPT)?;
    std::fs::write(dir.join("mitsuba_gltf_bsdf.py"), GLTF_BSDF_SCRIPT)?;
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
mod tests;
