//! What every bundle holds whatever its method, and checked access to its tensors.
//!
//! # Bundle schema (docs/BUNDLE.md has the full table)
//! Metadata (strings, JSON where structured):
//! * `method`: the bake kind, `sh`, `sg`, `cuts` or `vmf` ([`crate::BakeKind::name`]);
//! * `schema`: `2` since the method seam (absent in older bundles, which still load:
//!   `legacy_record` and each method's settings migration read them);
//! * `relight_version`: the crate version that wrote it;
//! * `settings`: the method's settings (its `Method::Settings`, serde), written once;
//! * `record`: how the bake ran ([`BakeRecord`]: back-end, storage precision, and for a part
//!   of a sharded bake its vertex range and part number; no time, so a bake's bytes are
//!   reproducible);
//! * `scene`, `materials`: the scene description and the merged scene's materials;
//! * `objects`: the named objects, `[{"name", "first", "count"}]` over the triangles
//!   ([`BakedScene::objects`]; absent in older bundles: [`objects_of_materials`]).
//!
//! Tensors shared by every method: `positions [V, 3]`, `normals [V, 3]`, optional
//! `uvs [V, 2]` (F32), `indices [T, 3]`, `material_ids [T]` (U32), and the materials' texture
//! and normal maps, `map_<material>_<kind> [H, W, 3]` (F32 linear texels, `kind` one of
//! `diffuse`, `specular`, `roughness`, `normal`; see `relight_scene::material::maps`), each with
//! its sampler and `KHR_texture_transform` in `map_<material>_<kind>_sampling [8]` (F32:
//! `wrap_s, wrap_t, filter, offset.x, offset.y, rotation, scale.x, scale.y`, wrap codes
//! [`WRAP_CODES`], filter codes [`FILTER_CODES`]) written only when they are not the
//! defaults (repeat, linear, no transform; an identity transform counts as none), so a bundle
//! of plain textures has no such tensor. Each method adds its own,
//! prefixed by nothing for `sh` (`albedo`, `transfer`) and by its name for the others (`sg_`,
//! `cuts_`, `vmf_`).

use crate::MethodError;
use glam::{Vec2, Vec3};
use relight_bundle::{Bundle, Tensor};
use relight_scene::material::maps::{MaterialMaps, SceneMaps, MAP_KINDS};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::{validate_objects, SceneObject};
use relight_scene::scene_file::SceneDesc;
use relight_scene::texture::{Filter, Sampler, Texture, UvTransform, Wrap, MAX_TEXTURE_PIXELS};
use serde::{de::DeserializeOwned, Deserialize, Serialize};
use std::ops::Range;
use std::path::Path;
use std::sync::Arc;

/// Value of the `schema` metadata key written by this version.
pub const SCHEMA: u32 = 2;

/// Largest finite f16: values stored as f16 are clamped to it.
pub const F16_MAX: f32 = 65504.0;

/// How a bake ran: recorded beside its settings, never an input of the bake. Nothing in it
/// depends on when or where the bake ran, so the same bake always writes the same bytes (what
/// [`crate::shard::merge`] relies on).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeRecord {
    /// Ray-casting back-end (`embree`, `bvh`).
    pub backend: String,
    /// Wall time of the bake, seconds: reported by whoever baked, not written to bundles
    /// (read back as 0; older bundles that hold it still read it).
    #[serde(skip_serializing, default)]
    pub seconds: f64,
    /// Whether the method's float tensors are stored as f16.
    pub f16: bool,
    /// The vertices baked, when the bundle is one part of a sharded bake (`None`: all).
    #[serde(default)]
    pub range: Option<(usize, usize)>,
    /// Which part of a sharded bake this is (`None`: a whole bake).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<crate::shard::Shard>,
}

impl BakeRecord {
    /// Check that the bundle is a whole bake, not a part of a sharded one.
    ///
    /// # Errors
    /// [`MethodError::PartialBake`] for a part bundle.
    pub fn require_whole(&self, path: &Path, vertices: usize) -> Result<(), MethodError> {
        let part = |what: String| {
            Err(MethodError::PartialBake {
                path: path.to_path_buf(),
                part: what,
            })
        };
        match (self.range, self.shard) {
            (Some((start, end)), _) if (start, end) != (0, vertices) => part(format!(
                "a part bundle (vertices {start}..{end} of {vertices})"
            )),
            (_, Some(s)) if s.count > 1 => {
                part(format!("part {}/{} of a sharded bake", s.index, s.count))
            }
            _ => Ok(()),
        }
    }

