//! Errors of scene and environment IO.
//!
//! Every message names the file and the problem, with the line number for text formats, e.g.
//! `bunny.obj: line 12: face index 900 out of range (300 vertices)`.

use std::fmt;
use std::path::Path;

/// Where in a file a problem was found: the file name and, for text formats, the line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file as the caller named it.
    pub file: String,
    /// 1-based line number (text formats only).
    pub line: Option<usize>,
}

impl Location {
    /// A location naming only the file.
    pub fn file(path: &Path) -> Self {
        Location {
            file: path.display().to_string(),
            line: None,
        }
    }

    /// A location naming the file and a 1-based line.
    pub fn line(path: &Path, line: usize) -> Self {
        Location {
            file: path.display().to_string(),
            line: Some(line),
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "{}: line {}", self.file, l),
            None => write!(f, "{}", self.file),
        }
    }
}

/// A value that breaks an invariant or a documented range, returned by the `validate()`
/// methods of descriptions and built structures ([`crate::camera::Camera::validate`],
/// [`crate::scene_file::SceneDesc::validate`], [`crate::meshops::validate`], ...). The message
/// names the field and the rule; callers add the file.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Invalid(pub String);

impl From<String> for Invalid {
    fn from(s: String) -> Self {
        Invalid(s)
    }
}

impl std::ops::Deref for Invalid {
    type Target = str;

    /// The message.
    fn deref(&self) -> &str {
        &self.0
    }
}

impl From<Invalid> for String {
    fn from(e: Invalid) -> Self {
        e.0
    }
}

/// A failure to read or write a scene or image file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The operating system refused (missing file, permission, disk full, ...).
    ///
    /// The OS error is part of the message and deliberately *not* a `source()`, so that
    /// error chains (`anyhow`'s `{:#}`) print it once.
    #[error("{file}: {error}")]
    Io {
        /// The file.
        file: String,
        /// The underlying error (shown in the message).
        error: std::io::Error,
    },
    /// A path that is not a regular file (a FIFO, a device such as `/dev/zero`, a directory):
    /// refused before reading (see `io::files`).
    #[error("{file}: is {kind}: relight reads only regular files")]
    NotRegularFile {
        /// The path.
        file: String,
        /// What it is ("a FIFO", "a character device", ...).
        kind: String,
    },
    /// A reference inside a model (glTF buffer URI, OBJ `mtllib`) that leads outside the
    /// model's folder, refused by the default path policy (see `io::files`).
    #[error("{model}: {what} '{reference}' leads to {resolved}, outside the model's folder {folder}: models may only refer to files in their own folder (allow with --allow-outside-paths, PathPolicy::allow_outside)")]
    OutsideFolder {
        /// The model file containing the reference.
        model: String,
        /// Which reference ("buffer 0 uri", "mtllib").
        what: String,
        /// The reference as written.
        reference: String,
        /// Where it leads.
        resolved: String,
        /// The model's folder.
        folder: String,
    },
    /// Geometry over the triangle limit (`LoadOptions::max_triangles`), refused before it is
    /// expanded where the format allows.
    #[error("{at}: {}{count} triangles{} exceed the limit of {limit} triangles; raise it with --max-triangles (LoadOptions::max_triangles) if this much geometry is intended", if *at_least { "at least " } else { "" }, others_note(*others))]
    TooManyTriangles {
        /// The file (and line) or scene shape.
        at: Location,
        /// Triangles of this file or shape (a lower bound when `at_least`).
        count: u64,
        /// Whether reading stopped at the limit, so `count` is a lower bound.
        at_least: bool,
        /// Triangles of the scene's other shapes already loaded (0 for a lone file).
        others: u64,
        /// The limit.
        limit: u64,
    },
    /// The file is not valid in its format (bad syntax, index out of range, truncated).
    #[error("{at}: {msg}")]
    Malformed {
        /// File and line.
        at: Location,
        /// What is wrong.
        msg: String,
    },
    /// A size announced by the file is absurd or beyond what the data could hold; refused
    /// before allocating.
    #[error("{at}: {msg}")]
    TooLarge {
        /// File and line.
        at: Location,
        /// What is too large.
        msg: String,
    },
    /// A valid file using a feature relight does not read (e.g. a sparse glTF accessor).
    #[error("{at}: unsupported: {msg}")]
    Unsupported {
        /// File and line.
        at: Location,
        /// The feature.
        msg: String,
    },
    /// A pixel that cannot be radiance (NaN, infinite or negative).
    #[error("{file}: pixel (x {x}, y {y}) is {value}: environment radiance must be finite and non-negative")]
    BadPixel {
        /// The file.
        file: String,
        /// Column from the left.
        x: usize,
        /// Row from the top.
        y: usize,
        /// The offending values, formatted.
        value: String,
    },
    /// A parameter outside its valid range (e.g. a sky turbidity of 20).
    #[error("invalid parameter: {msg}")]
    InvalidParameter {
        /// Which parameter and its valid range.
        msg: String,
    },
    /// A mesh that is empty or breaks a `TriMesh` invariant.
    #[error("{file}: {msg}")]
    InvalidMesh {
        /// The file (or a description of the mesh's origin).
        file: String,
        /// What is wrong.
        msg: String,
    },
}

fn others_note(others: u64) -> String {
    if others == 0 {
        String::new()
    } else {
        format!(" (plus {others} in the scene's other shapes)")
    }
}

impl SceneError {
    /// An IO error on `path`.
    pub fn io(path: &Path, error: std::io::Error) -> Self {
        SceneError::Io {
            file: path.display().to_string(),
            error,
        }
    }

    /// A format error in `path` (no line).
    pub fn malformed(path: &Path, msg: impl Into<String>) -> Self {
        SceneError::Malformed {
            at: Location::file(path),
            msg: msg.into(),
        }
    }

    /// A format error at `line` (1-based) of `path`.
    pub fn malformed_at(path: &Path, line: usize, msg: impl Into<String>) -> Self {
        SceneError::Malformed {
            at: Location::line(path, line),
            msg: msg.into(),
        }
    }

    /// An absurd size in `path`.
    pub fn too_large(path: &Path, msg: impl Into<String>) -> Self {
        SceneError::TooLarge {
            at: Location::file(path),
            msg: msg.into(),
        }
    }

    /// An unsupported feature of `path`.
    pub fn unsupported(path: &Path, msg: impl Into<String>) -> Self {
        SceneError::Unsupported {
            at: Location::file(path),
            msg: msg.into(),
        }
    }

    /// An invalid mesh from `path`.
    pub fn invalid_mesh(path: &Path, msg: impl Into<String>) -> Self {
        SceneError::InvalidMesh {
            file: path.display().to_string(),
            msg: msg.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The error and its sources joined by ": ", as `anyhow` prints `{:#}`.
    fn chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut cur = e.source();
        while let Some(c) = cur {
            s += &format!(": {c}");
            cur = c.source();
        }
        s
    }

    #[test]
    fn os_errors_print_once_in_an_error_chain() {
        let p = Path::new("/nonexistent-relight-dir/bunny.obj");
        let e = crate::io::load_mesh(p).unwrap_err();
        let s = chain(&e);
        assert_eq!(s.matches("os error 2").count(), 1, "{s}");
        assert!(s.starts_with("/nonexistent-relight-dir/bunny.obj: "), "{s}");
    }
}
