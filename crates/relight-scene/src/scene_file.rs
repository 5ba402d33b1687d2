//! Scene description files (JSON): what `relight bake`, `relight reference` and the demo read.
//!
//! ```json
//! {
//!   "shapes": [
//!     {"type": "mesh", "file": "bunny.obj", "fit": {"base": [0, 0, 0], "height": 1.0},
//!      "material": {"type": "lambert", "albedo": [0.8, 0.8, 0.8]}},
//!     {"type": "sphere", "center": [1.5, 0.5, 0], "radius": 0.5},
//!     {"type": "plane", "center": [0, 0, 0], "size": 8, "divisions": 32,
//!      "material": {"type": "ggx_conductor", "specular": [0.9, 0.9, 0.9], "alpha": 0.2}}
//!   ],
//!   "environment": {"type": "file", "path": "grace.hdr", "scale": 1.0, "rotate_y_deg": 0},
//!   "camera": {"origin": [0, 1.5, 4], "target": [0, 0.5, 0], "up": [0, 1, 0],
//!              "fov_deg": 40, "width": 512, "height": 384}
//! }
//! ```
//!
//! Relative paths are resolved against the scene file's folder. A shape without `material`
//! keeps the materials of its file (OBJ/MTL, glTF) or gets the default (Lambert 0.8).
//! Environments: `file` (any layout relight reads, optional `"layout"`: `latlong`, `cube`,
//! `probe`), `sky` (procedural sun and sky) or `constant` (`"radiance": [r, g, b]`).

use crate::camera::Camera;
use crate::error::SceneError;
use crate::material::Material;
use crate::mesh::TriMesh;
use crate::scene::{Environment, Scene};
use crate::{io, meshops, shapes, sky, Vec3};
use relight_sphere::envmap::{EnvLayout, EnvMap};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Uniformly scale and move a loaded mesh so its bounding box has height `height` and its
/// bottom centre sits at `base`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fit {
    /// Where the bottom centre of the bounding box goes.
    pub base: [f32; 3],
    /// Height of the bounding box after scaling.
    pub height: f32,
}

/// One shape of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeDesc {
    /// A mesh file (OBJ, PLY, glTF/GLB).
    Mesh {
        /// Path to the file.
        file: PathBuf,
        /// Optional placement.
        #[serde(default)]
        fit: Option<Fit>,
        /// Weld vertices closer than this (in the file's units) and recompute smooth normals
        /// (for meshes made of unwelded patches, like the Utah teapot).
        #[serde(default)]
        weld: Option<f32>,
        /// Override of the file's materials.
        #[serde(default)]
        material: Option<Material>,
    },
    /// A tessellated sphere.
    Sphere {
        /// Centre.
        center: [f32; 3],
        /// Radius.
        radius: f32,
        /// Latitude bands (default 48; longitude slices are twice that).
        #[serde(default)]
        rings: Option<u32>,
        /// Material.
        #[serde(default)]
        material: Option<Material>,
    },
    /// A square facing +Y.
    Plane {
        /// Centre.
        center: [f32; 3],
        /// Side length.
        size: f32,
        /// Quads per side (default 32).
        #[serde(default)]
        divisions: Option<u32>,
        /// Material.
        #[serde(default)]
        material: Option<Material>,
    },
    /// A small table (a top slab on four legs) standing on y = 0, centred on the Y axis.
    Table {
        /// Width (x) of the top.
        width: f32,
        /// Depth (z) of the top.
        depth: f32,
        /// Height of the top surface above y = 0.
        height: f32,
        /// Material.
        #[serde(default)]
        material: Option<Material>,
    },
    /// An axis-aligned box.
    Box {
        /// Lower corner.
        min: [f32; 3],
        /// Upper corner.
        max: [f32; 3],
        /// Material.
        #[serde(default)]
        material: Option<Material>,
    },
}