    /// The record of a bake of `range` over `vertices` vertices.
    pub fn new(
        backend: &str,
        seconds: f64,
        f16: bool,
        range: &Range<usize>,
        vertices: usize,
    ) -> Self {
        BakeRecord {
            backend: backend.into(),
            seconds,
            f16,
            range: (*range != (0..vertices)).then_some((range.start, range.end)),
            shard: None,
        }
    }
}

/// The scene part of every bake: what it was made from.
#[derive(Clone, Debug)]
pub struct BakedScene {
    /// The scene description (its environment and camera are the defaults for rendering).
    pub desc: SceneDesc,
    /// The merged mesh.
    pub mesh: TriMesh,
    /// The scene's materials, indexed by `mesh.material_ids`.
    pub materials: Vec<Material>,
    /// Their texture and normal maps (stored as tensors `map_<material>_<kind>`).
    pub maps: SceneMaps,
    /// The named objects, covering the triangles in order (metadata `objects`; stored as
    /// [`objects_of_materials`] when empty).
    pub objects: Vec<SceneObject>,
}

/// One entry of the `objects` metadata: an object's name and triangles `first..first + count`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct StoredObject {
    name: String,
    first: u32,
    count: u32,
}

/// The objects of a scene without names (built in code, or a bundle written before the
/// `objects` key): when every material's triangles are one contiguous run, one object per
/// run named `material<index>`; otherwise one object `scene`.
pub fn objects_of_materials(mesh: &TriMesh) -> Vec<SceneObject> {
    let mut runs: Vec<(u32, Range<u32>)> = Vec::new();
    for (t, &m) in mesh.material_ids.iter().enumerate() {
        match runs.last_mut() {
            Some((id, r)) if *id == m => r.end = t as u32 + 1,
            _ => runs.push((m, t as u32..t as u32 + 1)),
        }
    }
    let mut ids: Vec<u32> = runs.iter().map(|r| r.0).collect();
    ids.sort_unstable();
    ids.dedup();
    if ids.len() != runs.len() || runs.is_empty() {
        let name = "scene".to_string();
        return vec![SceneObject {
            name,
            triangles: 0..mesh.triangle_count() as u32,
        }];
    }
    runs.into_iter()
        .map(|(m, triangles)| SceneObject {
            name: format!("material{m}"),
            triangles,
        })
        .collect()
}

impl BakedScene {
    /// The scene part of a bake of `input`.
    pub fn of(input: &crate::BakeInput) -> BakedScene {
        BakedScene {
            desc: input.desc.clone(),
            mesh: input.scene.mesh.clone(),
            materials: input.scene.materials.clone(),
            maps: input.scene.maps.clone(),
            objects: if input.scene.objects.is_empty() {
                objects_of_materials(&input.scene.mesh)
            } else {
                input.scene.objects.clone()
            },
        }
    }

    /// Metadata and tensors of the scene part, with the method name, schema, version,
    /// settings and record.
    pub(crate) fn store<S: Serialize>(
        &self,
        b: &mut Bundle,
        method: &str,
        settings: &S,
        record: &BakeRecord,
    ) -> Result<(), MethodError> {
        let mut meta = |k: &str, v: String| b.metadata.insert(k.into(), v);
        meta("method", method.into());
        meta("schema", SCHEMA.to_string());
        meta("relight_version", env!("CARGO_PKG_VERSION").into());
        meta("settings", json(settings)?);
        meta("record", json(record)?);
        // A scene built in code without names is stored as one without the key reads.
        let unnamed = objects_of_materials(&self.mesh);
        let named = if self.objects.is_empty() {
            &unnamed
        } else {
            &self.objects
        };
        let objects: Vec<StoredObject> = named
            .iter()
            .map(|o| StoredObject {
                name: o.name.clone(),
                first: o.triangles.start,
                count: o.triangles.len() as u32,
            })
            .collect();
        meta("objects", json(&objects)?);
        self.store_scene(b)
    }

