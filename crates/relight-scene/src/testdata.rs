//! Locating the project's shared test data (`../shared` beside the repository).
//!
//! Tests that need real data call [`shared_dir`] or [`shared_file`] and, when it returns
//! `None`, print why and return early (skip): users' clones do not have `../shared`.

use std::path::PathBuf;

/// The shared data folder: `$RELIGHT_SHARED` if set, else `<workspace>/../shared`, if it exists.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("RELIGHT_SHARED") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared"),
    };
    dir.is_dir().then(|| dir.canonicalize().unwrap_or(dir))
}

/// A file under the shared folder (e.g. `data/meshes/bunny.obj`), or `None` with a printed
/// reason when it is absent, so a test can skip: `let Some(p) = shared_file("...") else { return };`
pub fn shared_file(rel: &str) -> Option<PathBuf> {
    match shared_dir() {
        Some(d) if d.join(rel).is_file() => Some(d.join(rel)),
        Some(d) => {
            eprintln!("SKIP: {} not found under {}", rel, d.display());
            None
        }
        None => {
            eprintln!(
                "SKIP: shared data folder (../shared or $RELIGHT_SHARED) not present; needs {rel}"
            );
            None
        }
    }
}
