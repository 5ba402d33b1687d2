//! glTF 2.0 reader (`.gltf` with embedded base64 or external buffers and images, and `.glb`)
//! on the `gltf` crate (gltf-rs: typed JSON and its validation).
//!
//! Conventions, stated once:
//! * **Geometry**: the default scene's node tree (`matrix` or TRS, composed parent-to-child;
//!   without scenes, every root node), mesh primitives in modes TRIANGLES, TRIANGLE_STRIP and
//!   TRIANGLE_FAN (others are skipped with a warning), attributes `POSITION`, `NORMAL`,
//!   `TEXCOORD_0` (float or normalised integers), indices (u8, u16, u32). Positions are
//!   transformed by the node's `world_from_node` matrix, normals by its inverse transpose; a
//!   mirroring matrix flips the winding. A primitive without normals gets angle-weighted
//!   smooth normals. Sparse accessors and accessors without a buffer view are refused.
//! * **Texture coordinates**: glTF's `v` grows downwards from the image's top; it is flipped
//!   to `1 - v` on load (OBJ's upward convention, which every mesh carries and
//!   [`crate::texture`] defines lookups in, `KHR_texture_transform` included).
//! * **Objects** ([`LoadedMesh::objects`]): one per node instancing a mesh, in depth-first
//!   order, named after the node, else the mesh, else `mesh{index}`; a repeated name gets
//!   `.1`, `.2`, ... appended.
//! * **Camera** ([`LoadedMesh::camera`]): the first node with a perspective camera in a
//!   depth-first walk of the default scene: eye at the node's origin, looking along its -Z,
//!   up its +Y; horizontal field of view `2 atan(tan(yfov / 2) aspectRatio)` (aspect 4:3
//!   when absent), 640 pixels wide and `640 / aspectRatio` high. Orthographic cameras are
//!   ignored with a warning.
//! * **Materials**: `pbrMetallicRoughness` with its factors and textures (`baseColorTexture`
//!   sRGB, `metallicRoughnessTexture` linear with G = roughness and B = metallic,
//!   `normalTexture` linear with its `scale`), each texture with its sampler and
//!   `KHR_texture_transform`, is read into a [`GltfPbr`] ([`material`]); one function,
//!   [`pbr_to_material`], turns it into relight's material and maps.
//!
//! Refused, with the file named: required extensions other than [`SUPPORTED_EXTENSIONS`];
//! extensions relight cannot honour even when only used ([`REFUSED_EXTENSIONS`]: KTX2/Basis
//! and WebP images, Draco and meshopt compression, emissive strength); emission
//! (`emissiveTexture` or a non-zero `emissiveFactor`: relight's methods carry no emission);
//! factors that are NaN, negative or over 1; a textured material on a primitive without
//! `TEXCOORD_0`; images outside the model's folder, missing, corrupt, over
//! [`crate::texture::MAX_TEXTURE_SIDE`] per side, or other than PNG and JPEG. Warned once
//! per material: `alphaMode` MASK or BLEND (drawn opaque) and a texture on `TEXCOORD_1`
//! (read with `TEXCOORD_0`).
//!
//! External buffers and images are resolved against the glTF file's folder under the
//! [`LoadOptions::paths`] policy (see [`super::files`]: by default a `uri` may not leave that
//! folder); buffers are read up to their `byteLength`. Before any geometry is expanded, the
//! triangles and vertices of every primitive of every node instance are counted from the
//! accessors' `count`s: a file whose instancing expands beyond [`LoadOptions::max_triangles`]
//! triangles (or three times that many vertices) is refused — 1000 nodes sharing a mesh of
//! 1000 primitives sharing one accessor are a few kilobytes of JSON that would expand to
//! hundreds of millions of vertices.

mod accessors;
mod buffers;
pub mod material;

use buffers::{load_buffers, split_glb};

pub use material::{pbr_to_material, GltfPbr};

use super::files::LoadOptions;
use super::{extension, read_bytes, LoadedMesh};
use crate::camera::Camera;
use crate::error::SceneError;
use crate::material::maps::MaterialMaps;
use crate::material::Material;
use crate::mesh::TriMesh;
use crate::meshops::{smooth_normals, NormalWeighting};
use crate::{Vec2, Vec3};
use glam::{Mat4, Quat};
use gltf::mesh::{Mode, Semantic};
use std::path::Path;