    /// The scene part's bytes (description, materials, mesh tensors): equal for two bakes
    /// exactly when they were made from the same scene.
    ///
    /// # Errors
    /// [`MethodError::Settings`] if the description cannot be recorded.
    pub fn fingerprint(&self) -> Result<Vec<u8>, MethodError> {
        let mut b = Bundle::new();
        self.store_scene(&mut b)?;
        Ok(b.to_bytes())
    }

    /// Metadata `scene`, `materials` and the mesh tensors.
    fn store_scene(&self, b: &mut Bundle) -> Result<(), MethodError> {
        let mut meta = |k: &str, v: String| b.metadata.insert(k.into(), v);
        meta("scene", json(&self.desc)?);
        meta("materials", json(&self.materials)?);
        let m = &self.mesh;
        let (v, t) = (m.vertex_count(), m.triangle_count());
        b.insert(
            "positions",
            Tensor::from_f32(vec![v, 3], &flat3(&m.positions)),
        );
        b.insert("normals", Tensor::from_f32(vec![v, 3], &flat3(&m.normals)));
        if let Some(uv) = &m.uvs {
            let f: Vec<f32> = uv.iter().flat_map(|p| p.to_array()).collect();
            b.insert("uvs", Tensor::from_f32(vec![v, 2], &f));
        }
        let idx: Vec<u32> = m.indices.iter().flatten().copied().collect();
        b.insert("indices", Tensor::from_u32(vec![t, 3], &idx));
        b.insert("material_ids", Tensor::from_u32(vec![t], &m.material_ids));
        for i in 0..self.maps.len() {
            let Some(maps) = self.maps.of(i as u32) else {
                continue;
            };
            for (kind, tex) in MAP_KINDS.iter().zip(maps.textures()) {
                if let Some(tex) = tex {
                    b.insert(
                        &format!("map_{i}_{kind}"),
                        Tensor::from_f32(vec![tex.height(), tex.width(), 3], &flat3(tex.texels())),
                    );
                    if let Some(s) = encode_sampling(tex) {
                        b.insert(
                            &format!("map_{i}_{kind}_{SAMPLING}"),
                            Tensor::from_f32(vec![8], &s),
                        );
                    }
                }
            }
            if maps.normal_scale != 1.0 {
                b.insert(
                    &format!("map_{i}_{NORMAL_SCALE}"),
                    Tensor::from_f32(vec![1], &[maps.normal_scale]),
                );
            }
        }
        Ok(())
    }

