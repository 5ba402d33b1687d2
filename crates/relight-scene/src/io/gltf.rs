//! Minimal glTF 2.0 reader (`.gltf` with embedded base64 or external buffers, and `.glb`).
//!
//! Read: the default scene's node tree (`matrix` or TRS, composed parent-to-child), mesh
//! primitives in modes TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (others are skipped with a
//! warning), attributes `POSITION`, `NORMAL`, `TEXCOORD_0` (float or normalised integers;
//! `v` flipped to `1 - v`, OBJ's upward convention, which [`crate::texture`] follows),
//! indices (u8, u16, u32) and `pbrMetallicRoughness` factors (textures are ignored).
//! Positions are transformed by the node's world matrix, normals by its inverse transpose;
//! a mirroring matrix flips the winding. A primitive without normals gets angle-weighted
//! smooth normals. Sparse accessors and accessors without a buffer view are refused.
//!
//! External buffers are resolved against the glTF file's folder under the
//! [`LoadOptions::paths`] policy (see [`super::files`]: by default a buffer `uri` may not leave
//! that folder) and read up to their `byteLength`. Before any geometry is expanded, the
//! triangles and vertices of every primitive of every node instance are counted from the
//! accessors' `count`s: a file whose instancing expands beyond [`LoadOptions::max_triangles`]
//! triangles (or three times that many vertices) is refused — 1000 nodes sharing a mesh of
//! 1000 primitives sharing one accessor are a few kilobytes of JSON that would expand to
//! hundreds of millions of vertices.
//!
//! Materials: glTF's metallic-roughness model is mapped to the nearest closed-form material,
//! with `alpha = roughness^2` (glTF spec, Appendix B) clamped to `[1e-3, 1]`:
//! `metallic >= 0.5` gives [`Material::GgxConductor`] with `specular = baseColor`, otherwise
//! [`Material::GgxPlastic`] with `diffuse = baseColor`, `specular = 1`, `ior = 1.5` (glTF's
//! dielectric F0 = 0.04). Primitives without a material get `Material::default()`. A
//! material that fails `Material::validate` (e.g. a base colour above 1) is an error.

use super::files::{self, LoadOptions};
use super::{extension, read_bytes, LoadedMesh};
use crate::error::SceneError;
use crate::material::Material;
use crate::mesh::TriMesh;
use crate::meshops::{smooth_normals, NormalWeighting};
use crate::{Vec2, Vec3};
use glam::{Mat4, Quat};
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

