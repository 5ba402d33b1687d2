//! Locating the project's shared test data (`../shared` beside the repository), and one policy
//! for every test that skips.
//!
//! Tests that need real data call [`shared_dir`] or [`shared_file`] and, when it returns
//! `None`, return early: users' clones do not have `../shared`.
//!
//! # The skip policy
//!
//! A test that cannot run here says why and returns; it never passes silently. Every skip
//! goes through one of two functions:
//!
//! - [`skip`]`(reason)`, for inputs CI always has (the shared data, Mitsuba 3, Slurm, Xvfb, a
//!   Vulkan adapter);
//! - [`skip_platform`]`(name, reason)`, for a platform precondition that a CI machine may lack,
//!   named by one of the keys of [`PLATFORM_PRECONDITIONS`]: `avx2`, `avx512`, `fifo`, `proc`,
//!   `dev-zero`, `feature-gpu`, `feature-view`.
//!
//! Both print a line starting with `SKIP` on stderr. With `RELIGHT_REQUIRE_REFERENCE=1` (set by CI) a skip is
//! a failure (the test panics), except a [`skip_platform`] whose name is listed in the
//! comma-separated allow-list `RELIGHT_ALLOW_SKIP` (e.g. `RELIGHT_ALLOW_SKIP=avx512` on a
//! machine without AVX-512). CI prints the allow-list it runs with. A name that is not a key
//! of [`PLATFORM_PRECONDITIONS`], in a test or in `RELIGHT_ALLOW_SKIP`, is refused, so a typo
//! cannot allow a skip. [`skip_verdict`] is the whole policy as a function of the two
//! variables' values.
//!
//! # Textured glTF assets
//!
//! [`gltf_assets()`] builds, once per test run, textured glTF files made by third-party npm tools
//! (`obj2gltf`, `@gltf-transform`) from the shared `spot.obj` and validated by the Khronos
//! `gltf-validator`, and returns their paths; [`validate_gltf`] runs the validator on any file.
//! Both [`skip`] (with the reason) without `node`, the tools `scripts/setup.sh` installs, or
//! the shared data. See [`mod@gltf_assets`] for the assets and the cache.

pub mod gltf_assets;

pub use gltf_assets::{gltf_assets, validate_gltf, GltfAssets, ValidatorVerdict};

use std::path::PathBuf;

/// The platform preconditions a test may skip for, by name, each with what it needs: the only
/// names [`skip_platform`] and `RELIGHT_ALLOW_SKIP` take.
pub const PLATFORM_PRECONDITIONS: &[(&str, &str)] = &[
    ("avx2", "an x86-64 CPU with AVX2 and FMA"),
    ("avx512", "an x86-64 CPU with AVX-512F and AVX-512VL"),
    ("fifo", "named pipes made by `mkfifo`"),
    ("proc", "Linux's /proc (process status and liveness)"),
    ("dev-zero", "the character device /dev/zero"),
    ("feature-gpu", "a build with `--features gpu`"),
    ("feature-view", "a build with `--features view`"),
];

/// What a skip does under the policy (see the module docs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// Print the message (on stderr) and let the test return.
    Skip(String),
    /// Fail the test with the message.
    Fail(String),
}