    /// The maps of the tensors `map_<material>_<kind>` (`[H, W, 3]` F32), each checked as a
    /// texture is when read from a file, with its `map_<material>_<kind>_sampling` (`[8]` F32,
    /// module docs; defaults when absent), and `map_<material>_normal_scale` (`[1]` F32,
    /// finite; 1 when absent); a map of a material that does not exist, of an unknown kind, on
    /// a mesh without texture coordinates, or a sampling tensor without its map or with an
    /// unknown code is refused by name.
    fn load_maps(
        r: &TensorReader,
        mesh: &TriMesh,
        materials: usize,
    ) -> Result<SceneMaps, MethodError> {
        let mut per_material: Vec<Option<MaterialMaps>> = vec![None; materials];
        // Sampling tensors, applied once every map is read: (name, material, kind index).
        let mut samplings = Vec::new();
        let parse_map = |rest: &str| {
            rest.split_once('_').and_then(|(i, kind)| {
                let i: usize = i.parse().ok()?;
                let k = MAP_KINDS.iter().position(|&m| m == kind)?;
                (i < materials).then_some((i, k))
            })
        };
        for name in r.b.tensors.keys().filter(|k| k.starts_with("map_")) {
            let sampling_of = name["map_".len()..]
                .strip_suffix(&format!("_{SAMPLING}"))
                .and_then(parse_map);
            if let Some((i, k)) = sampling_of {
                samplings.push((name, i, k));
                continue;
            }
            let scale_of = name["map_".len()..]
                .strip_suffix(&format!("_{NORMAL_SCALE}"))
                .and_then(|i| i.parse::<usize>().ok())
                .filter(|&i| i < materials);
            if let Some(i) = scale_of {
                let s = r.f32s(name, &[1])?[0];
                per_material[i]
                    .get_or_insert_with(MaterialMaps::default)
                    .normal_scale = s;
                continue;
            }
            let Some((i, k)) = parse_map(&name["map_".len()..]) else {
                return Err(r.invalid(format!(
                    "tensor '{name}' is not a map of one of the {materials} materials (map_<material>_<{}>[_{SAMPLING}])",
                    MAP_KINDS.join("|")
                )));
            };
            let shape = &r.b.tensors[name].shape;
            let &[h, w, 3] = shape.as_slice() else {
                return Err(r.invalid(format!(
                    "tensor '{name}' has shape {shape:?}, expected [H, W, 3]"
                )));
            };
            // The texture limits, before converting (the tensor is in memory already).
            if w.checked_mul(h).is_none_or(|n| n > MAX_TEXTURE_PIXELS) {
                return Err(r.invalid(format!(
                    "tensor '{name}': {w} x {h} texels exceed the texture limit"
                )));
            }
            let texels = unflat3(&r.f32s(name, &[h, w, 3])?);
            let tex = Texture::new(w, h, texels)
                .map_err(|e| r.invalid(format!("tensor '{name}': {e}")))?;
            *per_material[i]
                .get_or_insert_with(MaterialMaps::default)
                .textures_mut()[k] = Some(tex);
        }
        for (name, i, k) in samplings {
            let v = r.f32s(name, &[8])?;
            let (sampler, transform) =
                decode_sampling(&v).map_err(|e| r.invalid(format!("tensor '{name}': {e}")))?;
            let slot = per_material[i]
                .as_mut()
                .and_then(|m| m.textures_mut().into_iter().nth(k))
                .and_then(|t| t.as_mut())
                .ok_or_else(|| {
                    r.invalid(format!(
                        "tensor '{name}' has no map 'map_{i}_{}' to apply to",
                        MAP_KINDS[k]
                    ))
                })?;
            *slot = slot.clone().with_sampler(sampler).with_transform(transform);
        }
        let per_material = per_material.into_iter().map(|m| m.map(Arc::new)).collect();
        SceneMaps::new(mesh, per_material).map_err(|e| r.invalid(e))
    }

    /// Read and check the scene part of a bundle read from `path`.
    pub(crate) fn load(r: &TensorReader) -> Result<BakedScene, MethodError> {
        let desc: SceneDesc = r.json("scene")?;
        desc.validate()
            .map_err(|e| r.invalid(format!("metadata 'scene': {e}")))?;
        let materials: Vec<Material> = r.json("materials")?;
        for m in &materials {
            m.validate()
                .map_err(|e| r.invalid(format!("material {m:?}: {e}")))?;
        }
        let mesh = r.mesh(materials.len())?;
        let maps = Self::load_maps(r, &mesh, materials.len())?;
        let objects = Self::load_objects(r, &mesh)?;
        Ok(BakedScene {
            desc,
            mesh,
            materials,
            maps,
            objects,
        })
    }

    /// The `objects` metadata, checked against the mesh ([`validate_objects`]); absent (an
    /// older bundle): [`objects_of_materials`].
    fn load_objects(r: &TensorReader, mesh: &TriMesh) -> Result<Vec<SceneObject>, MethodError> {
        if !r.has_meta("objects") {
            return Ok(objects_of_materials(mesh));
        }
        let stored: Vec<StoredObject> = r.json("objects")?;
        let objects: Vec<SceneObject> = stored
            .into_iter()
            .map(|o| SceneObject {
                triangles: o.first..o.first.saturating_add(o.count),
                name: o.name,
            })
            .collect();
        validate_objects(&objects, mesh.triangle_count() as u32)
            .map_err(|e| r.invalid(format!("metadata 'objects': {e}")))?;
        Ok(objects)
    }
}

/// The kind name of the tensor holding a material's normal-map scale (`map_<m>_normal_scale`).
const NORMAL_SCALE: &str = "normal_scale";

