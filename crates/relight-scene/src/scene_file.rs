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
//! A shape without `material` keeps the materials of its file (OBJ/MTL, glTF) or gets the
//! default (Lambert 0.8). A shape's material may name texture and normal maps in the same
//! object ([`MaterialDesc`]; what each map does: [`crate::material::maps`]):
//! `"material": {"type": "ggx_plastic", "diffuse": [1, 1, 1], "specular": [1, 1, 1],
//! "alpha": 0.2, "ior": 1.5, "maps": {"diffuse": "albedo.png", "roughness": "r.exr",
//! "normal": "n.png"}}`; the shape needs texture coordinates (spheres and planes have
//! them, a mesh file must). Environments: `file` (any layout relight reads, optional
//! `"layout"`: `latlong`, `cube`, `probe`), `sky` (procedural sun and sky) or `constant`
//! (`"radiance": [r, g, b]`).
//!
//! # Objects
//! The built scene keeps its objects' names ([`Scene::objects`]): a mesh shape brings its
//! file's objects (glTF nodes or meshes, OBJ `o` / `g`, else the file stem), and a mesh of one
//! object in a scene of several shapes takes the shape's optional `"name"`; a procedural
//! shape is named by its `"name"` or by its kind and place (`sphere1`, `plane2`: shape 1, 2).
//! A `"name"` given twice is refused naming both shapes; a file's or a generated name already
//! taken gets the first free suffix `.1`, `.2`, ...
//!
//! # Files a scene names
//! Relative paths are resolved against the scene file's folder; `..` and absolute paths are
//! allowed: a scene is a list of files its author chose (the examples use
//! `../../shared/data/...`). The files themselves must be regular files within the size caps,
//! and the references *inside* a model (glTF buffers, OBJ `mtllib`) may not leave the model's
//! folder unless [`LoadOptions::paths`] allows it: the rules are in [`crate::io::files`].
//! Material maps count as such references of the scene file: resolved against its folder
//! and refused outside it unless [`LoadOptions::paths`] allows it (`--allow-outside-paths`).
//!
//! # Checks
//! A description is checked when read ([`SceneDesc::from_json`], [`SceneDesc::read`]) and
//! again when built, and refused with an error naming the field (`scene.json: shapes[1]
//! (sphere): radius -1.0 must be in (0, 1e8]`):
//! * every number must fit an `f32` (`1e39` is refused, not turned into infinity);
//! * coordinates and lengths are finite and within [`MAX_COORDINATE`]; radii, sizes,
//!   heights, weld distances are > 0; a box's `min` is below its `max` on every axis;
//! * `rings` is in [`RINGS`], `divisions` in [`DIVISIONS`] (refused, never clamped);
//! * light is never negative: an environment's `scale` is finite and >= 0, a constant
//!   `radiance` finite and >= 0; angles are finite; the sky's parameters are in their ranges
//!   ([`sky::SkyParams::validate`]); the camera passes [`Camera::validate`]; materials pass
//!   `Material::validate`.
//!
//! Building counts the triangles of every procedural shape before generating it and loads
//! each mesh with the triangles left under [`LoadOptions::max_triangles`], so the merged
//! scene never exceeds that limit; the merged geometry must stay within
//! [`MAX_COORDINATE`].

use crate::camera::Camera;
use crate::error::{Location, SceneError};
use crate::io::files::{self, LoadOptions};
use crate::material::maps::{MaterialDesc, MaterialMaps, SceneMaps};
use crate::material::Material;
use crate::mesh::{TriMesh, MAX_COORDINATE};
use crate::scene::{Environment, Scene, SceneObject};
use crate::{io, meshops, shapes, sky, Vec3};
use relight_sphere::envmap::{EnvLayout, EnvMap};
use serde::{Deserialize, Serialize};
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

