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

/// A failure to read or write a scene or image file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The operating system refused (missing file, permission, disk full, ...).
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
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

impl SceneError {
    /// An IO error on `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        SceneError::Io {
            file: path.display().to_string(),
            source,
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