/// The kind suffix of the tensor holding a map's sampler and transform
/// (`map_<m>_<kind>_sampling`).
const SAMPLING: &str = "sampling";

/// Wrap modes in the order of their codes in a sampling tensor (0, 1, 2).
pub const WRAP_CODES: [Wrap; 3] = [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat];

/// Filters in the order of their codes in a sampling tensor (0, 1).
pub const FILTER_CODES: [Filter; 2] = [Filter::Linear, Filter::Nearest];

/// The sampling tensor of a texture (module docs), `None` when sampler and transform are
/// the defaults (an identity transform counts as none: it reads the same texels).
fn encode_sampling(tex: &Texture) -> Option<[f32; 8]> {
    let s = tex.sampler();
    let t = tex.transform().filter(|t| *t != UvTransform::default());
    if s == Sampler::default() && t.is_none() {
        return None;
    }
    let code = |w: Wrap| WRAP_CODES.iter().position(|&c| c == w).unwrap_or(0) as f32;
    let t = t.unwrap_or_default();
    Some([
        code(s.wrap_s),
        code(s.wrap_t),
        FILTER_CODES
            .iter()
            .position(|&f| f == s.filter)
            .unwrap_or(0) as f32,
        t.offset.x,
        t.offset.y,
        t.rotation,
        t.scale.x,
        t.scale.y,
    ])
}

/// The sampler and transform of a sampling tensor's finite values (an identity transform
/// gives `None`), or a message naming the bad element.
fn decode_sampling(v: &[f32]) -> Result<(Sampler, Option<UvTransform>), String> {
    let code = |i: usize, what: &str, n: usize| {
        let c = v[i];
        if c.fract() == 0.0 && c >= 0.0 && (c as usize) < n {
            Ok(c as usize)
        } else {
            Err(format!(
                "element {i} ({what}) is {c}, expected a code in 0..{n}"
            ))
        }
    };
    let sampler = Sampler {
        wrap_s: WRAP_CODES[code(0, "wrap_s", WRAP_CODES.len())?],
        wrap_t: WRAP_CODES[code(1, "wrap_t", WRAP_CODES.len())?],
        filter: FILTER_CODES[code(2, "filter", FILTER_CODES.len())?],
    };
    let t = UvTransform {
        offset: Vec2::new(v[3], v[4]),
        rotation: v[5],
        scale: Vec2::new(v[6], v[7]),
    };
    Ok((sampler, (t != UvTransform::default()).then_some(t)))
}

/// JSON text of a value to record, with a typed error.
pub(crate) fn json<S: Serialize>(v: &S) -> Result<String, MethodError> {
    serde_json::to_string(v).map_err(|e| MethodError::Settings(format!("cannot record: {e}")))
}

/// `[x, y, z]` triples flattened.
pub(crate) fn flat3(v: &[Vec3]) -> Vec<f32> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

/// Flat floats as `Vec3`s.
pub(crate) fn unflat3(v: &[f32]) -> Vec<Vec3> {
    v.chunks_exact(3).map(Vec3::from_slice).collect()
}

/// A float tensor, as f16 (clamped to its range) or f32.
pub(crate) fn float_tensor(shape: Vec<usize>, data: &[f32], f16: bool) -> Tensor {
    if f16 {
        let c: Vec<f32> = data.iter().map(|x| x.clamp(-F16_MAX, F16_MAX)).collect();
        Tensor::from_f32_as_f16(shape, &c)
    } else {
        Tensor::from_f32(shape, data)
    }
}

/// The record of a bundle written before the `record` key existed (schema 1): its
/// `settings` object held `backend`, `seconds` and `f16` beside the method's settings.
pub(crate) fn legacy_record(r: &TensorReader) -> Result<BakeRecord, MethodError> {
    r.json("settings")
}

/// Checked access to the metadata and tensors of a bundle read from `path` (named in every
/// error).
pub(crate) struct TensorReader<'a> {
    /// The bundle.
    pub b: &'a Bundle,
    /// Where it was read from.
    pub path: &'a Path,
}

impl<'a> TensorReader<'a> {
    /// An [`MethodError::Invalid`] naming the bundle.
    pub fn invalid(&self, message: impl Into<String>) -> MethodError {
        MethodError::invalid(self.path, message)
    }

