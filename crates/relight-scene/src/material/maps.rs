//! Spatially varying materials: texture maps and normal maps (Cheslack-Postava et al. 2008,
//! sec. 4.2: "the BRDF parameters of each pixel are read from textures, and the normal may be
//! perturbed by a bump or normal map").
//!
//! A material may name up to five maps ([`MapsDesc`]); at a surface point of texture
//! coordinates `uv` ([`crate::texture`] states the lookup conventions):
//! * `diffuse` **multiplies** the diffuse reflectance (Lambert's `albedo`, the `diffuse` of
//!   Blinn-Phong, GGX plastic and Ward, glTF's `base_color`), per channel; sRGB-decoded when
//!   PNG;
//! * `specular` **multiplies** the specular reflectance (Blinn-Phong, GGX conductor and
//!   plastic, Ward), per channel; sRGB-decoded when PNG;
//! * `roughness` **replaces** the GGX `alpha` (conductor and plastic) by the map's first
//!   channel, raised to at least [`MIN_MAP_ALPHA`]; for the plastic, whose Fresnel tables
//!   are computed per `alpha`, it is also rounded to a multiple of 1/[`PLASTIC_ALPHA_STEPS`]
//!   (at most that many tables);
//! * `metallic_roughness` (glTF only, as glTF's `metallicRoughnessTexture`, linear): its
//!   green channel **multiplies** `roughness`, its blue channel **multiplies** `metallic`;
//! * `normal` is a **tangent-space normal map** (OpenGL convention: red = +u, green = +v,
//!   blue = the normal), stored linearly: `n_t = (2 rgb - 1) * (s, s, 1)` with `s` the
//!   `normal_scale` (default 1; glTF's `normalTexture.scale`). The shading normal becomes
//!   `normalize(n_t.x T + n_t.y B + n_t.z N)` with `N` the interpolated vertex normal, `T` the
//!   interpolated per-vertex tangent made orthogonal to `N` (Gram-Schmidt) and
//!   `B = sign N x T` ([`vertex_tangents`]). A flat map (`(0.5, 0.5, 1)`) gives `N` exactly.
//!
//! Maps on a material that has no such parameter are refused by name (a `roughness` map on a
//! Lambert material, a `diffuse` map on a conductor, a `specular` or `roughness` map on a glTF
//! material), as is a map on a mesh without texture
//! coordinates. [`shading_at`] is the one place where a material and its shading frame are
//! looked up at a surface point: the path tracer and the cuts deferred buffer both call it,
//! so they agree by construction.

use super::Material;
use crate::error::SceneError;
use crate::io::files::{self, PathPolicy};
use crate::mesh::TriMesh;
use crate::texture::{Encoding, Texture};
use crate::Vec3;
use glam::{Vec2, Vec4};
use relight_sphere::warp::Frame;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// Smallest GGX `alpha` a roughness map yields (a texel of 0 means "as smooth as allowed").
pub const MIN_MAP_ALPHA: f32 = 1e-3;
/// A roughness map's `alpha` on a GGX plastic is rounded to a multiple of `1 / 256`.
pub const PLASTIC_ALPHA_STEPS: f32 = 256.0;

/// The maps a material names (paths as written; relative ones are resolved against the
/// folder of the JSON file that names them, and must stay inside it unless
/// [`PathPolicy::allow_outside`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapsDesc {
    /// Multiplies the diffuse reflectance (PNG sRGB, EXR linear).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diffuse: Option<String>,
    /// Multiplies the specular reflectance (PNG sRGB, EXR linear).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub specular: Option<String>,
    /// Replaces the GGX `alpha` (first channel, linear).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roughness: Option<String>,
    /// glTF only: green multiplies `roughness`, blue multiplies `metallic` (linear).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metallic_roughness: Option<String>,
    /// Tangent-space normal map (linear, `2 rgb - 1`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<String>,
    /// Scale of the normal map's `x` and `y` (glTF's `normalTexture.scale`; default 1).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub normal_scale: f32,
}

fn one() -> f32 {
    1.0
}

fn is_one(v: &f32) -> bool {
    *v == 1.0
}

impl Default for MapsDesc {
    fn default() -> Self {
        MapsDesc {
            diffuse: None,
            specular: None,
            roughness: None,
            metallic_roughness: None,
            normal: None,
            normal_scale: 1.0,
        }
    }
}

/// A material as a scene or material file writes it: the constant [`Material`] and, in the
/// same JSON object, optional `"maps"`:
/// `{"type": "ggx_plastic", "diffuse": [1, 1, 1], ..., "maps": {"diffuse": "albedo.png"}}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialDesc {
    /// The constant parameters (what the maps multiply or replace).
    #[serde(flatten)]
    pub material: Material,
    /// The maps, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub maps: Option<MapsDesc>,
}