fn known_names() -> String {
    PLATFORM_PRECONDITIONS
        .iter()
        .map(|(k, _)| *k)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The skip policy as a pure function: `require_reference` and `allow_skip` are the values of
/// `RELIGHT_REQUIRE_REFERENCE` and `RELIGHT_ALLOW_SKIP` (`None` when unset), `platform` the
/// precondition's name for [`skip_platform`] (`None` for [`skip`]).
pub fn skip_verdict(
    require_reference: Option<&str>,
    allow_skip: Option<&str>,
    platform: Option<&str>,
    reason: &str,
) -> Verdict {
    let known = |n: &str| PLATFORM_PRECONDITIONS.iter().any(|(k, _)| *k == n);
    if let Some(name) = platform.filter(|n| !known(n)) {
        return Verdict::Fail(format!(
            "a test skips for '{name}', which is not a platform precondition (known: {}): \
             {reason}",
            known_names()
        ));
    }
    let label = platform.map_or(String::new(), |n| format!(" ({n})"));
    if require_reference != Some("1") {
        return Verdict::Skip(format!("SKIP{label}: {reason}"));
    }
    let allowed: Vec<&str> = allow_skip
        .unwrap_or("")
        .split(',')
        .map(str::trim)
        .filter(|n| !n.is_empty())
        .collect();
    if let Some(bad) = allowed.iter().find(|n| !known(n)) {
        return Verdict::Fail(format!(
            "RELIGHT_ALLOW_SKIP names '{bad}', which is not a platform precondition (known: \
             {}); a test would skip{label}: {reason}",
            known_names()
        ));
    }
    match platform {
        Some(name) if allowed.contains(&name) => Verdict::Skip(format!(
            "SKIP{label}, allowed by RELIGHT_ALLOW_SKIP: {reason}"
        )),
        Some(name) => Verdict::Fail(format!(
            "RELIGHT_REQUIRE_REFERENCE=1 but a test would skip{label}, and RELIGHT_ALLOW_SKIP={} \
             does not list '{name}': {reason}",
            allow_skip.unwrap_or("")
        )),
        None => Verdict::Fail(format!(
            "RELIGHT_REQUIRE_REFERENCE=1 but a test would skip: {reason}"
        )),
    }
}

/// Whether skips are failures (`RELIGHT_REQUIRE_REFERENCE=1`), apart from the platform
/// preconditions listed in `RELIGHT_ALLOW_SKIP`.
pub fn references_required() -> bool {
    std::env::var_os("RELIGHT_REQUIRE_REFERENCE").is_some_and(|v| v == "1")
}

/// [`skip_verdict`] on this process's environment: print the skip, or panic.
#[track_caller]
fn apply(platform: Option<&str>, reason: &str) {
    let var = |k: &str| std::env::var_os(k).map(|v| v.to_string_lossy().into_owned());
    let (require, allow) = (var("RELIGHT_REQUIRE_REFERENCE"), var("RELIGHT_ALLOW_SKIP"));
    match skip_verdict(require.as_deref(), allow.as_deref(), platform, reason) {
        Verdict::Skip(m) => eprintln!("{m}"),
        Verdict::Fail(m) => panic!("{m}"),
    }
}

/// Skip a test for `reason` (an input CI has: the shared data, Mitsuba 3, ...): print it, or
/// panic when [`references_required`]. The caller returns after it.
///
/// # Panics
/// When `RELIGHT_REQUIRE_REFERENCE=1`.
#[track_caller]
pub fn skip(reason: &str) {
    apply(None, reason);
}

/// Skip a test for want of the platform precondition `name` (a key of
/// [`PLATFORM_PRECONDITIONS`], e.g. `avx512`): print the reason, or panic when
/// [`references_required`] and `name` is not listed in `RELIGHT_ALLOW_SKIP`. The caller
/// returns after it (or goes on without the part that needs `name`).
///
/// # Panics
/// When `RELIGHT_REQUIRE_REFERENCE=1` and `RELIGHT_ALLOW_SKIP` does not list `name`; when
/// `name`, or a name in `RELIGHT_ALLOW_SKIP`, is not a key of [`PLATFORM_PRECONDITIONS`].
#[track_caller]
pub fn skip_platform(name: &str, reason: &str) {
    apply(Some(name), reason);
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
#[track_caller]
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
#[track_caller]
pub fn require_shared_dir(what: &str) -> Option<PathBuf> {
    let d = shared_dir();
    if d.is_none() {
        skip(&format!(
            "shared data folder (../shared or $RELIGHT_SHARED) not present; {what} needs it"
        ));
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn skips(v: Verdict) -> String {
        match v {
            Verdict::Skip(m) => m,
            Verdict::Fail(m) => panic!("expected a skip, got a failure: {m}"),
        }
    }

    fn fails(v: Verdict) -> String {
        match v {
            Verdict::Fail(m) => m,
            Verdict::Skip(m) => panic!("expected a failure, got a skip: {m}"),
        }
    }

    #[test]
    fn without_the_requirement_every_skip_is_printed() {
        for require in [None, Some("0"), Some(""), Some("yes")] {
            for allow in [None, Some(""), Some("avx512")] {
                let m = skips(skip_verdict(require, allow, None, "no data"));
                assert_eq!(m, "SKIP: no data");
                let m = skips(skip_verdict(require, allow, Some("fifo"), "no mkfifo"));
                assert_eq!(m, "SKIP (fifo): no mkfifo");
            }
        }
    }

    #[test]
    fn under_the_requirement_a_skip_outside_the_allow_list_fails() {
        let r = Some("1");
        // A data or Mitsuba skip fails whatever the allow-list says.
        for allow in [None, Some(""), Some("avx2,avx512,fifo,proc,dev-zero")] {
            let m = fails(skip_verdict(r, allow, None, "no data"));
            assert!(
                m.contains("RELIGHT_REQUIRE_REFERENCE=1") && m.ends_with("no data"),
                "{m}"
            );
        }
        // A platform skip fails unless its own name is listed.
        for allow in [
            None,
            Some(""),
            Some("avx2"),
            Some("avx512x"),
            Some("avx2, fifo"),
        ] {
            let v = skip_verdict(r, allow, Some("avx512"), "no AVX-512");
            let m = fails(v);
            assert!(m.contains("avx512") && m.ends_with("no AVX-512"), "{m}");
        }
    }

    #[test]
    fn under_the_requirement_a_listed_platform_skip_is_printed() {
        let r = Some("1");
        for allow in [
            "avx512",
            "avx2,avx512",
            " fifo , avx512 ,",
            "feature-gpu,avx512",
        ] {
            let m = skips(skip_verdict(r, Some(allow), Some("avx512"), "no AVX-512"));
            assert_eq!(
                m,
                "SKIP (avx512), allowed by RELIGHT_ALLOW_SKIP: no AVX-512"
            );
        }
        let allow = Some("feature-gpu,feature-view");
        skips(skip_verdict(r, allow, Some("feature-gpu"), "no gpu"));
        skips(skip_verdict(r, allow, Some("feature-view"), "no view"));
        fails(skip_verdict(r, allow, Some("proc"), "no /proc"));
    }

    #[test]
    fn unknown_names_are_refused() {
        // In a test: always (a typo in the test's name would never be allowed).
        for r in [None, Some("1")] {
            let m = fails(skip_verdict(r, Some("avx-512"), Some("avx-512"), "x"));
            assert!(m.contains("'avx-512'") && m.contains("avx512"), "{m}");
        }
        // In the allow-list, under the requirement: a typo does not pass unnoticed.
        let m = fails(skip_verdict(
            Some("1"),
            Some("avx512,dev_zero"),
            Some("avx512"),
            "x",
        ));
        assert!(m.contains("RELIGHT_ALLOW_SKIP names 'dev_zero'"), "{m}");
    }

    #[test]
    fn the_named_preconditions_are_distinct_short_keys() {
        let names: Vec<&str> = PLATFORM_PRECONDITIONS.iter().map(|(k, _)| *k).collect();
        for (i, n) in names.iter().enumerate() {
            assert!(!names[..i].contains(n), "{n} twice");
            assert!(
                !n.is_empty()
                    && n.bytes()
                        .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-'),
                "{n}"
            );
        }
        for n in [
            "avx2",
            "avx512",
            "fifo",
            "proc",
            "dev-zero",
            "feature-gpu",
            "feature-view",
        ] {
            assert!(names.contains(&n), "{n}");
        }
    }
}
