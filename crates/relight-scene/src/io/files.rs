//! Which files a scene may read, and how: the one place where relight-scene opens input files.
//!
//! Every reader (scene descriptions, OBJ, MTL, PLY, glTF and its buffers, `.hdr`, `.exr`)
//! goes through [`read_file`] (or [`read_prefix`]), and every reference found *inside* a
//! model goes through [`resolve_model_ref`]. The rules, for hostile or careless input:
//!
//! 1. **A scene description names files as the user wrote them.** A scene file is a list of
//!    files its author chose (`"file"` of a mesh, `"path"` of an environment). Relative paths
//!    are resolved against the scene file's folder, and may use `..` or be absolute: the
//!    example scenes refer to `../../shared/data/...` by design. They are *not* confined.
//! 2. **A model may only refer to files in its own folder.** References written inside a
//!    model file — glTF buffer and image `uri`s, OBJ `mtllib`, and the texture maps a
//!    material names in a scene or material file (`crate::material::maps`) — are resolved
//!    against the
//!    model's folder (the folder of the path the model was opened by) and refused when they
//!    are absolute, climb out with `..`, or lead out through a symbolic link (checked on the
//!    canonical path). A model downloaded from the web cannot make relight read
//!    `/etc/passwd` into a bundle. [`PathPolicy::allow_outside`] (the CLI's
//!    `--allow-outside-paths`) lifts this rule; rules 3 and 4 still apply. URIs with a scheme
//!    other than `data:` (`file:`, `http:`) are refused either way.
//! 3. **Only regular files are read.** The path's metadata is checked before opening (so a
//!    FIFO is never opened, which would block), and the opened file's own metadata
//!    (`fstat`) is checked again after, so a swap in between cannot slip a device or FIFO
//!    through. Directories, FIFOs, sockets and devices (`/dev/zero`, `/dev/stdin`) are
//!    refused with [`SceneError::NotRegularFile`].
//! 4. **Reads are bounded.** A file is read only up to the size its metadata states and at
//!    most a cap: [`MAX_TEXT_BYTES`] (64 MiB) for scene descriptions and MTL libraries,
//!    [`MAX_FILE_BYTES`] (4 GiB) for meshes and images, and a glTF buffer's `byteLength` for
//!    its external `.bin`. A file over its cap is refused with [`SceneError::TooLarge`]
//!    before anything is read.
//!
//! What a file may *expand to* is bounded separately: [`LoadOptions::max_triangles`] for
//! geometry (glTF instancing, OBJ, PLY, procedural shapes and the merged scene) and the
//! pixel and expansion limits of [`super::image`] for images.

use crate::error::SceneError;
use std::fs::File;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// Largest scene description or MTL library read, in bytes (64 MiB): text files written by
/// hand or by exporters, far smaller in practice.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;
/// Largest mesh or image file read, in bytes (4 GiB: GLB's own size limit, and about twice a
/// binary PLY of [`DEFAULT_MAX_TRIANGLES`] triangles).
pub const MAX_FILE_BYTES: u64 = 4 << 30;
/// Default of [`LoadOptions::max_triangles`]: 50 million triangles, about 2 GB of
/// [`crate::mesh::TriMesh`] before any bake data.
pub const DEFAULT_MAX_TRIANGLES: usize = 50_000_000;

/// Whether references inside models may leave the model's folder (rule 2 of the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PathPolicy {
    /// Follow model-internal references (glTF buffer URIs, OBJ `mtllib`) outside the model's
    /// folder: absolute paths, `..` past the folder, symbolic links out of it. Default
    /// `false`. Regular-file and size checks apply either way.
    pub allow_outside: bool,
}

/// Limits and policies of loading meshes and scenes (see the module docs).
///
/// The CLI maps `--allow-outside-paths` to `paths.allow_outside` and `--max-triangles` to
/// `max_triangles`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadOptions {
    /// Where model-internal references may lead.
    pub paths: PathPolicy,
    /// Most triangles a mesh file may expand to (after glTF instancing and polygon
    /// triangulation), and most triangles of a whole scene (all shapes merged). Vertices are
    /// limited to three times this. Checked before allocating where the format announces its
    /// size (glTF, PLY, procedural shapes), while reading otherwise (OBJ).
    pub max_triangles: usize,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            paths: PathPolicy::default(),
            max_triangles: DEFAULT_MAX_TRIANGLES,
        }
    }
}

impl LoadOptions {
    /// The triangle limit as a [`SceneError::TooManyTriangles`] check: `Ok` when
    /// `count <= max_triangles`; `at` (called only on failure) locates the problem.
    pub(crate) fn check_triangles(
        &self,
        count: u64,
        at_least: bool,
        at: impl FnOnce() -> crate::error::Location,
    ) -> Result<(), SceneError> {
        if count <= self.max_triangles as u64 {
            return Ok(());
        }
        Err(SceneError::TooManyTriangles {
            at: at(),
            count,
            at_least,
            others: 0,
            limit: self.max_triangles as u64,
        })
    }
}