/// The lighting of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum EnvDesc {
    /// An environment image.
    File {
        /// Path to the .hdr / .exr.
        path: PathBuf,
        /// Layout (detected from the aspect ratio when absent).
        #[serde(default)]
        layout: Option<String>,
        /// Radiance scale (default 1).
        #[serde(default)]
        scale: Option<f32>,
        /// Rotation about +Y in degrees (default 0).
        #[serde(default)]
        rotate_y_deg: Option<f32>,
    },
    /// The procedural sun and sky (Preetham et al. 1999; see [`crate::sky`]).
    Sky {
        /// Sun elevation above the horizon, degrees.
        sun_elevation_deg: f32,
        /// Sun azimuth, degrees, as Mitsuba's latlong phi (0 = -Z, 90 = +X).
        sun_azimuth_deg: f32,
        /// Atmospheric turbidity in [2, 10].
        turbidity: f32,
        /// Ground albedo (RGB).
        ground_albedo: [f32; 3],
        /// Rotation about +Y in degrees (default 0).
        #[serde(default)]
        rotate_y_deg: Option<f32>,
    },
    /// Constant radiance from every direction.
    Constant {
        /// RGB radiance.
        radiance: [f32; 3],
    },
}

/// A scene description as stored in a JSON file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// Shapes.
    pub shapes: Vec<ShapeDesc>,
    /// Lighting.
    pub environment: EnvDesc,
    /// Camera.
    pub camera: Camera,
}

/// Parse a layout name.
pub fn parse_layout(s: &str) -> Option<EnvLayout> {
    match s {
        "latlong" | "equirect" => Some(EnvLayout::LatLong),
        "cube" | "cross" => Some(EnvLayout::Cube),
        "probe" | "angular" => Some(EnvLayout::Probe),
        _ => None,
    }
}

impl SceneDesc {
    /// Read a scene description file.
    pub fn read(path: &Path) -> Result<SceneDesc, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
        let mut d: SceneDesc = serde_json::from_str(&text)
            .map_err(|e| SceneError::malformed_at(path, e.line(), e.to_string()))?;
        d.resolve_paths(path.parent().unwrap_or(Path::new(".")));
        Ok(d)
    }

    /// Make relative file paths relative to `dir`, and absolute when the file exists (so a
    /// bundle remembers where its environment came from whatever the working folder).
    pub fn resolve_paths(&mut self, dir: &Path) {
        let resolve = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = dir.join(&*p);
            }
            if let Ok(abs) = p.canonicalize() {
                *p = abs;
            }
        };
        for s in &mut self.shapes {
            if let ShapeDesc::Mesh { file, .. } = s {
                resolve(file);
            }
        }
        if let EnvDesc::File { path, .. } = &mut self.environment {
            resolve(path);
        }
    }

    /// Load every file, build every shape, and merge into a [`Scene`].
    pub fn build(&self, origin: &Path) -> Result<Scene, SceneError> {
        self.camera
            .validate()
            .map_err(|m| SceneError::malformed(origin, m))?;
        if self.shapes.is_empty() {
            return Err(SceneError::malformed(origin, "the scene has no shapes"));
        }
        let mut mesh = TriMesh::default();
        let mut materials: Vec<Material> = Vec::new();
        for s in &self.shapes {
            let (part, mats) = build_shape(s)?;
            for m in &mats {
                m.validate()
                    .map_err(|e| SceneError::malformed(origin, format!("material: {e}")))?;
            }
            mesh.append(&part, materials.len() as u32);
            materials.extend(mats);
        }
        let env = build_env(&self.environment)?;
        Ok(Scene {
            mesh,
            materials,
            env,
            camera: self.camera,
        })
    }
}