impl From<Material> for MaterialDesc {
    fn from(material: Material) -> Self {
        MaterialDesc {
            material,
            maps: None,
        }
    }
}

/// The loaded maps of one material (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialMaps {
    /// Multiplies the diffuse reflectance.
    pub diffuse: Option<Texture>,
    /// Multiplies the specular reflectance.
    pub specular: Option<Texture>,
    /// Replaces the GGX `alpha`.
    pub roughness: Option<Texture>,
    /// glTF: green multiplies `roughness`, blue multiplies `metallic`.
    pub metallic_roughness: Option<Texture>,
    /// Tangent-space normal map.
    pub normal: Option<Texture>,
    /// Scale of the normal map's `x` and `y` (1 by default).
    pub normal_scale: f32,
}

impl Default for MaterialMaps {
    fn default() -> Self {
        MaterialMaps {
            diffuse: None,
            specular: None,
            roughness: None,
            metallic_roughness: None,
            normal: None,
            normal_scale: 1.0,
        }
    }
}

/// Which map names a material accepts, or why not.
fn check_applies(m: &Material, which: &str) -> Result<(), String> {
    let ok = match (which, m) {
        ("normal", _) => true,
        ("diffuse", Material::GgxConductor { .. }) => false,
        ("diffuse", _) => true,
        ("specular", Material::Lambert { .. } | Material::Gltf { .. }) => false,
        ("specular", _) => true,
        ("roughness", Material::GgxConductor { .. } | Material::GgxPlastic { .. }) => true,
        ("metallic_roughness", Material::Gltf { .. }) => true,
        _ => false,
    };
    if ok {
        Ok(())
    } else {
        let kind = serde_json::to_value(m)
            .ok()
            .and_then(|v| v.get("type").and_then(|t| t.as_str().map(String::from)))
            .unwrap_or_default();
        Err(format!(
            "a {which} map on a {kind} material: it has no such parameter (diffuse: all but ggx_conductor; specular: all but lambert and gltf; roughness: ggx_conductor, ggx_plastic; metallic_roughness: gltf)"
        ))
    }
}

/// The kinds of map, in the order of [`MaterialMaps::textures`].
pub const MAP_KINDS: [&str; 5] = [
    "diffuse",
    "specular",
    "roughness",
    "normal",
    "metallic_roughness",
];

impl MaterialMaps {
    /// The five maps in the order of [`MAP_KINDS`].
    pub fn textures(&self) -> [&Option<Texture>; 5] {
        [
            &self.diffuse,
            &self.specular,
            &self.roughness,
            &self.normal,
            &self.metallic_roughness,
        ]
    }

    /// The five maps in the order of [`MAP_KINDS`], to fill in.
    pub fn textures_mut(&mut self) -> [&mut Option<Texture>; 5] {
        [
            &mut self.diffuse,
            &mut self.specular,
            &mut self.roughness,
            &mut self.normal,
            &mut self.metallic_roughness,
        ]
    }

    /// Load the maps `desc` names for `material`: each path is resolved against the folder of
    /// `origin` (the JSON file naming it) under `policy` ([`files::resolve_model_ref`]) and
    /// read as a [`Texture`]. Errors name the file (or `origin` and the map) and the problem
    /// (a `normal_scale` that is not finite is refused).
    pub fn load(
        desc: &MapsDesc,
        material: &Material,
        origin: &Path,
        policy: &PathPolicy,
    ) -> Result<MaterialMaps, SceneError> {
        let load = |which: &str, p: &Option<String>, enc: Encoding| match p {
            None => Ok(None),
            Some(p) => {
                check_applies(material, which)
                    .map_err(|m| SceneError::malformed(origin, format!("maps.{which}: {m}")))?;
                let path = files::resolve_model_ref(origin, p, policy, &format!("maps.{which}"))?;
                Texture::read(&path, enc).map(Some)
            }
        };
        if !desc.normal_scale.is_finite() {
            return Err(SceneError::malformed(
                origin,
                format!("maps.normal_scale {} must be finite", desc.normal_scale),
            ));
        }
        Ok(MaterialMaps {
            diffuse: load("diffuse", &desc.diffuse, Encoding::Colour)?,
            specular: load("specular", &desc.specular, Encoding::Colour)?,
            roughness: load("roughness", &desc.roughness, Encoding::Data)?,
            metallic_roughness: load(
                "metallic_roughness",
                &desc.metallic_roughness,
                Encoding::Data,
            )?,
            normal: load("normal", &desc.normal, Encoding::Data)?,
            normal_scale: desc.normal_scale,
        })
    }