    /// Whether the bundle predates the `schema` key.
    pub fn is_legacy(&self) -> bool {
        !self.b.metadata.contains_key("schema")
    }

    /// Whether the bundle holds metadata `key`.
    pub fn has_meta(&self, key: &str) -> bool {
        self.b.metadata.contains_key(key)
    }

    /// A required metadata string.
    pub fn meta(&self, key: &str) -> Result<&'a str, MethodError> {
        Ok(self.b.meta(self.path, key)?)
    }

    /// A required JSON metadata value.
    pub fn json<T: DeserializeOwned>(&self, key: &str) -> Result<T, MethodError> {
        serde_json::from_str(self.meta(key)?)
            .map_err(|e| self.invalid(format!("metadata '{key}' is not valid: {e}")))
    }

    /// The bake record (schema 2), or the one of a legacy bundle.
    pub fn record(&self) -> Result<BakeRecord, MethodError> {
        let r: BakeRecord = if self.is_legacy() {
            legacy_record(self)?
        } else {
            self.json("record")?
        };
        if let Some(s) = r.shard {
            if !(1..=crate::shard::MAX_SHARDS).contains(&s.count) || s.index >= s.count {
                return Err(self.invalid(format!(
                    "record: part {}/{} is not a valid part number",
                    s.index, s.count
                )));
            }
        }
        Ok(r)
    }

    /// A required tensor of the expected shape.
    pub fn shaped(&self, name: &str, shape: &[usize]) -> Result<&'a Tensor, MethodError> {
        let t = self.b.tensor(self.path, name)?;
        if t.shape != shape {
            return Err(self.invalid(format!(
                "tensor '{name}' has shape {:?}, expected {shape:?}",
                t.shape
            )));
        }
        Ok(t)
    }

    /// A floating-point tensor of the expected shape, every value finite.
    pub fn f32s(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>, MethodError> {
        let v = self
            .shaped(name, shape)?
            .to_f32()
            .ok_or_else(|| self.invalid(format!("tensor '{name}' is not floating point")))?;
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(self.invalid(format!(
                "tensor '{name}' has a non-finite value at element {i}"
            )));
        }
        Ok(v)
    }

    /// A U32 tensor of the expected shape.
    pub fn u32s(&self, name: &str, shape: &[usize]) -> Result<Vec<u32>, MethodError> {
        self.shaped(name, shape)?
            .to_u32()
            .ok_or_else(|| self.invalid(format!("tensor '{name}' is not U32")))
    }

    /// The first dimension of a tensor.
    pub fn rows(&self, name: &str) -> Result<usize, MethodError> {
        Ok(self
            .b
            .tensor(self.path, name)?
            .shape
            .first()
            .copied()
            .unwrap_or(0))
    }

    /// The mesh tensors (positions, normals, optional uvs, indices, material ids), checked
    /// against each other and against `materials` scene materials.
    pub fn mesh(&self, materials: usize) -> Result<TriMesh, MethodError> {
        let (v, t) = (self.rows("positions")?, self.rows("indices")?);
        let positions = unflat3(&self.f32s("positions", &[v, 3])?);
        let normals = unflat3(&self.f32s("normals", &[v, 3])?);
        let uvs = match self.b.tensors.get("uvs") {
            Some(_) => Some(
                self.f32s("uvs", &[v, 2])?
                    .chunks_exact(2)
                    .map(Vec2::from_slice)
                    .collect(),
            ),
            None => None,
        };
        let idx = self.u32s("indices", &[t, 3])?;
        if let Some(bad) = idx.iter().find(|&&i| i as usize >= v) {
            return Err(self.invalid(format!("triangle index {bad} out of range ({v} vertices)")));
        }
        let material_ids = self.u32s("material_ids", &[t])?;
        if let Some(bad) = material_ids.iter().find(|&&i| i as usize >= materials) {
            return Err(self.invalid(format!(
                "material id {bad} out of range ({materials} materials)"
            )));
        }
        Ok(TriMesh {
            positions,
            normals,
            uvs,
            indices: idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            material_ids,
        })
    }
}