/// Accepted `rings` of a sphere (latitude bands; longitude slices are twice that). Default 48.
pub const RINGS: RangeInclusive<u32> = 2..=2048;
/// Accepted `divisions` of a plane (quads per side). Default 32.
pub const DIVISIONS: RangeInclusive<u32> = 1..=2048;
/// Default `rings` of a sphere.
pub const DEFAULT_RINGS: u32 = 48;
/// Default `divisions` of a plane.
pub const DEFAULT_DIVISIONS: u32 = 32;
/// Longest `"name"` of a shape, in characters.
pub const MAX_NAME_CHARS: usize = 256;
/// Quads per side of each box face ([`ShapeDesc::Box`]).
const BOX_DIVISIONS: u32 = 4;

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
        material: Option<MaterialDesc>,
        /// Levels of midpoint subdivision after loading (1 to
        /// [`meshops::MAX_SUBDIVISION`]; each multiplies the triangles by 4): a dense mesh
        /// from a shared one (for bakes of a million vertices and more).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        subdivide: Option<u32>,
        /// Its name in the scene's object list ([`crate::scene::SceneObject`]); unique
        /// among the shapes. A mesh file's objects keep their own names unless the file
        /// holds one object and the scene several shapes.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// A tessellated sphere.
    Sphere {
        /// Centre.
        center: [f32; 3],
        /// Radius.
        radius: f32,
        /// Latitude bands (default [`DEFAULT_RINGS`], in [`RINGS`]; longitude slices are twice
        /// that).
        #[serde(default)]
        rings: Option<u32>,
        /// Material.
        #[serde(default)]
        material: Option<MaterialDesc>,
        /// Its name in the scene's object list ([`crate::scene::SceneObject`]); unique
        /// among the shapes. A mesh file's objects keep their own names unless the file
        /// holds one object and the scene several shapes.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// A square facing +Y.
    Plane {
        /// Centre.
        center: [f32; 3],
        /// Side length.
        size: f32,
        /// Quads per side (default [`DEFAULT_DIVISIONS`], in [`DIVISIONS`]).
        #[serde(default)]
        divisions: Option<u32>,
        /// Material.
        #[serde(default)]
        material: Option<MaterialDesc>,
        /// Its name in the scene's object list ([`crate::scene::SceneObject`]); unique
        /// among the shapes. A mesh file's objects keep their own names unless the file
        /// holds one object and the scene several shapes.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
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
        material: Option<MaterialDesc>,
        /// Its name in the scene's object list ([`crate::scene::SceneObject`]); unique
        /// among the shapes. A mesh file's objects keep their own names unless the file
        /// holds one object and the scene several shapes.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// An axis-aligned box.
    Box {
        /// Lower corner.
        min: [f32; 3],
        /// Upper corner.
        max: [f32; 3],
        /// Material.
        #[serde(default)]
        material: Option<MaterialDesc>,
        /// Its name in the scene's object list ([`crate::scene::SceneObject`]); unique
        /// among the shapes. A mesh file's objects keep their own names unless the file
        /// holds one object and the scene several shapes.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
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
    /// Read a scene description file: a regular file of at most
    /// [`files::MAX_TEXT_BYTES`], UTF-8 (a leading byte-order mark is skipped), parsed and
    /// checked by [`SceneDesc::from_json`]; relative paths are then resolved
    /// ([`SceneDesc::resolve_paths`]) against the file's folder.
    pub fn read(path: &Path) -> Result<SceneDesc, SceneError> {
        let bytes = files::read_file(path, files::MAX_TEXT_BYTES, "scene description")?;
        let text = std::str::from_utf8(&bytes).map_err(|e| {
            SceneError::malformed(path, format!("not UTF-8 text (byte {})", e.valid_up_to()))
        })?;
        let mut d = SceneDesc::from_json(path, text)?;
        d.resolve_paths(path.parent().unwrap_or(Path::new(".")));
        Ok(d)
    }

    /// Parse and check a description (see the module docs); `origin` names the source in
    /// errors. A leading UTF-8 byte-order mark is skipped. Paths are left as written.
    pub fn from_json(origin: &Path, text: &str) -> Result<SceneDesc, SceneError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let d: SceneDesc = serde_json::from_str(text)
            .map_err(|e| SceneError::malformed_at(origin, e.line(), e.to_string()))?;
        // Numbers beyond f32 parse as infinity above: find them, by field, in the raw JSON.
        let raw: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| SceneError::malformed_at(origin, e.line(), e.to_string()))?;
        if let Some((field, v)) = number_beyond_f32(&raw, String::new()) {
            return Err(SceneError::malformed(
                origin,
                format!("{field}: {v} is beyond the range of a 32-bit float (+-3.4e38)"),
            ));
        }
        d.validate().map_err(|m| SceneError::malformed(origin, m))?;
        Ok(d)
    }

    /// Check every value of the description (see the module docs); the message names the
    /// field, e.g. `shapes[1] (sphere): radius -1.0 must be in (0, 1e8]`.
    pub fn validate(&self) -> Result<(), crate::error::Invalid> {
        self.validate_msg().map_err(crate::error::Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        if self.shapes.is_empty() {
            return Err("the scene has no shapes".into());
        }
        let mut named: std::collections::HashMap<&str, usize> = Default::default();
        for (i, s) in self.shapes.iter().enumerate() {
            s.validate()
                .map_err(|m| format!("{}: {m}", shape_label(i, s)))?;
            if let Some(n) = s.name() {
                if let Some(&j) = named.get(n) {
                    return Err(format!(
                        "{} and {} are both named {n:?} (names must be unique)",
                        shape_label(j, &self.shapes[j]),
                        shape_label(i, s)
                    ));
                }
                named.insert(n, i);
            }
        }
        self.environment.validate()?;
        self.camera.validate().map_err(String::from)
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

    /// [`SceneDesc::build_with`] with the default [`LoadOptions`] (models confined to their
    /// folder, [`files::DEFAULT_MAX_TRIANGLES`]).
    pub fn build(&self, origin: &Path) -> Result<Scene, SceneError> {
        self.build_with(origin, &LoadOptions::default())
    }

    /// Check the description, load every file (as `opts` allows), build every shape, and
    /// merge into a [`Scene`]; `origin` (the scene file) names the scene in errors. The merged
    /// scene has at most `opts.max_triangles` triangles: procedural shapes are counted before
    /// they are generated, and each mesh file is loaded with the triangles left.
    pub fn build_with(&self, origin: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
        self.validate()
            .map_err(|m| SceneError::malformed(origin, m))?;
        let limit = opts.max_triangles as u64;
        let mut mesh = TriMesh::default();
        let mut materials: Vec<Material> = Vec::new();
        let mut maps = Vec::new();
        // Each object's name, whether the scene file gave it, and its triangles.
        let mut named: Vec<(String, bool, std::ops::Range<u32>)> = Vec::new();
        for (i, s) in self.shapes.iter().enumerate() {
            let others = mesh.triangle_count() as u64;
            if let Some(n) = s.triangle_count() {
                if others.saturating_add(n) > limit {
                    return Err(SceneError::TooManyTriangles {
                        at: Location {
                            file: format!("{}: {}", origin.display(), shape_label(i, s)),
                            line: None,
                        },
                        count: n,
                        at_least: false,
                        others,
                        limit,
                    });
                }
            }
            let budget = LoadOptions {
                max_triangles: limit.saturating_sub(others) as usize,
                ..*opts
            };
            let (part, mats, loaded_maps, file_objects) =
                build_shape(s, &budget).map_err(|e| match e {
                    SceneError::TooManyTriangles {
                        at,
                        count,
                        at_least,
                        ..
                    } => SceneError::TooManyTriangles {
                        at,
                        count,
                        at_least,
                        others,
                        limit,
                    },
                    e => e,
                })?;
            for m in &mats {
                m.validate()
                    .map_err(|e| SceneError::malformed(origin, format!("material: {e}")))?;
            }
            match s.maps() {
                Some(desc) => {
                    let at = |m: String| {
                        SceneError::malformed(origin, format!("{}: {m}", shape_label(i, s)))
                    };
                    if part.uvs.is_none() {
                        return Err(at(format!(
                            "material maps on {}, which has no texture coordinates (uvs)",
                            shape_origin(s).display()
                        )));
                    }
                    let loaded = MaterialMaps::load(desc, &mats[0], origin, &opts.paths)?;
                    maps.push(Some(std::sync::Arc::new(loaded)));
                }
                // The maps a model file brings (glTF textures) when no material overrides its own.
                None if loaded_maps.len() == mats.len() => maps.extend(
                    loaded_maps
                        .into_iter()
                        .map(|m| (m != MaterialMaps::default()).then(|| std::sync::Arc::new(m))),
                ),
                None => maps.extend(mats.iter().map(|_| None)),
            }
            let first = mesh.triangle_count() as u32;
            named.extend(
                shape_objects(
                    i,
                    s,
                    self.shapes.len(),
                    &file_objects,
                    part.triangle_count() as u32,
                )
                .into_iter()
                .map(|(n, explicit, r)| (n, explicit, first + r.start..first + r.end)),
            );
            mesh.append(&part, materials.len() as u32);
            materials.extend(mats);
        }
        let objects = unique_objects(named);
        let maps = SceneMaps::new(&mesh, maps).map_err(|m| SceneError::malformed(origin, m))?;
        if let Some((lo, hi)) = mesh.bounds() {
            let extent = lo.abs().max(hi.abs()).max_element();
            if extent > MAX_COORDINATE {
                return Err(SceneError::malformed(
                    origin,
                    format!("the geometry reaches {extent:e}, beyond +-{MAX_COORDINATE:e} (normals would overflow): scale the meshes down with \"fit\""),
                ));
            }
        }
        let env = build_env(&self.environment)?;
        Ok(Scene {
            mesh,
            materials,
            maps,
            env,
            camera: self.camera,
            objects,
        })
    }
}

/// The objects of shape `i` of `shapes` (with triangles counted from the shape's first):
/// name, whether the scene file gave it, triangles. A mesh keeps its file's objects (one named
/// by the shape's `"name"` when the file holds one and the scene several shapes); a
/// procedural shape is one object named by its `"name"` or its kind and place (`sphere1`).
fn shape_objects(
    i: usize,
    s: &ShapeDesc,
    shapes: usize,
    file_objects: &[io::MeshObject],
    triangles: u32,
) -> Vec<(String, bool, std::ops::Range<u32>)> {
    let whole = |name: String, explicit: bool| vec![(name, explicit, 0..triangles)];
    match (s.name(), file_objects) {
        (Some(n), [_]) if shapes > 1 => whole(n.to_string(), true),
        (Some(n), []) => whole(n.to_string(), true),
        (None, []) => whole(format!("{}{}", shape_kind(s), i + 1), false),
        (_, objects) => objects
            .iter()
            .map(|o| (o.name.clone(), false, o.triangles.clone()))
            .collect(),
    }
}

/// Scene objects from `(name, explicit, triangles)`: explicit names (unique, checked by
/// [`SceneDesc::validate`]) are kept; a file's or generated name already taken gets the
/// first free suffix `.1`, `.2`, ...; empty objects are dropped.
fn unique_objects(named: Vec<(String, bool, std::ops::Range<u32>)>) -> Vec<SceneObject> {
    let mut used: std::collections::HashSet<String> =
        named.iter().filter(|n| n.1).map(|n| n.0.clone()).collect();
    named
        .into_iter()
        .filter(|n| !n.2.is_empty())
        .map(|(name, explicit, triangles)| {
            let name = if explicit {
                name
            } else {
                let free = (0..)
                    .map(|k| {
                        if k == 0 {
                            name.clone()
                        } else {
                            format!("{name}.{k}")
                        }
                    })
                    .find(|c| !used.contains(c))
                    .unwrap_or(name);
                used.insert(free.clone());
                free
            };
            SceneObject { name, triangles }
        })
        .collect()
}

/// The kind of a shape as the scene file spells it (`mesh`, `sphere`, ...).
fn shape_kind(s: &ShapeDesc) -> &'static str {
    match s {
        ShapeDesc::Mesh { .. } => "mesh",
        ShapeDesc::Sphere { .. } => "sphere",
        ShapeDesc::Plane { .. } => "plane",
        ShapeDesc::Table { .. } => "table",
        ShapeDesc::Box { .. } => "box",
    }
}

/// `shapes[i] (kind)`, naming a shape in errors.
/// How messages name shape `i` of a scene file: `shapes[1] (sphere)`.
pub fn shape_label(i: usize, s: &ShapeDesc) -> String {
    format!("shapes[{i}] ({})", shape_kind(s))
}

/// The first number of `v` (a JSON document) that is not a finite `f32`, with its field path
/// (`shapes[0].center[1]`).
fn number_beyond_f32(v: &serde_json::Value, at: String) -> Option<(String, f64)> {
    use serde_json::Value;
    match v {
        Value::Number(n) => n
            .as_f64()
            .filter(|x| !(*x as f32).is_finite())
            .map(|x| (at, x)),
        Value::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, x)| number_beyond_f32(x, format!("{at}[{i}]"))),
        Value::Object(o) => o.iter().find_map(|(k, x)| {
            let field = if at.is_empty() {
                k.clone()
            } else {
                format!("{at}.{k}")
            };
            number_beyond_f32(x, field)
        }),
        _ => None,
    }
}