#[derive(Deserialize, Default)]
#[serde(rename_all = "camelCase", default)]
struct Gltf {
    scene: Option<usize>,
    scenes: Vec<GScene>,
    nodes: Vec<Node>,
    meshes: Vec<GMesh>,
    accessors: Vec<Accessor>,
    buffer_views: Vec<BufferView>,
    buffers: Vec<Buffer>,
    materials: Vec<GMaterial>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct GScene {
    nodes: Vec<usize>,
}

#[derive(Deserialize, Default)]
#[serde(default)]
struct Node {
    children: Vec<usize>,
    mesh: Option<usize>,
    matrix: Option<[f32; 16]>,
    translation: Option<[f32; 3]>,
    rotation: Option<[f32; 4]>,
    scale: Option<[f32; 3]>,
}

#[derive(Deserialize)]
struct GMesh {
    primitives: Vec<Primitive>,
}

fn triangles() -> u32 {
    4
}

#[derive(Deserialize)]
struct Primitive {
    attributes: HashMap<String, usize>,
    indices: Option<usize>,
    material: Option<usize>,
    #[serde(default = "triangles")]
    mode: u32,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Accessor {
    buffer_view: Option<usize>,
    #[serde(default)]
    byte_offset: usize,
    component_type: u32,
    #[serde(default)]
    normalized: bool,
    count: usize,
    #[serde(rename = "type")]
    ty: String,
    sparse: Option<serde_json::Value>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct BufferView {
    buffer: usize,
    #[serde(default)]
    byte_offset: usize,
    byte_length: usize,
    byte_stride: Option<usize>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Buffer {
    uri: Option<String>,
    byte_length: usize,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "camelCase", default)]
struct GMaterial {
    pbr_metallic_roughness: Option<Pbr>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "camelCase", default)]
struct Pbr {
    base_color_factor: [f32; 4],
    metallic_factor: f32,
    roughness_factor: f32,
}

impl Default for Pbr {
    fn default() -> Self {
        Pbr {
            base_color_factor: [1.0; 4],
            metallic_factor: 1.0,
            roughness_factor: 1.0,
        }
    }
}

/// Read a `.gltf` or `.glb` file (see the module docs); `opts` gives the path policy for
/// buffer URIs and the triangle limit.
pub fn read_gltf(path: &Path, opts: &LoadOptions) -> Result<LoadedMesh, SceneError> {
    let bytes = read_bytes(path)?;
    let (json, bin) = if extension(path) == "glb" || bytes.starts_with(b"glTF") {
        split_glb(path, &bytes)?
    } else {
        (&bytes[..], None)
    };
    let doc: Gltf = serde_json::from_slice(json)
        .map_err(|e| SceneError::malformed_at(path, e.line(), format!("JSON: {e}")))?;
    let buffers = load_buffers(path, &doc, bin, opts)?;
    let mut r = Reader {
        visits: 0,
        path,
        doc: &doc,
        buffers,
        warnings: Vec::new(),
    };
    let mut mesh = TriMesh::default();
    let roots: Vec<usize> = match doc
        .scene
        .or(if doc.scenes.is_empty() { None } else { Some(0) })
    {
        Some(s) => doc
            .scenes
            .get(s)
            .ok_or_else(|| r.err(format!("scene {s} does not exist")))?
            .nodes
            .clone(),
        None => {
            let mut is_child = vec![false; doc.nodes.len()];
            doc.nodes.iter().flat_map(|n| &n.children).for_each(|&c| {
                if let Some(x) = is_child.get_mut(c) {
                    *x = true;
                }
            });
            (0..doc.nodes.len()).filter(|&i| !is_child[i]).collect()
        }
    };
    // Count what the node tree expands to before expanding it.
    let (mut tris, mut verts, mut visits) = (0u64, 0u64, 0usize);
    for &root in &roots {
        r.count(root, 0, &mut visits, &mut tris, &mut verts)?;
    }
    opts.check_triangles(tris, false, || crate::error::Location::file(path))?;
    if verts > 3 * opts.max_triangles as u64 {
        return Err(SceneError::too_large(
            path,
            format!(
                "{verts} vertices after instancing exceed three times the triangle limit of {}; raise it with --max-triangles (LoadOptions::max_triangles) if this is intended",
                opts.max_triangles
            ),
        ));
    }
    for root in roots {
        r.visit(root, Mat4::IDENTITY, 0, &mut mesh)?;
    }
    let mut materials = Vec::with_capacity(doc.materials.len() + 1);
    for (i, m) in doc.materials.iter().enumerate() {
        let m = to_material(m);
        m.validate()
            .map_err(|e| r.err(format!("material {i}: {e}")))?;
        materials.push(m);
    }
    let default_id = materials.len() as u32;
    if mesh.material_ids.contains(&default_id) {
        materials.push(Material::default());
    }
    Ok(LoadedMesh {
        mesh,
        materials,
        warnings: r.warnings,
    })
}

fn to_material(m: &GMaterial) -> Material {
    let p = m.pbr_metallic_roughness.unwrap_or_default();
    let c = p.base_color_factor;
    let base = Vec3::new(c[0], c[1], c[2]); // checked by `Material::validate`
    let alpha = (p.roughness_factor * p.roughness_factor).clamp(1e-3, 1.0);
    if p.metallic_factor >= 0.5 {
        Material::GgxConductor {
            specular: base,
            alpha,
        }
    } else {
        Material::GgxPlastic {
            diffuse: base,
            specular: Vec3::ONE,
            alpha,
            ior: 1.5,
        }
    }
}

/// Split a GLB container into its JSON chunk and optional BIN chunk.
fn split_glb<'a>(path: &Path, b: &'a [u8]) -> Result<(&'a [u8], Option<&'a [u8]>), SceneError> {
    let u32_at = |o: usize| {
        b.get(o..o + 4)
            .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]) as usize)
    };
    if !b.starts_with(b"glTF") {
        return Err(SceneError::malformed(path, "not a GLB file (bad magic)"));
    }
    let (Some(version), Some(total)) = (u32_at(4), u32_at(8)) else {
        return Err(SceneError::malformed(path, "truncated GLB header"));
    };
    if version != 2 {
        return Err(SceneError::unsupported(
            path,
            format!("GLB version {version}"),
        ));
    }
    if total > b.len() {
        return Err(SceneError::malformed(
            path,
            format!(
                "truncated: GLB announces {total} bytes, file has {}",
                b.len()
            ),
        ));
    }
    let mut chunks = Vec::new();
    let mut o = 12;
    while o + 8 <= total {
        let (Some(len), Some(kind)) = (u32_at(o), u32_at(o + 4)) else {
            break;
        };
        let data = b
            .get(o + 8..o + 8 + len)
            .filter(|_| o + 8 + len <= total)
            .ok_or_else(|| {
                SceneError::malformed(
                    path,
                    format!("truncated: GLB chunk at byte {o} overruns the file"),
                )
            })?;
        chunks.push((kind, data));
        o += 8 + len.div_ceil(4) * 4;
    }
    match chunks.first() {
        Some(&(0x4E4F_534A, json)) => Ok((
            json,
            chunks.get(1).filter(|c| c.0 == 0x004E_4942).map(|c| c.1),
        )),
        _ => Err(SceneError::malformed(
            path,
            "GLB does not start with a JSON chunk",
        )),
    }
}

