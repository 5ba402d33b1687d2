//! Names of atomic-write temporaries, and the removal of those left by killed processes.
//!
//! A temporary for output `dir/<name>` is `dir/.<name>.relight-tmp.<host>.<pid>.<random>`:
//! hidden, in the output's folder (so the final rename stays on one file system), and telling
//! which process on which machine wrote it. [`remove_stale_temporaries`] removes those of this
//! host whose process no longer runs (`/proc/<pid>` absent), and those of the former naming
//! `<name>.tmp-<pid>` for the output being written. A temporary of another host (a folder
//! shared over the network) is never touched; where `/proc` is not mounted nothing is removed.
//! relight-scene's atomic writer uses the same naming and rule.

use std::path::{Path, PathBuf};

/// The marker between the output's name and the writer's identity in a temporary's name.
pub const TMP_MARKER: &str = ".relight-tmp.";

/// The temporary's file name for output `name` written by this process.
pub fn temporary_name(name: &str) -> String {
    format!(
        ".{name}{TMP_MARKER}{}.{}.{:016x}",
        host_name(),
        std::process::id(),
        random_u64()
    )
}

/// This machine's name as used in temporaries (`/proc/sys/kernel/hostname`, "unknown" if
/// unreadable), with every character but ASCII letters, digits and `-` replaced by `_`.
pub fn host_name() -> String {
    let h = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    let h: String = h
        .trim()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if h.is_empty() {
        "unknown".into()
    } else {
        h
    }
}

/// A value that differs between calls and processes (not cryptographic).
fn random_u64() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    if let Ok(t) = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        h.write_u128(t.as_nanos());
    }
    h.finish()
}

/// The writer's host and process id of a temporary's file name, if it is one.
fn parse_temporary(file_name: &str) -> Option<(&str, u32)> {
    let rest = file_name.strip_prefix('.')?;
    let (_, who) = rest.rsplit_once(TMP_MARKER)?;
    let mut parts = who.rsplitn(3, '.');
    let random = parts.next()?;
    let pid = parts.next()?.parse().ok()?;
    let host = parts.next()?;
    (random.len() == 16 && random.bytes().all(|b| b.is_ascii_hexdigit())).then_some((host, pid))
}

/// The process id of a temporary of the former naming, `<output>.tmp-<pid>`, for `output`.
fn parse_legacy_temporary(file_name: &str, output: &str) -> Option<u32> {
    let pid = file_name.strip_prefix(output)?.strip_prefix(".tmp-")?;
    pid.bytes()
        .all(|b| b.is_ascii_digit())
        .then(|| pid.parse().ok())
        .flatten()
}

/// Remove the temporaries in `dir` left by processes of this host that no longer run (and
/// those of the former naming for `output`), saying so on stderr; returns the paths removed.
/// Best effort: unreadable folders and failed removals are skipped silently.
pub fn remove_stale_temporaries(dir: &Path, output: &str) -> Vec<PathBuf> {
    let mut removed = Vec::new();
    if !Path::new("/proc/self").exists() {
        return removed; // cannot tell live processes from dead ones
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return removed;
    };
    let (host, me) = (host_name(), std::process::id());
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let (h, pid) = match parse_temporary(name) {
            Some(t) => t,
            None => match parse_legacy_temporary(name, output) {
                Some(pid) => (host.as_str(), pid),
                None => continue,
            },
        };
        let alive = pid == me || Path::new(&format!("/proc/{pid}")).exists();
        if h != host || alive || !entry.file_type().is_ok_and(|t| t.is_file()) {
            continue;
        }
        let p = entry.path();
        if std::fs::remove_file(&p).is_ok() {
            eprintln!(
                "relight: removed stale temporary file {} (left by process {pid}, no longer running)",
                p.display()
            );
            removed.push(p);
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_parse_back() {
        let n = temporary_name("b.relight");
        assert!(n.starts_with(".b.relight.relight-tmp."), "{n}");
        assert_eq!(
            parse_temporary(&n),
            Some((host_name().as_str(), std::process::id()))
        );
        assert_eq!(parse_temporary("b.relight"), None);
        assert_eq!(parse_temporary(".b.relight.relight-tmp.h.1.0123"), None);
        assert_eq!(
            parse_legacy_temporary("b.relight.tmp-77", "b.relight"),
            Some(77)
        );
        assert_eq!(
            parse_legacy_temporary("b.relight.tmp-7x", "b.relight"),
            None
        );
    }
}
