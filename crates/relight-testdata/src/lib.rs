//! Locating the project's shared test data (`../shared` beside the repository), and skipping
//! tests that need it (or Mitsuba 3) where it is absent.
//!
//! Tests that need real data call [`shared_dir`] or [`shared_file`] and, when it returns
//! `None`, return early: users' clones do not have `../shared`. Every skip goes through
//! [`skip`], which prints the reason, and **fails** instead when the environment variable
//! `RELIGHT_REQUIRE_REFERENCE=1` is set (CI has the data and Mitsuba, so there a skip is a
//! bug, not a missing input).

use std::path::PathBuf;

/// Whether skips are failures (`RELIGHT_REQUIRE_REFERENCE=1`).
pub fn references_required() -> bool {
    std::env::var_os("RELIGHT_REQUIRE_REFERENCE").is_some_and(|v| v == "1")
}

/// Skip a test for `reason`: print it, or panic when [`references_required`].
///
/// # Panics
/// When `RELIGHT_REQUIRE_REFERENCE=1`.
pub fn skip(reason: &str) {
    if references_required() {
        panic!("RELIGHT_REQUIRE_REFERENCE=1 but a test would skip: {reason}");
    }
    eprintln!("SKIP: {reason}");
}

/// The shared data folder: `$RELIGHT_SHARED` if set, else `<workspace>/../shared`, if it exists.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("RELIGHT_SHARED") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared"),
    };
    dir.is_dir().then(|| dir.canonicalize().unwrap_or(dir))
}

/// A file under the shared folder (e.g. `data/meshes/bunny.obj`), or `None` after a [`skip`]
/// when it is absent: `let Some(p) = shared_file("...") else { return };`
pub fn shared_file(rel: &str) -> Option<PathBuf> {
    match shared_dir() {
        Some(d) if d.join(rel).is_file() => Some(d.join(rel)),
        Some(d) => {
            skip(&format!("{} not found under {}", rel, d.display()));
            None
        }
        None => {
            skip(&format!(
                "shared data folder (../shared or $RELIGHT_SHARED) not present; needs {rel}"
            ));
            None
        }
    }
}

/// The shared data folder, or `None` after a [`skip`] naming `what` needs it.
pub fn require_shared_dir(what: &str) -> Option<PathBuf> {
    let d = shared_dir();
    if d.is_none() {
        skip(&format!(
            "shared data folder (../shared or $RELIGHT_SHARED) not present; {what} needs it"
        ));
    }
    d
}