fn build_shape(s: &ShapeDesc) -> Result<(TriMesh, Vec<Material>), SceneError> {
    let one = |m: &Option<Material>| vec![m.unwrap_or_default()];
    Ok(match s {
        ShapeDesc::Mesh {
            file,
            fit,
            weld,
            material,
        } => {
            let loaded = io::load_mesh(file)?;
            // Loading carries on past recoverable problems; tell the user about each.
            for w in &loaded.warnings {
                eprintln!("warning: {w}");
            }
            let mut mesh = loaded.mesh;
            if let Some(eps) = *weld {
                if !(eps.is_finite() && eps > 0.0) {
                    return Err(SceneError::malformed(
                        file,
                        format!("weld distance {eps} must be > 0"),
                    ));
                }
                mesh = meshops::weld(&mesh, eps);
                meshops::drop_degenerate(&mut mesh);
                meshops::remove_unused_vertices(&mut mesh);
                mesh.normals = meshops::smooth_normals(&mesh, meshops::NormalWeighting::Angle);
            }
            if let Some(f) = fit {
                let (lo, hi) = mesh
                    .bounds()
                    .ok_or_else(|| SceneError::malformed(file, "empty mesh"))?;
                let h = hi.y - lo.y;
                if h.is_nan() || h <= 0.0 {
                    return Err(SceneError::malformed(
                        file,
                        "mesh is flat in Y: cannot fit by height",
                    ));
                }
                let scale = f.height / h;
                let bottom = Vec3::new((lo.x + hi.x) * 0.5, lo.y, (lo.z + hi.z) * 0.5);
                shapes::transform(&mut mesh, scale, Vec3::from(f.base) - bottom * scale);
            }
            let mats = match material {
                Some(m) => {
                    mesh.material_ids.iter_mut().for_each(|id| *id = 0);
                    vec![*m]
                }
                None if loaded.materials.is_empty() => {
                    mesh.material_ids.iter_mut().for_each(|id| *id = 0);
                    vec![Material::default()]
                }
                None => loaded.materials,
            };
            (mesh, mats)
        }
        ShapeDesc::Sphere {
            center,
            radius,
            rings,
            material,
        } => {
            let r = rings.unwrap_or(48).clamp(2, 4096);
            (
                shapes::uv_sphere(Vec3::from(*center), *radius, r, 2 * r),
                one(material),
            )
        }
        ShapeDesc::Plane {
            center,
            size,
            divisions,
            material,
        } => (
            shapes::ground_plane(
                Vec3::from(*center),
                *size,
                divisions.unwrap_or(32).clamp(1, 4096),
            ),
            one(material),
        ),
        ShapeDesc::Table {
            width,
            depth,
            height,
            material,
        } => {
            if !(*width > 0.0 && *depth > 0.0 && *height > 0.0) {
                return Err(SceneError::malformed(
                    Path::new("<table>"),
                    "table width, depth and height must be > 0",
                ));
            }
            let t = 0.04 * height.max(*width);
            (shapes::table(*width, *depth, *height, t, t), one(material))
        }
        ShapeDesc::Box { min, max, material } => (
            shapes::aabb_box(Vec3::from(*min), Vec3::from(*max), 4),
            one(material),
        ),
    })
    .and_then(|(m, mats)| {
        meshops::validate(&m).map_err(|e| SceneError::invalid_mesh(shape_origin(s), e))?;
        Ok((m, mats))
    })
}

fn shape_origin(s: &ShapeDesc) -> &Path {
    match s {
        ShapeDesc::Mesh { file, .. } => file,
        ShapeDesc::Sphere { .. } => Path::new("<sphere>"),
        ShapeDesc::Plane { .. } => Path::new("<plane>"),
        ShapeDesc::Box { .. } => Path::new("<box>"),
        ShapeDesc::Table { .. } => Path::new("<table>"),
    }
}

/// Build the environment of a description (loading files, rasterising the sky).
pub fn build_env(d: &EnvDesc) -> Result<Environment, SceneError> {
    Ok(match d {
        EnvDesc::File {
            path,
            layout,
            scale,
            rotate_y_deg,
        } => {
            let layout = match layout {
                Some(l) => Some(parse_layout(l).ok_or_else(|| {
                    SceneError::malformed(
                        path,
                        format!("unknown layout '{l}' (latlong, cube, probe)"),
                    )
                })?),
                None => None,
            };
            let map = io::load_env(path, layout)?;
            Environment {
                map,
                scale: scale.unwrap_or(1.0),
                rotate_y_deg: rotate_y_deg.unwrap_or(0.0),
            }
        }
        EnvDesc::Sky {
            sun_elevation_deg,
            sun_azimuth_deg,
            turbidity,
            ground_albedo,
            rotate_y_deg,
        } => {
            let params = sky::SkyParams {
                sun_elevation_deg: *sun_elevation_deg,
                sun_azimuth_deg: *sun_azimuth_deg,
                turbidity: *turbidity,
                ground_albedo: Vec3::from(*ground_albedo),
                ..sky::SkyParams::default()
            };
            Environment {
                map: sky::sun_sky_envmap(params)?,
                scale: 1.0,
                rotate_y_deg: rotate_y_deg.unwrap_or(0.0),
            }
        }
        EnvDesc::Constant { radiance } => Environment::new(EnvMap::constant(Vec3::from(*radiance))),
    })
}