fn load_buffers(
    path: &Path,
    doc: &Gltf,
    bin: Option<&[u8]>,
    opts: &LoadOptions,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut out = Vec::with_capacity(doc.buffers.len());
    for (i, b) in doc.buffers.iter().enumerate() {
        if b.byte_length as u64 > files::MAX_FILE_BYTES {
            return Err(SceneError::too_large(
                path,
                format!(
                    "buffer {i}: byteLength {} exceeds the limit of {} bytes",
                    b.byte_length,
                    files::MAX_FILE_BYTES
                ),
            ));
        }
        let data = match &b.uri {
            None if i == 0 => bin
                .ok_or_else(|| {
                    SceneError::malformed(path, "buffer 0 has no uri and there is no GLB BIN chunk")
                })?
                .to_vec(),
            None => {
                return Err(SceneError::malformed(
                    path,
                    format!("buffer {i} has no uri"),
                ))
            }
            Some(uri) if uri.starts_with("data:") => {
                let (_, payload) = uri.split_once(";base64,").ok_or_else(|| {
                    SceneError::unsupported(
                        path,
                        format!("buffer {i}: data URI that is not base64"),
                    )
                })?;
                base64_decode(payload)
                    .map_err(|m| SceneError::malformed(path, format!("buffer {i}: {m}")))?
            }
            Some(uri) if has_scheme(uri) => {
                return Err(SceneError::unsupported(
                    path,
                    format!("buffer {i}: uri '{uri}' (only relative file paths and data: URIs)"),
                ))
            }
            Some(uri) => {
                let what = format!("buffer {i} uri");
                let rel = files::percent_decode(uri);
                let file = files::resolve_model_ref(path, &rel, &opts.paths, &what)?;
                files::read_prefix(&file, b.byte_length as u64)?
            }
        };
        if data.len() < b.byte_length {
            return Err(SceneError::malformed(
                path,
                format!(
                    "buffer {i} holds {} bytes, byteLength says {}",
                    data.len(),
                    b.byte_length
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Whether a URI reference starts with a scheme (`file:`, `http:`, `data:`; RFC 3986: a
/// letter, then letters, digits, `+`, `-`, `.`, then `:`).
fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            scheme.starts_with(|c: char| c.is_ascii_alphabetic())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        }
        None => false,
    }
}

/// Decode standard base64 (padding optional, whitespace ignored).
fn base64_decode(s: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return Err(format!("invalid base64 character '{}'", c as char)),
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Ok(out)
}

/// Deepest node hierarchy accepted (recursion depth).
const MAX_DEPTH: usize = 256;

struct Reader<'a> {
    visits: usize,
    path: &'a Path,
    doc: &'a Gltf,
    buffers: Vec<Vec<u8>>,
    warnings: Vec<String>,
}

impl Reader<'_> {
    fn err(&self, msg: String) -> SceneError {
        SceneError::malformed(self.path, msg)
    }

    /// Add the triangles and vertices that node `i` and its subtree expand to (no data is
    /// decoded: counts come from the accessors, checked against their buffers), refusing what
    /// [`Self::visit`] would refuse about the tree's shape.
    fn count(
        &self,
        i: usize,
        depth: usize,
        visits: &mut usize,
        tris: &mut u64,
        verts: &mut u64,
    ) -> Result<(), SceneError> {
        let doc = self.doc;
        *visits += 1;
        if *visits > doc.nodes.len() || depth > MAX_DEPTH {
            return Err(self.err(format!(
                "node hierarchy is not a tree of depth <= {MAX_DEPTH} (cycle or shared node)"
            )));
        }
        let node = doc
            .nodes
            .get(i)
            .ok_or_else(|| self.err(format!("node {i} does not exist")))?;
        if let Some(m) = node.mesh {
            let mesh = doc
                .meshes
                .get(m)
                .ok_or_else(|| self.err(format!("node {i}: mesh {m} does not exist")))?;
            for (k, p) in mesh.primitives.iter().enumerate() {
                if !matches!(p.mode, 4..=6) {
                    continue;
                }
                // `view` checks the accessor lies within its buffer (no data is copied).
                let acc_count = |a: usize| self.view(a).map(|(_, _, acc, _)| acc.count as u64);
                let pos =
                    p.attributes.get("POSITION").copied().ok_or_else(|| {
                        self.err(format!("mesh {m} primitive {k} has no POSITION"))
                    })?;
                let n_vert = acc_count(pos)?;
                let n_idx = match p.indices {
                    Some(a) => acc_count(a)?,
                    None => n_vert,
                };
                let n_tri = if p.mode == 4 {
                    n_idx / 3
                } else {
                    n_idx.saturating_sub(2)
                };
                *tris = tris.saturating_add(n_tri);
                *verts = verts.saturating_add(n_vert);
            }
        }
        for &c in &node.children {
            self.count(c, depth + 1, visits, tris, verts)?;
        }
        Ok(())
    }

    fn visit(
        &mut self,
        i: usize,
        parent: Mat4,
        depth: usize,
        out: &mut TriMesh,
    ) -> Result<(), SceneError> {
        let doc = self.doc;
        // glTF node hierarchies are strict trees: every node is visited at most once. Counting
        // visits refuses cycles and shared children (exponential blow-up) alike.
        self.visits += 1;
        if self.visits > doc.nodes.len() || depth > MAX_DEPTH {
            return Err(self.err(format!(
                "node hierarchy is not a tree of depth <= {MAX_DEPTH} (cycle or shared node)"
            )));
        }
        let node = doc
            .nodes
            .get(i)
            .ok_or_else(|| self.err(format!("node {i} does not exist")))?;
        let local = match node.matrix {
            Some(m) => Mat4::from_cols_array(&m),
            None => {
                let t = node.translation.map_or(Vec3::ZERO, Vec3::from);
                let r = node
                    .rotation
                    .map_or(Quat::IDENTITY, |q| Quat::from_array(q).normalize());
                let s = node.scale.map_or(Vec3::ONE, Vec3::from);
                Mat4::from_scale_rotation_translation(s, r, t)
            }
        };
        let world_from_node = parent * local;
        if !world_from_node.is_finite() {
            return Err(self.err(format!("node {i} has a non-finite transform")));
        }
        if let Some(m) = node.mesh {
            let mesh = doc
                .meshes
                .get(m)
                .ok_or_else(|| self.err(format!("node {i}: mesh {m} does not exist")))?;
            for (k, prim) in mesh.primitives.iter().enumerate() {
                if let Some(part) = self.primitive(m, k, prim, world_from_node)? {
                    out.append(&part, 0);
                }
            }
        }
        for &c in &node.children {
            self.visit(c, world_from_node, depth + 1, out)?;
        }
        Ok(())
    }

    fn primitive(
        &mut self,
        m: usize,
        k: usize,
        p: &Primitive,
        world: Mat4,
    ) -> Result<Option<TriMesh>, SceneError> {
        let what = format!("mesh {m} primitive {k}");
        if !matches!(p.mode, 4..=6) {
            self.warnings.push(format!(
                "{}: {what}: mode {} is not triangles; skipped",
                self.path.display(),
                p.mode
            ));
            return Ok(None);
        }
        let pos_acc = *p
            .attributes
            .get("POSITION")
            .ok_or_else(|| self.err(format!("{what} has no POSITION")))?;
        let positions: Vec<Vec3> = self
            .floats::<3>(pos_acc)?
            .into_iter()
            .map(|v| world.transform_point3(Vec3::from(v)))
            .collect();
        let n = positions.len();
        let raw: Vec<u32> = match p.indices {
            Some(a) => self.indices(a)?,
            None => (0..n as u32).collect(),
        };
        if let Some(bad) = raw.iter().find(|&&i| i as usize >= n) {
            return Err(self.err(format!("{what}: index {bad} out of range ({n} vertices)")));
        }
        let mirror = world.determinant() < 0.0;
        let mut indices = Vec::new();
        let mut push = |t: [u32; 3]| indices.push(if mirror { [t[0], t[2], t[1]] } else { t });
        match p.mode {
            4 => raw.chunks_exact(3).for_each(|c| push([c[0], c[1], c[2]])),
            5 => (0..raw.len().saturating_sub(2)).for_each(|i| {
                let t = [raw[i], raw[i + 1], raw[i + 2]];
                push(if i % 2 == 0 { t } else { [t[1], t[0], t[2]] })
            }),
            _ => (1..raw.len().saturating_sub(1)).for_each(|i| push([raw[0], raw[i], raw[i + 1]])),
        }
        let material = match p.material {
            Some(mi) if mi < self.doc.materials.len() => mi as u32,
            Some(mi) => return Err(self.err(format!("{what}: material {mi} does not exist"))),
            None => self.doc.materials.len() as u32,
        };
        let mut part = TriMesh {
            positions,
            material_ids: vec![material; indices.len()],
            indices,
            ..Default::default()
        };
        if let Some(&a) = p.attributes.get("TEXCOORD_0") {
            let uv = self.floats::<2>(a)?;
            if uv.len() != n {
                return Err(self.err(format!(
                    "{what}: TEXCOORD_0 count {} != POSITION count {n}",
                    uv.len()
                )));
            }
            // glTF's v grows downwards from the image's top; relight's (OBJ's) upwards.
            part.uvs = Some(uv.into_iter().map(|[u, v]| Vec2::new(u, 1.0 - v)).collect());
        }
        part.normals = match p.attributes.get("NORMAL") {
            Some(&a) => {
                let nrm = self.floats::<3>(a)?;
                if nrm.len() != n {
                    return Err(self.err(format!(
                        "{what}: NORMAL count {} != POSITION count {n}",
                        nrm.len()
                    )));
                }
                let normal_from_object = glam::Mat3::from_mat4(world).inverse().transpose();
                nrm.into_iter()
                    .map(|v| {
                        (normal_from_object * Vec3::from(v))
                            .try_normalize()
                            .unwrap_or(Vec3::Y)
                    })
                    .collect()
            }
            None => smooth_normals(&part, NormalWeighting::Angle),
        };
        Ok(Some(part))
    }

    /// Bytes of accessor `a`: (data, element stride, component type, component count, count).
    fn view(&self, a: usize) -> Result<(&[u8], usize, &Accessor, usize), SceneError> {
        let acc = self
            .doc
            .accessors
            .get(a)
            .ok_or_else(|| self.err(format!("accessor {a} does not exist")))?;
        if acc.sparse.is_some() {
            return Err(SceneError::unsupported(
                self.path,
                format!("accessor {a} is sparse"),
            ));
        }
        let comps = match acc.ty.as_str() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            t => return Err(self.err(format!("accessor {a}: unexpected type {t}"))),
        };
        let csize = match acc.component_type {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            5125 | 5126 => 4,
            c => return Err(self.err(format!("accessor {a}: bad componentType {c}"))),
        };
        let bv = acc.buffer_view.ok_or_else(|| {
            SceneError::unsupported(self.path, format!("accessor {a} without bufferView"))
        })?;
        let view = self
            .doc
            .buffer_views
            .get(bv)
            .ok_or_else(|| self.err(format!("accessor {a}: bufferView {bv} does not exist")))?;
        let buf = self.buffers.get(view.buffer).ok_or_else(|| {
            self.err(format!(
                "bufferView {bv}: buffer {} does not exist",
                view.buffer
            ))
        })?;
        let elem = comps * csize;
        let stride = view.byte_stride.unwrap_or(elem);
        let view_end = view
            .byte_offset
            .checked_add(view.byte_length)
            .filter(|&e| e <= buf.len());
        // Bytes of the view the accessor spans: offset + (count - 1) stride + element size.
        let need = match acc.count.checked_sub(1) {
            None => Some(acc.byte_offset),
            Some(c) => c
                .checked_mul(stride)
                .and_then(|v| v.checked_add(elem))
                .and_then(|v| v.checked_add(acc.byte_offset)),
        };
        match (view_end, need) {
            (Some(_), Some(need)) if stride >= elem && need <= view.byte_length => {
                let data = &buf[view.byte_offset + acc.byte_offset..view.byte_offset + need];
                Ok((data, stride, acc, comps))
            }
            _ => Err(SceneError::TooLarge {
                at: crate::error::Location::file(self.path),
                msg: format!(
                    "accessor {a} ({} x {} {}) lies beyond its buffer view or buffer",
                    acc.count, acc.ty, acc.component_type
                ),
            }),
        }
    }

    fn component(data: &[u8], ct: u32, normalized: bool) -> f32 {
        let b = |n: usize| data[n];
        match ct {
            5120 => {
                let v = b(0) as i8 as f32;
                if normalized {
                    (v / 127.0).max(-1.0)
                } else {
                    v
                }
            }
            5121 => {
                let v = b(0) as f32;
                if normalized {
                    v / 255.0
                } else {
                    v
                }
            }
            5122 => {
                let v = i16::from_le_bytes([b(0), b(1)]) as f32;
                if normalized {
                    (v / 32767.0).max(-1.0)
                } else {
                    v
                }
            }
            5123 => {
                let v = u16::from_le_bytes([b(0), b(1)]) as f32;
                if normalized {
                    v / 65535.0
                } else {
                    v
                }
            }
            5125 => u32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f32,
            _ => f32::from_le_bytes([b(0), b(1), b(2), b(3)]),
        }
    }

    fn floats<const N: usize>(&self, a: usize) -> Result<Vec<[f32; N]>, SceneError> {
        let (data, stride, acc, comps) = self.view(a)?;
        if comps != N {
            return Err(self.err(format!(
                "accessor {a}: expected {N} components, found {}",
                acc.ty
            )));
        }
        let csize = if acc.component_type == 5126 || acc.component_type == 5125 {
            4
        } else {
            (acc.component_type as usize - 5120) / 2 + 1
        };
        let mut out = Vec::with_capacity(acc.count);
        for e in 0..acc.count {
            let v: [f32; N] = std::array::from_fn(|c| {
                Self::component(
                    &data[e * stride + c * csize..],
                    acc.component_type,
                    acc.normalized,
                )
            });
            if v.iter().any(|x| !x.is_finite()) {
                return Err(self.err(format!("accessor {a}: element {e} is not finite")));
            }
            out.push(v);
        }
        Ok(out)
    }

    fn indices(&self, a: usize) -> Result<Vec<u32>, SceneError> {
        let (data, stride, acc, comps) = self.view(a)?;
        let size = match (acc.component_type, comps) {
            (5121, 1) => 1,
            (5123, 1) => 2,
            (5125, 1) => 4,
            _ => return Err(self.err(format!("accessor {a}: indices must be unsigned scalars"))),
        };
        Ok((0..acc.count)
            .map(|e| {
                let d = &data[e * stride..e * stride + size];
                match size {
                    1 => d[0] as u32,
                    2 => u16::from_le_bytes([d[0], d[1]]) as u32,
                    _ => u32::from_le_bytes([d[0], d[1], d[2], d[3]]),
                }
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{load_mesh, test_util::temp_dir};
    use std::path::PathBuf;

    fn base64_encode(b: &[u8]) -> String {
        const T: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut s = String::new();
        for c in b.chunks(3) {
            let n = (c[0] as u32) << 16
                | (*c.get(1).unwrap_or(&0) as u32) << 8
                | *c.get(2).unwrap_or(&0) as u32;
            for k in 0..4 {
                s.push(if k <= c.len() {
                    T[(n >> (18 - 6 * k) & 63) as usize] as char
                } else {
                    '='
                });
            }
        }
        s
    }

    /// A unit quad in the z = 0 plane: 4 positions, 4 UVs, 6 u16 indices (no normals).
    fn quad_bin() -> Vec<u8> {
        let mut b = Vec::new();
        for p in [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]] {
            p.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
        }
        for t in [[0f32, 0.], [1., 0.], [1., 1.], [0., 1.]] {
            t.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
        }
        for i in [0u16, 1, 2, 0, 2, 3] {
            b.extend_from_slice(&i.to_le_bytes());
        }
        b
    }

    fn quad_json(uri: Option<&str>, idx_count: usize) -> String {
        let uri = uri.map_or(String::new(), |u| format!("\"uri\": \"{u}\", "));
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
            "nodes": [{{"children": [1], "translation": [0, 0, 5]}}, {{"mesh": 0, "scale": [2, 2, 2]}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0}}]}}],
            "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.25, 1, 1], "metallicFactor": 0, "roughnessFactor": 0.5}}}}],
            "buffers": [{{{uri}"byteLength": 92}}],
            "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                            {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}},
                          {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
                          {{"bufferView": 2, "componentType": 5123, "count": {idx_count}, "type": "SCALAR"}}]}}"#
        )
    }

    fn check_quad(m: &LoadedMesh) {
        assert_eq!(m.mesh.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.mesh.positions[2], Vec3::new(2.0, 2.0, 5.0)); // scaled by 2, moved by +5 z
        assert!(m
            .mesh
            .normals
            .iter()
            .all(|n| (*n - Vec3::Z).length() < 1e-6));
        // TEXCOORD_0 (1, 1), v flipped to OBJ's upward convention.
        assert_eq!(m.mesh.uvs.as_ref().unwrap()[2], Vec2::new(1.0, 0.0));
        assert_eq!(
            m.materials,
            vec![Material::GgxPlastic {
                diffuse: Vec3::new(0.5, 0.25, 1.0),
                specular: Vec3::ONE,
                alpha: 0.25,
                ior: 1.5
            }]
        );
    }

    #[test]
    fn embedded_base64_gltf_reads() {
        let dir = temp_dir("gltf");
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64_encode(&quad_bin())
        );
        let p = dir.join("q.gltf");
        std::fs::write(&p, quad_json(Some(&uri), 6)).unwrap();
        check_quad(&load_mesh(&p).unwrap());
    }

    #[test]
    fn external_bin_gltf_reads() {
        let dir = temp_dir("gltfbin");
        std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
        let p = dir.join("q.gltf");
        std::fs::write(&p, quad_json(Some("q.bin"), 6)).unwrap();
        check_quad(&load_mesh(&p).unwrap());
    }

    fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
        let mut j = json.as_bytes().to_vec();
        while !j.len().is_multiple_of(4) {
            j.push(b' ');
        }
        let mut out = b"glTF".to_vec();
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&((12 + 8 + j.len() + 8 + bin.len()) as u32).to_le_bytes());
        out.extend_from_slice(&(j.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
        out.extend_from_slice(&j);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
        out.extend_from_slice(bin);
        out
    }

    #[test]
    fn glb_reads() {
        let dir = temp_dir("glb");
        let p = dir.join("q.glb");
        std::fs::write(&p, glb(&quad_json(None, 6), &quad_bin())).unwrap();
        check_quad(&load_mesh(&p).unwrap());
    }

    #[test]
    fn malformed_gltf_json_names_the_line() {
        let dir = temp_dir("gltfbad");
        let p = dir.join("bad.gltf");
        std::fs::write(
            &p,
            "{\n\"asset\": {\"version\": \"2.0\"},\n\"nodes\": [ {\"mesh\": } ]\n}",
        )
        .unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("bad.gltf: line 3"), "{e}");
    }

    #[test]
    fn truncated_gltf_is_an_error() {
        let dir = temp_dir("gltftrunc");
        let p = dir.join("t.gltf");
        let json = quad_json(Some("q.bin"), 6);
        std::fs::write(&p, &json[..json.len() / 2]).unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("t.gltf: line") && e.contains("EOF"), "{e}");
    }

    #[test]
    fn accessor_beyond_buffer_is_refused() {
        let dir = temp_dir("gltfhuge");
        std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
        let p = dir.join("q.gltf");
        std::fs::write(&p, quad_json(Some("q.bin"), 4_000_000_000)).unwrap();
        let e = load_mesh(&p).unwrap_err();
        assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
    }

    #[test]
    fn malformed_and_truncated_glb_are_errors() {
        let dir = temp_dir("glbbad");
        let p = dir.join("bad.glb");
        let good = glb(&quad_json(None, 6), &quad_bin());
        std::fs::write(&p, &good[..good.len() - 20]).unwrap();
        let e = load_mesh(&p).unwrap_err().to_string();
        assert!(e.contains("bad.glb") && e.contains("truncated"), "{e}");
        let mut bad = good.clone();
        bad[0] = b'x';
        std::fs::write(&p, &bad).unwrap();
        assert!(load_mesh(&p).unwrap_err().to_string().contains("magic"));
        std::fs::write(&p, b"glTF").unwrap();
        assert!(load_mesh(&p).is_err());
    }

    #[test]
    fn missing_external_buffer_is_an_io_error() {
        let dir = temp_dir("gltfmiss");
        let p = dir.join("q.gltf");
        std::fs::write(&p, quad_json(Some("gone.bin"), 6)).unwrap();
        let e = load_mesh(&p).unwrap_err();
        assert!(
            matches!(e, SceneError::Io { .. }) && e.to_string().contains("gone.bin"),
            "{e}"
        );
    }

    #[test]
    fn cyclic_node_graph_is_refused() {
        let dir = temp_dir("gltfcycle");
        std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
        let p = dir.join("c.gltf");
        let json = quad_json(Some("q.bin"), 6).replace(
            r#"{"mesh": 0, "scale": [2, 2, 2]}"#,
            r#"{"mesh": 0, "children": [0]}"#,
        );
        std::fs::write(&p, json).unwrap();
        assert!(load_mesh(&p)
            .unwrap_err()
            .to_string()
            .contains("not a tree"));
    }

    /// `root/model/q.gltf` whose buffer `uri` is `uri`, and the buffer at `root/outside/q.bin`.
    fn model_and_outside_buffer(tag: &str, uri: impl Fn(&Path) -> String) -> PathBuf {
        let root = temp_dir(tag);
        std::fs::create_dir_all(root.join("model")).unwrap();
        std::fs::create_dir_all(root.join("outside")).unwrap();
        std::fs::write(root.join("outside/q.bin"), quad_bin()).unwrap();
        let p = root.join("model/q.gltf");
        std::fs::write(&p, quad_json(Some(&uri(&root)), 6)).unwrap();
        p
    }

    fn allow_outside() -> LoadOptions {
        LoadOptions {
            paths: files::PathPolicy {
                allow_outside: true,
            },
            ..LoadOptions::default()
        }
    }

    #[test]
    fn buffer_uri_climbing_out_of_the_folder_is_refused_unless_allowed() {
        let p = model_and_outside_buffer("gltfdotdot", |_| "../outside/q.bin".into());
        let e = load_mesh(&p).unwrap_err();
        assert!(matches!(e, SceneError::OutsideFolder { .. }), "{e}");
        assert!(
            e.to_string().contains("buffer 0 uri '../outside/q.bin'")
                && e.to_string().contains("--allow-outside-paths"),
            "{e}"
        );
        // Percent-encoded dots climb out the same way.
        let p2 = p.with_file_name("enc.gltf");
        std::fs::write(&p2, quad_json(Some("%2e%2e/outside/q.bin"), 6)).unwrap();
        assert!(matches!(
            load_mesh(&p2).unwrap_err(),
            SceneError::OutsideFolder { .. }
        ));
        // The opt-in reads it.
        check_quad(&crate::io::load_mesh_with(&p, &allow_outside()).unwrap());
        // Deep climbs towards system files are refused without touching them.
        let p3 = p.with_file_name("passwd.gltf");
        let deep = "../".repeat(40) + "etc/passwd";
        std::fs::write(&p3, quad_json(Some(&deep), 6)).unwrap();
        assert!(matches!(
            load_mesh(&p3).unwrap_err(),
            SceneError::OutsideFolder { .. }
        ));
    }

    #[test]
    fn absolute_buffer_uri_is_refused_unless_allowed() {
        let p = model_and_outside_buffer("gltfabs", |root| {
            root.join("outside/q.bin").display().to_string()
        });
        let e = load_mesh(&p).unwrap_err();
        assert!(matches!(e, SceneError::OutsideFolder { .. }), "{e}");
        check_quad(&crate::io::load_mesh_with(&p, &allow_outside()).unwrap());
        // A URI with a scheme is refused either way.
        let p2 = p.with_file_name("file.gltf");
        std::fs::write(&p2, quad_json(Some("file:///etc/passwd"), 6)).unwrap();
        for opts in [LoadOptions::default(), allow_outside()] {
            let e = crate::io::load_mesh_with(&p2, &opts).unwrap_err();
            assert!(matches!(e, SceneError::Unsupported { .. }), "{e}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn symlink_out_of_the_folder_is_refused_unless_allowed() {
        let p = model_and_outside_buffer("gltflink", |_| "link.bin".into());
        let root = p.parent().unwrap().parent().unwrap().to_path_buf();
        std::os::unix::fs::symlink(root.join("outside/q.bin"), root.join("model/link.bin"))
            .unwrap();
        let e = load_mesh(&p).unwrap_err();
        assert!(matches!(e, SceneError::OutsideFolder { .. }), "{e}");
        check_quad(&crate::io::load_mesh_with(&p, &allow_outside()).unwrap());
        // A symlinked folder inside the model's folder leads out the same way.
        std::os::unix::fs::symlink(root.join("outside"), root.join("model/sub")).unwrap();
        let p2 = p.with_file_name("sub.gltf");
        std::fs::write(&p2, quad_json(Some("sub/q.bin"), 6)).unwrap();
        assert!(matches!(
            load_mesh(&p2).unwrap_err(),
            SceneError::OutsideFolder { .. }
        ));
        // A symlink that stays inside is fine.
        std::fs::copy(root.join("outside/q.bin"), root.join("model/real.bin")).unwrap();
        std::os::unix::fs::symlink("real.bin", root.join("model/inside.bin")).unwrap();
        let p3 = p.with_file_name("inside.gltf");
        std::fs::write(&p3, quad_json(Some("inside.bin"), 6)).unwrap();
        check_quad(&load_mesh(&p3).unwrap());
    }

    #[test]
    fn dev_zero_buffer_with_the_opt_in_fails_without_reading_it() {
        if !Path::new("/dev/zero").exists() {
            relight_testdata::skip_platform("dev-zero", "no /dev/zero");
            return;
        }
        let dir = temp_dir("gltfzero");
        let p = dir.join("z.gltf");
        // A byteLength as large as a real buffer may be: still not read from a device.
        let json = quad_json(Some("/dev/zero"), 6)
            .replace(r#""byteLength": 92}]"#, r#""byteLength": 4000000000}]"#);
        std::fs::write(&p, json).unwrap();
        let e = crate::io::test_util::within_seconds(10, move || {
            crate::io::load_mesh_with(&p, &allow_outside()).unwrap_err()
        });
        assert!(matches!(e, SceneError::NotRegularFile { .. }), "{e}");
        assert!(e.to_string().contains("/dev/zero"), "{e}");
    }

    /// 1000 nodes, each instancing one mesh of 1000 primitives that share one 300-vertex
    /// accessor: 1e8 triangles (3e8 vertices) from about 50 KB of JSON.
    fn instancing_bomb() -> String {
        let mut bin = Vec::new();
        for i in 0..300u32 {
            let v = [(i % 3) as f32, (i / 3 % 2) as f32, (i / 6) as f32];
            v.iter()
                .for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
        }
        let prims = vec![r#"{"attributes": {"POSITION": 0}}"#; 1000].join(",");
        let nodes = vec![r#"{"mesh": 0}"#; 1000].join(",");
        let roots: Vec<String> = (0..1000).map(|i| i.to_string()).collect();
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [{}]}}], "nodes": [{nodes}],
            "meshes": [{{"primitives": [{prims}]}}],
            "buffers": [{{"uri": "data:application/octet-stream;base64,{}", "byteLength": 3600}}],
            "bufferViews": [{{"buffer": 0, "byteLength": 3600}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 300, "type": "VEC3"}}]}}"#,
            roots.join(","),
            base64_encode(&bin)
        )
    }

    #[test]
    fn instancing_bomb_is_refused_before_expanding() {
        let dir = temp_dir("gltfbomb");
        let p = dir.join("bomb.gltf");
        let json = instancing_bomb();
        assert!(json.len() < 60_000);
        std::fs::write(&p, &json).unwrap();
        let e = crate::io::test_util::within_seconds(20, move || load_mesh(&p).unwrap_err());
        assert!(
            matches!(
                e,
                SceneError::TooManyTriangles {
                    count: 100_000_000,
                    limit: 50_000_000,
                    ..
                }
            ),
            "{e}"
        );
        let s = e.to_string();
        assert!(
            s.contains("bomb.gltf") && s.contains("50000000") && s.contains("--max-triangles"),
            "{s}"
        );
    }

    #[test]
    fn triangle_limit_applies_to_a_small_gltf() {
        let dir = temp_dir("gltflimit");
        std::fs::write(dir.join("q.bin"), quad_bin()).unwrap();
        let p = dir.join("q.gltf");
        std::fs::write(&p, quad_json(Some("q.bin"), 6)).unwrap();
        let one = LoadOptions {
            max_triangles: 1,
            ..LoadOptions::default()
        };
        let e = crate::io::load_mesh_with(&p, &one).unwrap_err();
        assert!(
            matches!(
                e,
                SceneError::TooManyTriangles {
                    count: 2,
                    limit: 1,
                    ..
                }
            ),
            "{e}"
        );
        let two = LoadOptions {
            max_triangles: 2,
            ..LoadOptions::default()
        };
        check_quad(&crate::io::load_mesh_with(&p, &two).unwrap());
    }

    #[test]
    fn base64_round_trip() {
        let data: Vec<u8> = (0..=255u8).collect();
        for n in [0, 1, 2, 3, 100, 256] {
            assert_eq!(
                base64_decode(&base64_encode(&data[..n])).unwrap(),
                &data[..n]
            );
        }
        assert!(base64_decode("ab$c").is_err());
    }
}