/// Extensions a file may require.
pub const SUPPORTED_EXTENSIONS: [&str; 1] = ["KHR_texture_transform"];

/// Extensions refused even when only used, with the reason.
pub const REFUSED_EXTENSIONS: [(&str, &str); 5] = [
    (
        "KHR_texture_basisu",
        "KTX2/Basis images are not read (PNG and JPEG are)",
    ),
    (
        "EXT_texture_webp",
        "WebP images are not read (PNG and JPEG are)",
    ),
    (
        "KHR_draco_mesh_compression",
        "Draco-compressed meshes are not read",
    ),
    (
        "EXT_meshopt_compression",
        "meshopt-compressed buffers are not read",
    ),
    (
        "KHR_materials_emissive_strength",
        "relight's methods carry no emission",
    ),
];

/// Read a `.gltf` or `.glb` file (see the module docs); `opts` gives the path policy for
/// buffer and image URIs and the triangle limit.
pub fn read_gltf(path: &Path, opts: &LoadOptions) -> Result<LoadedMesh, SceneError> {
    let bytes = read_bytes(path)?;
    let (json, bin) = if extension(path) == "glb" || bytes.starts_with(b"glTF") {
        split_glb(path, &bytes)?
    } else {
        (&bytes[..], None)
    };
    let root = gltf::Gltf::from_slice_without_validation(json)
        .map_err(|e| gltf_error(path, e))?
        .document
        .into_json();
    check_extensions(path, &root)?;
    let doc = validate(path, root)?;
    let buffers = load_buffers(path, &doc, bin, opts)?;
    let mut r = Reader {
        visits: 0,
        path,
        buffers,
        warnings: Vec::new(),
        textured: Vec::new(),
        objects: Vec::new(),
        camera: None,
    };
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            doc.nodes()
                .flat_map(|n| n.children())
                .for_each(|c| is_child[c.index()] = true);
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };
    // Count what the node tree expands to before expanding it.
    let (mut tris, mut verts, mut visits) = (0u64, 0u64, 0usize);
    for root in &roots {
        r.count(&doc, root, 0, &mut visits, &mut tris, &mut verts)?;
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
    // Materials (and their images) before geometry: a primitive needs to know whether its
    // material is textured.
    let mut images = material::ImageCache::new(doc.images().len());
    let mut materials = Vec::with_capacity(doc.materials().len() + 1);
    let mut maps = Vec::with_capacity(doc.materials().len() + 1);
    for m in doc.materials() {
        let pbr =
            material::read_material(path, &m, &r.buffers, opts, &mut images, &mut r.warnings)?;
        r.textured.push(pbr.is_textured());
        let (mat, mmaps) = pbr_to_material(&pbr).map_err(|e| {
            r.err(format!(
                "material {} ('{}'): {e}",
                m.index().unwrap_or(0),
                pbr.name
            ))
        })?;
        mat.validate().map_err(|e| {
            r.err(format!(
                "material {} ('{}'): {e}",
                m.index().unwrap_or(0),
                pbr.name
            ))
        })?;
        materials.push(mat);
        maps.push(mmaps);
    }
    let mut mesh = TriMesh::default();
    for root in &roots {
        r.visit(&doc, root, Mat4::IDENTITY, 0, &mut mesh)?;
    }
    let default_id = materials.len() as u32;
    if mesh.material_ids.contains(&default_id) {
        materials.push(Material::default());
        maps.push(MaterialMaps::default());
    }
    let starts = r.objects.iter().map(|o| (o.0.clone(), o.1.start)).collect();
    let objects = super::objects_from_starts(starts, mesh.triangle_count() as u32);
    Ok(LoadedMesh {
        mesh,
        materials,
        maps,
        objects,
        camera: r.camera,
        warnings: r.warnings,
    })
}

