//! Reading and writing scenes, meshes, images and environments.
//!
//! * meshes: [`obj`] (+ MTL), [`ply`] (ASCII and binary; binary write), [`gltf`] (`.gltf`,
//!   `.glb`), all through [`load_mesh`];
//! * images: [`image`] (Radiance `.hdr`, OpenEXR, 8-bit sRGB PNG);
//! * environments: [`mod@env`] (latlong, vertical cross, angular probe) through [`load_env`].
//!
//! The per-format `read_*` functions are the raw parsers (no degenerate-triangle removal, normals
//! possibly missing); [`load_mesh`] is the entry point that finishes and validates the mesh.
//!
//! Every reader opens its files through [`files`] (regular files only, bounded reads, models
//! confined to their folder: the rules are in that module's docs), checks sizes announced by
//! a file against the bytes it actually has and against [`LoadOptions::max_triangles`] before
//! allocating, and returns [`SceneError`] (never panics) on bad input. Every writer is atomic
//! ([`atomic`]): it writes a temporary `.<name>.relight-tmp.<host>.<pid>.<random>` in the
//! destination folder and renames it over `<name>`; temporaries left by killed processes are
//! removed by the next write into that folder.

pub mod atomic;
pub mod env;
pub mod files;
pub mod gltf;
pub mod image;
pub mod obj;
pub mod ply;

pub use env::load_env;
pub use files::{LoadOptions, PathPolicy, DEFAULT_MAX_TRIANGLES};
pub use image::{read_image, write_exr, write_hdr, write_png_srgb8};
pub use ply::write_ply;

use crate::camera::Camera;
use crate::error::SceneError;
use crate::material::maps::MaterialMaps;
use crate::material::Material;
use crate::mesh::TriMesh;
use crate::meshops;
use std::path::Path;

/// A mesh read from a file with its materials (`mesh.material_ids` index `materials`).
#[derive(Clone, Debug)]
pub struct LoadedMesh {
    /// The triangles; normals are present (read or computed) and unit.
    pub mesh: TriMesh,
    /// Materials; never empty.
    pub materials: Vec<Material>,
    /// The maps of each material, parallel to `materials` (all empty for OBJ and PLY).
    pub maps: Vec<MaterialMaps>,
    /// Named objects: contiguous triangle ranges in load order covering every triangle,
    /// with unique names (glTF nodes or meshes, OBJ `o` / `g`, else the file stem).
    pub objects: Vec<MeshObject>,
    /// The file's own camera, in world space (glTF only).
    pub camera: Option<Camera>,
    /// Non-fatal problems (missing MTL file, dropped degenerate triangles, ...), one per line.
    pub warnings: Vec<String>,
}

/// A named part of a loaded mesh.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshObject {
    /// Unique within its mesh.
    pub name: String,
    /// Its triangles (indices into `mesh.indices`).
    pub triangles: std::ops::Range<u32>,
}

/// Load a mesh with the default [`LoadOptions`] (models confined to their folder,
/// [`DEFAULT_MAX_TRIANGLES`]); see [`load_mesh_with`].
pub fn load_mesh(path: &Path) -> Result<LoadedMesh, SceneError> {
    load_mesh_with(path, &LoadOptions::default())
}

/// Load a mesh, dispatching on the extension (`obj`, `ply`, `gltf`, `glb`; case-insensitive).
///
/// Files are opened and references inside the model followed as `opts` allows (see
/// [`files`]); a mesh over `opts.max_triangles` is refused. After parsing, degenerate
/// triangles are dropped (their number is reported in `warnings`), missing normals are
/// computed (angle-weighted, [`meshops::smooth_normals`]), and the result must pass
/// [`meshops::validate`]; an empty mesh is an error.
pub fn load_mesh_with(path: &Path, opts: &LoadOptions) -> Result<LoadedMesh, SceneError> {
    let ext = extension(path);
    let mut loaded = match ext.as_str() {
        "obj" => obj::read_obj(path, opts)?,
        "ply" => ply::read_ply(path, opts)?,
        "gltf" | "glb" => gltf::read_gltf(path, opts)?,
        _ => {
            return Err(SceneError::unsupported(
                path,
                format!("mesh extension '{ext}' (expected obj, ply, gltf or glb)"),
            ))
        }
    };
    finish_mesh(path, &mut loaded)?;
    Ok(loaded)
}