/// Describe what kind of non-regular file `meta` is.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    let ft = meta.file_type();
    if ft.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_fifo() {
            return "a FIFO";
        }
        if ft.is_socket() {
            return "a socket";
        }
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
    }
    "not a regular file"
}

fn check_regular(path: &Path, meta: &std::fs::Metadata) -> Result<(), SceneError> {
    if meta.is_file() {
        Ok(())
    } else {
        Err(SceneError::NotRegularFile {
            file: path.display().to_string(),
            kind: kind_of(meta).to_string(),
        })
    }
}

/// Open `path` for reading if it is a regular file (rule 3 of the module docs); returns the
/// file and its size in bytes.
pub fn open_regular(path: &Path) -> Result<(File, u64), SceneError> {
    // Before opening: opening a FIFO would block until a writer appears.
    let meta = std::fs::metadata(path).map_err(|e| SceneError::io(path, e))?;
    check_regular(path, &meta)?;
    let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
    // After opening: what was opened, whatever happened to the path in between.
    let meta = file.metadata().map_err(|e| SceneError::io(path, e))?;
    check_regular(path, &meta)?;
    Ok((file, meta.len()))
}

/// Read a whole regular file of at most `cap` bytes (rules 3 and 4 of the module docs).
/// `what` names the kind of file in the error ("scene description", "mesh", ...).
pub fn read_file(path: &Path, cap: u64, what: &str) -> Result<Vec<u8>, SceneError> {
    let (file, len) = open_regular(path)?;
    if len > cap {
        return Err(SceneError::too_large(
            path,
            format!("{len} bytes exceed the {what} size limit of {cap} bytes"),
        ));
    }
    // Read at most one byte past the stated size, so a file that grows meanwhile cannot
    // make the read unbounded.
    let mut out = Vec::with_capacity(len as usize);
    file.take(cap.min(len.saturating_add(1)))
        .read_to_end(&mut out)
        .map_err(|e| SceneError::io(path, e))?;
    if out.len() as u64 > len {
        return Err(SceneError::malformed(
            path,
            format!("the file grew while being read (stated {len} bytes)"),
        ));
    }
    Ok(out)
}

/// Read the first `n` bytes of a regular file (fewer if it is shorter): a glTF buffer is
/// read up to its `byteLength`, whatever follows.
pub fn read_prefix(path: &Path, n: u64) -> Result<Vec<u8>, SceneError> {
    let (file, len) = open_regular(path)?;
    let mut out = Vec::with_capacity(n.min(len) as usize);
    file.take(n.min(len))
        .read_to_end(&mut out)
        .map_err(|e| SceneError::io(path, e))?;
    Ok(out)
}

/// Resolve `reference`, written inside the model file `model` (a glTF buffer URI, an OBJ
/// `mtllib`, ...), against the model's folder, applying rule 2 of the module docs:
/// unless `policy.allow_outside`, a reference that is absolute, climbs above the folder with
/// `..`, or whose canonical path (symbolic links followed) is outside the folder's canonical
/// path is refused with [`SceneError::OutsideFolder`]. `what` names the reference in errors
/// ("buffer 0 uri", "mtllib"). A reference to a file that does not exist is returned as is
/// (reading it then fails naming it).
pub fn resolve_model_ref(
    model: &Path,
    reference: &str,
    policy: &PathPolicy,
    what: &str,
) -> Result<PathBuf, SceneError> {
    let folder = match model.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let rel = Path::new(reference);
    let joined = folder.join(rel);
    if policy.allow_outside {
        return Ok(joined);
    }
    let outside = |resolved: &Path| SceneError::OutsideFolder {
        model: model.display().to_string(),
        what: what.to_string(),
        reference: reference.to_string(),
        resolved: resolved.display().to_string(),
        folder: folder.display().to_string(),
    };
    // Lexically: no root, no prefix, never above the folder.
    let mut depth: isize = 0;
    for c in rel.components() {
        match c {
            Component::Prefix(_) | Component::RootDir => return Err(outside(rel)),
            Component::CurDir => {}
            Component::ParentDir => depth -= 1,
            Component::Normal(_) => depth += 1,
        }
        if depth < 0 {
            return Err(outside(&joined));
        }
    }
    // Physically: symbolic links (of the file or of folders on the way) must stay inside.
    match (joined.canonicalize(), folder.canonicalize()) {
        (Ok(target), Ok(root)) if target.starts_with(&root) => Ok(target),
        (Ok(target), Ok(_)) => Err(outside(&target)),
        _ => Ok(joined),
    }
}

/// Decode `%XX` escapes of a URI path (glTF URIs are RFC 3986 references). Invalid escapes
/// are kept as written.
pub(crate) fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%' && i + 2 < b.len() {
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests;
