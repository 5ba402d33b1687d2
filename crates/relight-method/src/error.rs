//! [`MethodError`]: why a bake, a bundle or a frame could not be made.

use crate::{BakeKind, MethodKind};
use std::path::PathBuf;

/// Errors of the method layer. Messages name the file where there is one, the setting or the
/// method involved, and what to do instead.
#[derive(Debug, thiserror::Error)]
pub enum MethodError {
    /// A setting is out of range or does not apply (the message names it).
    #[error("{0}")]
    Settings(String),
    /// The bake itself failed (invalid scene, thread pool...).
    #[error(transparent)]
    Bake(#[from] relight_bake::BakeError),
    /// The ray caster could not be built.
    #[error("{path}: cannot build the ray caster: {message}")]
    Caster {
        /// The scene file.
        path: PathBuf,
        /// What the back-end said.
        message: String,
    },
    /// Reading or writing the bundle file failed (IO, checksums, layout).
    #[error(transparent)]
    Bundle(#[from] relight_bundle::BundleError),
    /// The bundle is readable but its contents are not a valid bake of its method.
    #[error("{path}: {message}")]
    Invalid {
        /// The bundle.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The bundle holds another method's bake than the one asked for.
    #[error("{path}: holds a `{found}` bake, but --method {method} renders `{needed}` bakes (bake the scene with `relight bake --method {needed}`)", found = found.name(), needed = needed.name(), method = method.name())]
    WrongBake {
        /// The bundle.
        path: PathBuf,
        /// What it holds.
        found: BakeKind,
        /// What the method needs.
        needed: BakeKind,
        /// The method asked for.
        method: MethodKind,
    },
    /// A part of a sharded bake cannot be rendered before it is merged.
    #[error("{path}: is {part}; merge the parts before rendering")]
    PartialBake {
        /// The bundle.
        path: PathBuf,
        /// Which part, and what it holds.
        part: String,
    },
    /// The parts given to a merge do not make one whole bake (the message says why).
    #[error("{path}: {message}")]
    Merge {
        /// The part at fault.
        path: PathBuf,
        /// What does not match.
        message: String,
    },
    /// Environment preparation failed (e.g. the decomposition of `hybrid`).
    #[error("{0}")]
    Environment(String),
}

impl MethodError {
    /// An [`MethodError::Invalid`] for the bundle at `path`.
    pub fn invalid(path: &std::path::Path, message: impl Into<String>) -> Self {
        MethodError::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}