    /// `m` with the maps applied at `uv` (module docs). The result passes
    /// [`Material::validate`] when `m` does: maps only scale reflectances by `[0, 1]` and
    /// give an `alpha` in `[MIN_MAP_ALPHA, 1]`, and scale glTF factors by `[0, 1]`.
    pub fn apply(&self, m: Material, uv: Vec2) -> Material {
        let d = self.diffuse.as_ref().map_or(Vec3::ONE, |t| t.lookup(uv));
        let s = self.specular.as_ref().map_or(Vec3::ONE, |t| t.lookup(uv));
        let a = |alpha: f32| {
            self.roughness
                .as_ref()
                .map_or(alpha, |t| t.lookup(uv).x.max(MIN_MAP_ALPHA))
        };
        match m {
            Material::Lambert { albedo } => Material::Lambert { albedo: albedo * d },
            Material::BlinnPhong {
                diffuse,
                specular,
                exponent,
            } => Material::BlinnPhong {
                diffuse: diffuse * d,
                specular: specular * s,
                exponent,
            },
            Material::GgxConductor { specular, alpha } => Material::GgxConductor {
                specular: specular * s,
                alpha: a(alpha),
            },
            Material::GgxPlastic {
                diffuse,
                specular,
                alpha,
                ior,
            } => Material::GgxPlastic {
                diffuse: diffuse * d,
                specular: specular * s,
                alpha: if self.roughness.is_some() {
                    ((a(alpha) * PLASTIC_ALPHA_STEPS).round() / PLASTIC_ALPHA_STEPS)
                        .max(MIN_MAP_ALPHA)
                } else {
                    alpha
                },
                ior,
            },
            Material::Ward {
                diffuse,
                specular,
                alpha_x,
                alpha_y,
                tangent,
            } => Material::Ward {
                diffuse: diffuse * d,
                specular: specular * s,
                alpha_x,
                alpha_y,
                tangent,
            },
            Material::Gltf {
                base_color,
                metallic,
                roughness,
            } => {
                let mr = self
                    .metallic_roughness
                    .as_ref()
                    .map_or(Vec3::ONE, |t| t.lookup(uv));
                Material::Gltf {
                    base_color: base_color * d,
                    metallic: metallic * mr.z,
                    roughness: roughness * mr.y,
                }
            }
        }
    }

    /// The shading normal at `uv` given the unit normal `n` and the tangent `t` (not
    /// necessarily orthogonal to `n`) with its handedness `sign` (module docs); `n` without a
    /// normal map.
    pub fn perturb_normal(&self, uv: Vec2, n: Vec3, t: Vec3, sign: f32) -> Vec3 {
        let Some(map) = &self.normal else {
            return n;
        };
        let s = self.normal_scale;
        let c = (map.lookup(uv) * 2.0 - Vec3::ONE) * Vec3::new(s, s, 1.0);
        if c.x == 0.0 && c.y == 0.0 && c.z > 0.0 {
            return n; // a flat texel: exactly the normal
        }
        let (t, b) = tangent_frame(n, t, sign);
        let p = (t * c.x + b * c.y + n * c.z).normalize_or_zero();
        if p == Vec3::ZERO {
            n
        } else {
            p
        }
    }
}

/// The orthonormal tangent and bitangent at unit normal `n` from the interpolated tangent
/// `t` (Gram-Schmidt) and handedness `sign`: `(T, sign n x T)`. A tangent along `n` (or zero)
/// falls back to [`Frame::from_normal`]'s.
pub fn tangent_frame(n: Vec3, t: Vec3, sign: f32) -> (Vec3, Vec3) {
    let t = (t - n * n.dot(t)).normalize_or_zero();
    let t = if t == Vec3::ZERO {
        Frame::from_normal(n).s
    } else {
        t
    };
    (t, n.cross(t) * sign)
}