/// `name` must be finite, > 0 and at most [`MAX_COORDINATE`].
fn check_length(name: &str, v: f32) -> Result<(), String> {
    if v > 0.0 && v <= MAX_COORDINATE {
        Ok(())
    } else {
        Err(format!("{name} {v:?} must be in (0, {MAX_COORDINATE:e}]"))
    }
}

/// Every component of `name` must be finite and within +-[`MAX_COORDINATE`].
fn check_point(name: &str, v: [f32; 3]) -> Result<(), String> {
    if v.iter().all(|x| x.abs() <= MAX_COORDINATE) {
        Ok(())
    } else {
        Err(format!(
            "{name} {v:?} must be finite and within +-{MAX_COORDINATE:e}"
        ))
    }
}

/// `name`, if given, must be in `range` (stated in the error; never clamped).
fn check_count(name: &str, v: Option<u32>, range: RangeInclusive<u32>) -> Result<(), String> {
    match v {
        Some(v) if !range.contains(&v) => Err(format!(
            "{name} {v} is out of range: must be in {}..={}",
            range.start(),
            range.end()
        )),
        _ => Ok(()),
    }
}

fn check_material(m: &Option<MaterialDesc>) -> Result<(), String> {
    match m {
        Some(m) => m.material.validate().map_err(|e| format!("material: {e}")),
        None => Ok(()),
    }
}

