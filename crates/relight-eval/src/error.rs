//! [`EvalError`]: why an experiment could not run or write its results.

use std::path::PathBuf;

/// Errors of an experiment. Messages name the file, the scene or the tool involved.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A bake, bundle or frame failed.
    #[error(transparent)]
    Method(#[from] relight_method::MethodError),
    /// A scene or an image could not be read or written.
    #[error(transparent)]
    Scene(#[from] relight_scene::error::SceneError),
    /// A results file could not be written.
    #[error(transparent)]
    Bundle(#[from] relight_bundle::BundleError),
    /// A folder could not be created or read.
    #[error("{path}: {source}")]
    Io {
        /// The folder or file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// Mitsuba 3 is missing or failed.
    #[error("{0}")]
    Mitsuba(String),
    /// The experiment's options are inconsistent (the message says which).
    #[error("{0}")]
    Options(String),
}

impl EvalError {
    /// An [`EvalError::Io`] for `path`.
    pub fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> EvalError + '_ {
        move |source| EvalError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// Results of experiments.
pub type Result<T, E = EvalError> = std::result::Result<T, E>;