/// Per-vertex tangents of `mesh` from its texture coordinates (Lengyel's method): each
/// triangle's `dP/du` and `dP/dv` from its edges and UV differences, summed per vertex
/// (degenerate UV triangles skipped), made orthogonal to the vertex normal (Gram-Schmidt)
/// and unit; `w` is the handedness, `+1` when `(T, dP/dv, N)` is right-handed
/// (`N x T . dP/dv >= 0`), else `-1`. A vertex without a usable tangent gets
/// [`Frame::from_normal`]'s `s`. `None` without UVs.
pub fn vertex_tangents(mesh: &TriMesh) -> Option<Vec<Vec4>> {
    let uvs = mesh.uvs.as_ref()?;
    let n = mesh.vertex_count();
    let (mut tu, mut tv) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    for tri in &mesh.indices {
        let [a, b, c] = tri.map(|i| i as usize);
        let (e1, e2) = (
            mesh.positions[b] - mesh.positions[a],
            mesh.positions[c] - mesh.positions[a],
        );
        let (d1, d2) = (uvs[b] - uvs[a], uvs[c] - uvs[a]);
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() < 1e-20 || !det.is_finite() {
            continue;
        }
        let r = 1.0 / det;
        let du = (e1 * d2.y - e2 * d1.y) * r;
        let dv = (e2 * d1.x - e1 * d2.x) * r;
        if !(du.is_finite() && dv.is_finite()) {
            continue;
        }
        for v in [a, b, c] {
            tu[v] += du;
            tv[v] += dv;
        }
    }
    Some(
        (0..n)
            .map(|v| {
                let nv = mesh.normals[v];
                let (t, _) = tangent_frame(nv, tu[v], 1.0);
                let sign = if nv.cross(t).dot(tv[v]) < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                t.extend(sign)
            })
            .collect(),
    )
}

/// The maps of a scene's materials and what they need of its mesh.
#[derive(Clone, Debug, Default)]
pub struct SceneMaps {
    /// Per material (parallel to `Scene::materials`); empty or `None`: constant.
    per_material: Vec<Option<Arc<MaterialMaps>>>,
    /// Per-vertex tangents with handedness ([`vertex_tangents`]); empty when no material
    /// has a normal map. Shared, so a clone (a frame's shader) copies no per-vertex data.
    tangents: Arc<[Vec4]>,
}

impl SceneMaps {
    /// The maps `per_material` (parallel to the scene's materials) over `mesh`.
    ///
    /// # Errors
    /// A message when a triangle whose material has maps belongs to a mesh without texture
    /// coordinates.
    pub fn new(
        mesh: &TriMesh,
        per_material: Vec<Option<Arc<MaterialMaps>>>,
    ) -> Result<SceneMaps, String> {
        if per_material.iter().all(Option::is_none) {
            return Ok(SceneMaps::default());
        }
        if mesh.uvs.is_none() {
            return Err("a material has maps but the mesh has no texture coordinates (uvs)".into());
        }
        let normal = per_material
            .iter()
            .any(|m| m.as_ref().is_some_and(|m| m.normal.is_some()));
        let tangents = if normal {
            vertex_tangents(mesh).unwrap_or_default()
        } else {
            Vec::new()
        }
        .into();
        Ok(SceneMaps {
            per_material,
            tangents,
        })
    }

    /// The maps of material `id`, if any.
    #[inline]
    pub fn of(&self, id: u32) -> Option<&MaterialMaps> {
        self.per_material.get(id as usize)?.as_deref()
    }

    /// Number of materials the maps were given for (`of` is `None` at and beyond it).
    pub fn len(&self) -> usize {
        self.per_material.len()
    }

    /// Whether no material has maps.
    pub fn is_empty(&self) -> bool {
        self.per_material.iter().all(Option::is_none)
    }
}

/// The material and shading frame at barycentrics `bary` of triangle `tri` of `mesh`, whose
/// interpolated unit shading normal is `n`: the constant material and its
/// [`Material::shading_frame`] without maps; with maps, the material with its maps applied
/// and the frame of the perturbed normal (module docs). The one lookup the path tracer and
/// the cuts renderer share.
///
/// # Panics
/// If `tri` or its material id is out of range of `mesh` and `materials`.
#[inline]
pub fn shading_at(
    mesh: &TriMesh,
    materials: &[Material],
    maps: &SceneMaps,
    tri: u32,
    bary: [f32; 3],
    n: Vec3,
) -> (Material, Frame) {
    let id = mesh.material_ids[tri as usize];
    let m = materials[id as usize];
    let (Some(mm), Some(uvs)) = (maps.of(id), mesh.uvs.as_ref()) else {
        return (m, m.shading_frame(n));
    };
    let corners = mesh.indices[tri as usize].map(|v| v as usize);
    let lerp2 = |a: [Vec2; 3]| a[0] * bary[0] + a[1] * bary[1] + a[2] * bary[2];
    let uv = lerp2(corners.map(|v| uvs[v]));
    let m = mm.apply(m, uv);
    let n = match (&mm.normal, maps.tangents.is_empty()) {
        (Some(_), false) => {
            let t = corners.map(|v| maps.tangents[v]);
            let tangent = t[0] * bary[0] + t[1] * bary[1] + t[2] * bary[2];
            let sign = if tangent.w < 0.0 { -1.0 } else { 1.0 };
            mm.perturb_normal(uv, n, tangent.truncate(), sign)
        }
        _ => n,
    };
    (m, m.shading_frame(n))
}

#[cfg(test)]
mod tests;