impl ShapeDesc {
    /// Check every value (see the module docs); the message names the field.
    pub fn validate(&self) -> Result<(), crate::error::Invalid> {
        self.validate_msg().map_err(crate::error::Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        if let Some(n) = self.name() {
            if n.is_empty() || n.chars().count() > MAX_NAME_CHARS {
                return Err(format!(
                    "name {n:?} must have 1 to {MAX_NAME_CHARS} characters"
                ));
            }
            if n.chars().any(|c| c.is_control() || c == '=') {
                return Err(format!(
                    "name {n:?} may not hold control characters or '=' (the command line's NAME=FILE)"
                ));
            }
        }
        match self {
            ShapeDesc::Mesh {
                fit,
                weld,
                material,
                subdivide,
                ..
            } => {
                check_count("subdivide", *subdivide, 1..=meshops::MAX_SUBDIVISION)?;
                if let Some(f) = fit {
                    check_point("fit.base", f.base)?;
                    check_length("fit.height", f.height)?;
                }
                if let Some(w) = weld {
                    check_length("weld", *w)?;
                }
                check_material(material)
            }
            ShapeDesc::Sphere {
                center,
                radius,
                rings,
                material,
                ..
            } => {
                check_point("center", *center)?;
                check_length("radius", *radius)?;
                check_count("rings", *rings, RINGS)?;
                check_material(material)
            }
            ShapeDesc::Plane {
                center,
                size,
                divisions,
                material,
                ..
            } => {
                check_point("center", *center)?;
                check_length("size", *size)?;
                check_count("divisions", *divisions, DIVISIONS)?;
                check_material(material)
            }
            ShapeDesc::Table {
                width,
                depth,
                height,
                material,
                ..
            } => {
                check_length("width", *width)?;
                check_length("depth", *depth)?;
                check_length("height", *height)?;
                let t = table_thickness(*width, *height);
                if !(t < *height && 2.0 * t < width.min(*depth)) {
                    return Err(format!(
                        "width {width}, depth {depth} and height {height} leave no room for the legs (top and legs are {t} thick: 4 % of the larger of width and height)"
                    ));
                }
                check_material(material)
            }
            ShapeDesc::Box {
                min, max, material, ..
            } => {
                check_point("min", *min)?;
                check_point("max", *max)?;
                if !(0..3).all(|k| min[k] < max[k]) {
                    return Err(format!(
                        "min {min:?} must be below max {max:?} on every axis"
                    ));
                }
                check_material(material)
            }
        }
    }

    /// The shape's `"name"`, if it has one.
    pub fn name(&self) -> Option<&str> {
        match self {
            ShapeDesc::Mesh { name, .. }
            | ShapeDesc::Sphere { name, .. }
            | ShapeDesc::Plane { name, .. }
            | ShapeDesc::Table { name, .. }
            | ShapeDesc::Box { name, .. } => name.as_deref(),
        }
    }

    /// The maps the shape's material names, if any (a shape with maps has one material).
    pub fn maps(&self) -> Option<&crate::material::maps::MapsDesc> {
        let m = match self {
            ShapeDesc::Mesh { material, .. }
            | ShapeDesc::Sphere { material, .. }
            | ShapeDesc::Plane { material, .. }
            | ShapeDesc::Table { material, .. }
            | ShapeDesc::Box { material, .. } => material,
        };
        m.as_ref()?.maps.as_ref()
    }

    /// Triangles the shape generates, known before generating it (`None` for a mesh file).
    pub fn triangle_count(&self) -> Option<u64> {
        let quads = |d: u64| 2 * d * d;
        match self {
            ShapeDesc::Mesh { .. } => None,
            ShapeDesc::Sphere { rings, .. } => {
                // `segments = 2 rings` slices; the pole bands have one triangle per slice.
                let r = rings.unwrap_or(DEFAULT_RINGS) as u64;
                Some(2 * (2 * r) * r.saturating_sub(1))
            }
            ShapeDesc::Plane { divisions, .. } => {
                Some(quads(divisions.unwrap_or(DEFAULT_DIVISIONS) as u64))
            }
            ShapeDesc::Box { .. } => Some(6 * quads(BOX_DIVISIONS as u64)),
            // The top (a box of 24 divisions) and four legs (12 divisions): `shapes::table`.
            ShapeDesc::Table { .. } => Some(6 * quads(24) + 4 * 6 * quads(12)),
        }
    }
}

impl EnvDesc {
    /// Check every value (see the module docs); the message names the field.
    pub fn validate(&self) -> Result<(), crate::error::Invalid> {
        self.validate_msg().map_err(crate::error::Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        let angle = |name: &str, v: Option<f32>| match v {
            Some(v) if !v.is_finite() => Err(format!("environment: {name} {v:?} must be finite")),
            _ => Ok(()),
        };
        match self {
            EnvDesc::File {
                layout,
                scale,
                rotate_y_deg,
                ..
            } => {
                if let Some(l) = layout {
                    if parse_layout(l).is_none() {
                        return Err(format!(
                            "environment: unknown layout '{l}' (latlong, cube, probe)"
                        ));
                    }
                }
                if let Some(s) = scale {
                    if !(s.is_finite() && *s >= 0.0) {
                        return Err(format!(
                            "environment: scale {s:?} must be finite and >= 0 (light is never negative)"
                        ));
                    }
                }
                angle("rotate_y_deg", *rotate_y_deg)
            }
            EnvDesc::Sky {
                sun_elevation_deg,
                sun_azimuth_deg,
                turbidity,
                ground_albedo,
                rotate_y_deg,
            } => {
                sky_params(
                    *sun_elevation_deg,
                    *sun_azimuth_deg,
                    *turbidity,
                    *ground_albedo,
                )
                .validate()
                .map_err(|m| format!("environment (sky): {m}"))?;
                angle("rotate_y_deg", *rotate_y_deg)
            }
            EnvDesc::Constant { radiance } => {
                if radiance.iter().all(|v| v.is_finite() && *v >= 0.0) {
                    Ok(())
                } else {
                    Err(format!(
                        "environment: radiance {radiance:?} must be finite and >= 0 (light is never negative)"
                    ))
                }
            }
        }
    }
}

/// Build one shape (already validated); mesh files are loaded with `opts`.
/// The maps are those of a mesh file's own materials (parallel to the materials), empty when
/// the shape has none or overrides them.
#[allow(clippy::type_complexity)]
/// A built shape: its mesh, materials, the maps its file brought, and its file's objects
/// (empty for a procedural shape, or a mesh whose objects could not be followed).
type BuiltShape = (
    TriMesh,
    Vec<Material>,
    Vec<MaterialMaps>,
    Vec<io::MeshObject>,
);

/// The objects of triangles whose objects (indices into `objects`) are `owner`, each
/// triangle become `growth` consecutive ones (midpoint subdivision); emptied objects vanish.
fn objects_of_owners(
    owner: &[usize],
    growth: usize,
    objects: &[io::MeshObject],
) -> Vec<io::MeshObject> {
    let mut out: Vec<io::MeshObject> = Vec::new();
    for (t, &k) in owner.iter().enumerate() {
        let end = ((t + 1) * growth) as u32;
        match out.last_mut() {
            Some(o) if o.name == objects[k].name => o.triangles.end = end,
            _ => out.push(io::MeshObject {
                name: objects[k].name.clone(),
                triangles: (t * growth) as u32..end,
            }),
        }
    }
    out
}

fn build_shape(s: &ShapeDesc, opts: &LoadOptions) -> Result<BuiltShape, SceneError> {
    let one =
        |m: &Option<MaterialDesc>| vec![m.as_ref().map_or_else(Material::default, |d| d.material)];
    Ok(match s {
        ShapeDesc::Mesh {
            file,
            fit,
            weld,
            material,
            subdivide,
            ..
        } => {
            let levels = subdivide.unwrap_or(0);
            let growth = 1u64 << (2 * levels);
            let budget = LoadOptions {
                max_triangles: (opts.max_triangles as u64 / growth) as usize,
                ..*opts
            };
            let loaded = io::load_mesh_with(file, &budget)?;
            // Loading carries on past recoverable problems; tell the user about each.
            for w in &loaded.warnings {
                eprintln!("warning: {w}");
            }
            let mut mesh = loaded.mesh;
            // The object of each triangle, following the triangles through welding.
            let mut owner: Vec<usize> = Vec::with_capacity(mesh.triangle_count());
            for (k, o) in loaded.objects.iter().enumerate() {
                owner.extend(o.triangles.clone().map(|_| k));
            }
            if let Some(eps) = *weld {
                mesh = meshops::weld(&mesh, eps);
                if owner.len() == mesh.indices.len() {
                    let mut tris = mesh.indices.iter();
                    owner.retain(|_| {
                        tris.next()
                            .is_some_and(|&t| !meshops::is_degenerate(&mesh, t))
                    });
                }
                meshops::drop_degenerate(&mut mesh);
                meshops::remove_unused_vertices(&mut mesh);
                mesh.normals = meshops::smooth_normals(&mesh, meshops::NormalWeighting::Angle);
            }
            for _ in 0..levels {
                mesh = meshops::subdivide_midpoint(&mesh);
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
            let (mats, maps) = match material {
                Some(m) => {
                    mesh.material_ids.iter_mut().for_each(|id| *id = 0);
                    (vec![m.material], Vec::new())
                }
                None if loaded.materials.is_empty() => {
                    mesh.material_ids.iter_mut().for_each(|id| *id = 0);
                    (vec![Material::default()], Vec::new())
                }
                None => (loaded.materials, loaded.maps),
            };
            let growth = 1usize << (2 * levels);
            let objects = if owner.len() * growth == mesh.triangle_count() {
                objects_of_owners(&owner, growth, &loaded.objects)
            } else {
                Vec::new()
            };
            (mesh, mats, maps, objects)
        }
        ShapeDesc::Sphere {
            center,
            radius,
            rings,
            material,
            ..
        } => {
            let r = rings.unwrap_or(DEFAULT_RINGS);
            (
                shapes::uv_sphere(Vec3::from(*center), *radius, r, 2 * r),
                one(material),
                Vec::new(),
                Vec::new(),
            )
        }
        ShapeDesc::Plane {
            center,
            size,
            divisions,
            material,
            ..
        } => (
            shapes::ground_plane(
                Vec3::from(*center),
                *size,
                divisions.unwrap_or(DEFAULT_DIVISIONS),
            ),
            one(material),
            Vec::new(),
            Vec::new(),
        ),
        ShapeDesc::Table {
            width,
            depth,
            height,
            material,
            ..
        } => {
            let t = table_thickness(*width, *height);
            (
                shapes::table(*width, *depth, *height, t, t),
                one(material),
                Vec::new(),
                Vec::new(),
            )
        }
        ShapeDesc::Box {
            min, max, material, ..
        } => (
            shapes::aabb_box(Vec3::from(*min), Vec3::from(*max), BOX_DIVISIONS),
            one(material),
            Vec::new(),
            Vec::new(),
        ),
    })
    .and_then(|(m, mats, maps, objects)| {
        meshops::validate(&m).map_err(|e| SceneError::invalid_mesh(shape_origin(s), e))?;
        Ok((m, mats, maps, objects))
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

/// The sky parameters of an [`EnvDesc::Sky`]'s fields.
fn sky_params(elevation: f32, azimuth: f32, turbidity: f32, albedo: [f32; 3]) -> sky::SkyParams {
    sky::SkyParams {
        sun_elevation_deg: elevation,
        sun_azimuth_deg: azimuth,
        turbidity,
        ground_albedo: Vec3::from(albedo),
        ..sky::SkyParams::default()
    }
}

/// Thickness of a table's top and legs.
fn table_thickness(width: f32, height: f32) -> f32 {
    0.04 * height.max(width)
}

/// Build the environment of a description (checked first: [`EnvDesc::validate`]; loading
/// files, rasterising the sky).
pub fn build_env(d: &EnvDesc) -> Result<Environment, SceneError> {
    d.validate()
        .map_err(|msg| SceneError::InvalidParameter { msg: msg.0 })?;
    Ok(match d {
        EnvDesc::File {
            path,
            layout,
            scale,
            rotate_y_deg,
        } => {
            let layout = layout.as_deref().and_then(parse_layout);
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
            let params = sky_params(
                *sun_elevation_deg,
                *sun_azimuth_deg,
                *turbidity,
                *ground_albedo,
            );
            Environment {
                map: sky::sun_sky_envmap(params)?,
                scale: 1.0,
                rotate_y_deg: rotate_y_deg.unwrap_or(0.0),
            }
        }
        EnvDesc::Constant { radiance } => Environment::new(EnvMap::constant(Vec3::from(*radiance))),
    })
}

pub mod model;

#[cfg(test)]
mod tests;