/// Common post-processing of every loader (see [`load_mesh`]).
pub(crate) fn finish_mesh(path: &Path, loaded: &mut LoadedMesh) -> Result<(), SceneError> {
    // Drop degenerate triangles, carrying each kept triangle's original index through the
    // material ids so that materials and object ranges follow.
    let n_tri = loaded.mesh.indices.len();
    let material_ids =
        std::mem::replace(&mut loaded.mesh.material_ids, (0..n_tri as u32).collect());
    let dropped = meshops::drop_degenerate(&mut loaded.mesh);
    let kept = std::mem::take(&mut loaded.mesh.material_ids);
    loaded.mesh.material_ids = if material_ids.len() == n_tri {
        kept.iter().map(|&t| material_ids[t as usize]).collect()
    } else {
        material_ids
    };
    if dropped > 0 {
        loaded.warnings.push(format!(
            "{}: dropped {dropped} degenerate triangles",
            path.display()
        ));
        // An object's new range starts at the number of kept triangles before its old start.
        let new_start = |old: u32| kept.partition_point(|&t| t < old) as u32;
        for o in &mut loaded.objects {
            o.triangles = new_start(o.triangles.start)..new_start(o.triangles.end);
        }
        loaded.objects.retain(|o| !o.triangles.is_empty());
    }
    meshops::check_non_empty(&loaded.mesh).map_err(|m| SceneError::invalid_mesh(path, m))?;
    if loaded.mesh.normals.len() != loaded.mesh.positions.len() {
        loaded.mesh.normals =
            meshops::smooth_normals(&loaded.mesh, meshops::NormalWeighting::Angle);
    }
    if loaded.materials.is_empty() {
        loaded.materials.push(Material::default());
    }
    loaded
        .maps
        .resize(loaded.materials.len(), MaterialMaps::default());
    if loaded.objects.is_empty() {
        loaded.objects.push(MeshObject {
            name: file_stem(path),
            triangles: 0..loaded.mesh.indices.len() as u32,
        });
    }
    let n_mat = loaded.materials.len() as u32;
    if let Some(bad) = loaded.mesh.material_ids.iter().find(|&&m| m >= n_mat) {
        return Err(SceneError::invalid_mesh(
            path,
            format!("material id {bad} out of range ({n_mat} materials)"),
        ));
    }
    meshops::validate(&loaded.mesh).map_err(|m| SceneError::invalid_mesh(path, m))
}

/// The file name of `path` without its extension (`"mesh"` when it has none).
pub(crate) fn file_stem(path: &Path) -> String {
    path.file_stem()
        .and_then(|s| s.to_str())
        .filter(|s| !s.is_empty())
        .unwrap_or("mesh")
        .to_string()
}

/// `names` made unique: a name met before gets `.1`, `.2`, ... (the first free suffix).
pub(crate) fn unique_names(names: Vec<String>) -> Vec<String> {
    let mut seen = std::collections::HashSet::new();
    names
        .into_iter()
        .map(|n| {
            if seen.insert(n.clone()) {
                return n;
            }
            let unique = (1..)
                .map(|k| format!("{n}.{k}"))
                .find(|c| !seen.contains(c))
                .unwrap_or(n);
            seen.insert(unique.clone());
            unique
        })
        .collect()
}

/// Objects from `(name, first triangle)` in order, the last ending at `end`: empty ones
/// dropped, names made unique.
pub(crate) fn objects_from_starts(starts: Vec<(String, u32)>, end: u32) -> Vec<MeshObject> {
    let ends: Vec<u32> = starts.iter().skip(1).map(|s| s.1).chain([end]).collect();
    let kept: Vec<(String, std::ops::Range<u32>)> = starts
        .into_iter()
        .zip(ends)
        .map(|((n, s), e)| (n, s..e))
        .filter(|(_, r)| !r.is_empty())
        .collect();
    let names = unique_names(kept.iter().map(|k| k.0.clone()).collect());
    names
        .into_iter()
        .zip(kept)
        .map(|(name, (_, triangles))| MeshObject { name, triangles })
        .collect()
}

/// Lower-case extension of `path` ("" if none).
pub(crate) fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Read a whole mesh or image file: a regular file of at most [`files::MAX_FILE_BYTES`].
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, SceneError> {
    files::read_file(path, files::MAX_FILE_BYTES, "mesh and image")
}

pub(crate) use atomic::write_atomic;

#[cfg(test)]
pub(crate) mod test_util {
    /// Standard base64 with padding (for data URIs in test glTF files).
    pub(crate) fn base64_encode(b: &[u8]) -> String {
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

    use std::path::PathBuf;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A fresh, unique temporary folder for one test.
    pub fn temp_dir(tag: &str) -> PathBuf {
        static N: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "relight-scene-{}-{}-{}",
            tag,
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        dir
    }

    /// Run `f` on a thread and return its result, failing the test if it takes more than
    /// `secs` seconds (a read blocked on a FIFO would hang the test otherwise).
    pub fn within_seconds<T: Send + 'static>(
        secs: u64,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> T {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(f());
        });
        rx.recv_timeout(std::time::Duration::from_secs(secs))
            .unwrap_or_else(|_| panic!("did not finish within {secs} s (blocked or too slow)"))
    }

    /// Make a FIFO at `path` with `mkfifo`; `false` after a skip of the platform
    /// precondition `fifo` (`relight_testdata::skip_platform`) where that is not possible:
    /// the test then returns.
    pub fn make_fifo(path: &std::path::Path) -> bool {
        let why = match std::process::Command::new("mkfifo").arg(path).status() {
            Ok(s) if s.success() => return true,
            Ok(s) => format!("mkfifo failed ({s})"),
            Err(e) => format!("mkfifo not available: {e}"),
        };
        relight_testdata::skip_platform("fifo", &why);
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_file_is_an_io_error_naming_the_file() {
        let p = test_util::temp_dir("missing").join("nope.obj");
        let e = load_mesh(&p).unwrap_err();
        assert!(matches!(e, SceneError::Io { .. }), "{e}");
        assert!(e.to_string().contains("nope.obj"), "{e}");
    }

    #[test]
    fn unknown_extension_is_refused() {
        let e = load_mesh(Path::new("mesh.stl")).unwrap_err();
        assert!(e.to_string().contains("stl"), "{e}");
    }
}