/// The error of the `gltf` crate as a [`SceneError`]: JSON syntax with its line, validation
/// with the JSON path of each problem.
fn gltf_error(path: &Path, e: gltf::Error) -> SceneError {
    match e {
        gltf::Error::Deserialize(e) => {
            SceneError::malformed_at(path, e.line(), format!("JSON: {e}"))
        }
        gltf::Error::Validation(list) => {
            let msgs: Vec<String> = list
                .iter()
                .take(5)
                .map(|(p, e)| format!("{p}: {e}"))
                .collect();
            SceneError::malformed(path, format!("invalid glTF: {}", msgs.join("; ")))
        }
        e => SceneError::malformed(path, format!("glTF: {e}")),
    }
}

/// The document, once the `gltf` crate's validation passed (indices in range, required
/// fields present), except that a `POSITION` accessor need not state its `min` and `max`
/// (relight does not use them).
fn validate(path: &Path, root: gltf::json::Root) -> Result<gltf::Document, SceneError> {
    use gltf::json::validation::{Error, Validate};
    // The crate's primitive check reads the POSITION accessor before checking its index:
    // check every attribute's index first (an index out of range would panic there).
    let n = root.accessors.len();
    for (i, m) in root.meshes.iter().enumerate() {
        for (j, p) in m.primitives.iter().enumerate() {
            if let Some((sem, a)) = p.attributes.iter().find(|(_, a)| a.value() >= n) {
                return Err(SceneError::malformed(
                    path,
                    format!(
                        "meshes[{i}].primitives[{j}]: attribute {sem:?} names accessor {}, but the file has {n}",
                        a.value()
                    ),
                ));
            }
        }
    }
    let mut errors = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |p, e| {
        let p = p();
        let bounds = p.as_str().ends_with("[\"POSITION\"].min")
            || p.as_str().ends_with("[\"POSITION\"].max");
        if !(bounds && e == Error::Missing) {
            errors.push((p, e));
        }
    });
    if !errors.is_empty() {
        return Err(gltf_error(path, gltf::Error::Validation(errors)));
    }
    Ok(gltf::Document::from_json_without_validation(root))
}

/// Refuse required extensions relight does not support, and used ones it cannot honour.
fn check_extensions(path: &Path, root: &gltf::json::Root) -> Result<(), SceneError> {
    for name in root.extensions_used.iter().chain(&root.extensions_required) {
        if let Some((_, why)) = REFUSED_EXTENSIONS.iter().find(|(n, _)| n == name) {
            return Err(SceneError::unsupported(
                path,
                format!("glTF extension {name}: {why}"),
            ));
        }
    }
    for name in &root.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&name.as_str()) {
            return Err(SceneError::unsupported(
                path,
                format!(
                    "required glTF extension {name} (supported: {})",
                    SUPPORTED_EXTENSIONS.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

/// Deepest node hierarchy accepted (recursion depth).
const MAX_DEPTH: usize = 256;

struct Reader<'a> {
    visits: usize,
    path: &'a Path,
    buffers: Vec<Vec<u8>>,
    warnings: Vec<String>,
    /// Per material: whether it has a texture (its primitives need `TEXCOORD_0`).
    textured: Vec<bool>,
    /// Per node instancing a mesh: its name before making names unique, and its triangles.
    objects: Vec<(String, std::ops::Range<u32>)>,
    camera: Option<Camera>,
}

/// Horizontal field of view (degrees) of a vertical one `yfov` (radians) at `aspect`.
fn horizontal_fov_deg(yfov: f32, aspect: f32) -> f32 {
    (2.0 * ((yfov * 0.5).tan() * aspect).atan()).to_degrees()
}

impl Reader<'_> {
    fn err(&self, msg: String) -> SceneError {
        SceneError::malformed(self.path, msg)
    }

    fn not_a_tree(&self) -> SceneError {
        self.err(format!(
            "node hierarchy is not a tree of depth <= {MAX_DEPTH} (cycle or shared node)"
        ))
    }

    /// Add the triangles and vertices that `node` and its subtree expand to (no data is
    /// decoded: counts come from the accessors, checked against their buffers), refusing what
    /// [`Self::visit`] would refuse about the tree's shape.
    fn count(
        &self,
        doc: &gltf::Document,
        node: &gltf::Node,
        depth: usize,
        visits: &mut usize,
        tris: &mut u64,
        verts: &mut u64,
    ) -> Result<(), SceneError> {
        *visits += 1;
        if *visits > doc.nodes().len() || depth > MAX_DEPTH {
            return Err(self.not_a_tree());
        }
        if let Some(mesh) = node.mesh() {
            for p in mesh.primitives() {
                if !is_triangles(p.mode()) {
                    continue;
                }
                // `view` checks the accessor lies within its buffer (no data is copied).
                let acc_count = |a: &gltf::Accessor| self.view(a).map(|_| a.count() as u64);
                let pos = p.get(&Semantic::Positions).ok_or_else(|| {
                    self.err(format!(
                        "mesh {} primitive {} has no POSITION",
                        mesh.index(),
                        p.index()
                    ))
                })?;
                let n_vert = acc_count(&pos)?;
                let n_idx = match p.indices() {
                    Some(a) => acc_count(&a)?,
                    None => n_vert,
                };
                let n_tri = if p.mode() == Mode::Triangles {
                    n_idx / 3
                } else {
                    n_idx.saturating_sub(2)
                };
                *tris = tris.saturating_add(n_tri);
                *verts = verts.saturating_add(n_vert);
            }
        }
        for c in node.children() {
            self.count(doc, &c, depth + 1, visits, tris, verts)?;
        }
        Ok(())
    }

    fn visit(
        &mut self,
        doc: &gltf::Document,
        node: &gltf::Node,
        parent: Mat4,
        depth: usize,
        out: &mut TriMesh,
    ) -> Result<(), SceneError> {
        // glTF node hierarchies are strict trees: every node is visited at most once. Counting
        // visits refuses cycles and shared children (exponential blow-up) alike.
        self.visits += 1;
        if self.visits > doc.nodes().len() || depth > MAX_DEPTH {
            return Err(self.not_a_tree());
        }
        let i = node.index();
        let node_from_child = match node.transform() {
            gltf::scene::Transform::Matrix { matrix } => Mat4::from_cols_array_2d(&matrix),
            gltf::scene::Transform::Decomposed {
                translation,
                rotation,
                scale,
            } => Mat4::from_scale_rotation_translation(
                Vec3::from(scale),
                Quat::from_array(rotation).normalize(),
                Vec3::from(translation),
            ),
        };
        let world_from_node = parent * node_from_child;
        if !world_from_node.is_finite() {
            return Err(self.err(format!("node {i} has a non-finite transform")));
        }
        if let Some(cam) = node.camera() {
            self.camera_at(&cam, world_from_node)?;
        }
        if let Some(mesh) = node.mesh() {
            let start = out.triangle_count() as u32;
            for prim in mesh.primitives() {
                if let Some(part) = self.primitive(&mesh, &prim, world_from_node)? {
                    out.append(&part, 0);
                }
            }
            let name = node
                .name()
                .or(mesh.name())
                .filter(|n| !n.is_empty())
                .map_or_else(|| format!("mesh{}", mesh.index()), String::from);
            self.objects
                .push((name, start..out.triangle_count() as u32));
        }
        for c in node.children() {
            self.visit(doc, &c, world_from_node, depth + 1, out)?;
        }
        Ok(())
    }

    /// Keep the first perspective camera met (module docs).
    fn camera_at(&mut self, cam: &gltf::Camera, world_from_node: Mat4) -> Result<(), SceneError> {
        if self.camera.is_some() {
            return Ok(());
        }
        let p = match cam.projection() {
            gltf::camera::Projection::Perspective(p) => p,
            gltf::camera::Projection::Orthographic(_) => {
                self.warnings.push(format!(
                    "{}: camera {} is orthographic; ignored (perspective cameras only)",
                    self.path.display(),
                    cam.index()
                ));
                return Ok(());
            }
        };
        let aspect = p.aspect_ratio().unwrap_or(4.0 / 3.0);
        let yfov = p.yfov();
        let fov_deg = horizontal_fov_deg(yfov, aspect);
        if !(aspect.is_finite() && aspect > 0.0 && yfov > 0.0 && fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(self.err(format!(
                "camera {}: yfov {yfov} and aspectRatio {aspect} give no field of view in (0, 180) degrees",
                cam.index()
            )));
        }
        let origin = world_from_node.transform_point3(Vec3::ZERO);
        let forward = world_from_node.transform_vector3(-Vec3::Z).try_normalize();
        let up = world_from_node.transform_vector3(Vec3::Y).try_normalize();
        let (Some(forward), Some(up)) = (forward, up) else {
            return Err(self.err(format!(
                "camera {}: its node's transform is degenerate",
                cam.index()
            )));
        };
        let width = 640u32;
        let height = ((width as f32 / aspect).round() as u32).max(1);
        self.camera = Some(Camera {
            origin: origin.into(),
            target: (origin + forward).into(),
            up: up.into(),
            fov_deg,
            width,
            height,
        });
        Ok(())
    }

    fn primitive(
        &mut self,
        mesh: &gltf::Mesh,
        p: &gltf::Primitive,
        world: Mat4,
    ) -> Result<Option<TriMesh>, SceneError> {
        let what = format!("mesh {} primitive {}", mesh.index(), p.index());
        if !is_triangles(p.mode()) {
            self.warnings.push(format!(
                "{}: {what}: mode {:?} is not triangles; skipped",
                self.path.display(),
                p.mode()
            ));
            return Ok(None);
        }
        let pos_acc = p
            .get(&Semantic::Positions)
            .ok_or_else(|| self.err(format!("{what} has no POSITION")))?;
        let positions: Vec<Vec3> = self
            .floats::<3>(&pos_acc)?
            .into_iter()
            .map(|v| world.transform_point3(Vec3::from(v)))
            .collect();
        let n = positions.len();
        let raw: Vec<u32> = match p.indices() {
            Some(a) => self.indices(&a)?,
            None => (0..n as u32).collect(),
        };
        if let Some(bad) = raw.iter().find(|&&i| i as usize >= n) {
            return Err(self.err(format!("{what}: index {bad} out of range ({n} vertices)")));
        }
        let mirror = world.determinant() < 0.0;
        let mut indices = Vec::new();
        let mut push = |t: [u32; 3]| indices.push(if mirror { [t[0], t[2], t[1]] } else { t });
        match p.mode() {
            Mode::Triangles => raw.chunks_exact(3).for_each(|c| push([c[0], c[1], c[2]])),
            Mode::TriangleStrip => (0..raw.len().saturating_sub(2)).for_each(|i| {
                let t = [raw[i], raw[i + 1], raw[i + 2]];
                push(if i % 2 == 0 { t } else { [t[1], t[0], t[2]] })
            }),
            _ => (1..raw.len().saturating_sub(1)).for_each(|i| push([raw[0], raw[i], raw[i + 1]])),
        }
        let material = match p.material().index() {
            Some(mi) => mi as u32,
            None => self.textured.len() as u32,
        };
        let mut part = TriMesh {
            positions,
            material_ids: vec![material; indices.len()],
            indices,
            ..Default::default()
        };
        match p.get(&Semantic::TexCoords(0)) {
            Some(a) => {
                let uv = self.floats::<2>(&a)?;
                if uv.len() != n {
                    return Err(self.err(format!(
                        "{what}: TEXCOORD_0 count {} != POSITION count {n}",
                        uv.len()
                    )));
                }
                // glTF's v grows downwards from the image's top; relight's (OBJ's) upwards.
                part.uvs = Some(uv.into_iter().map(|[u, v]| Vec2::new(u, 1.0 - v)).collect());
            }
            None if self.textured.get(material as usize) == Some(&true) => {
                return Err(self.err(format!(
                    "{what}: material {material} has textures but the primitive has no TEXCOORD_0"
                )));
            }
            None => {}
        }
        part.normals = match p.get(&Semantic::Normals) {
            Some(a) => {
                let nrm = self.floats::<3>(&a)?;
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
}

fn is_triangles(m: Mode) -> bool {
    matches!(m, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)
}

#[cfg(test)]
mod tests;
