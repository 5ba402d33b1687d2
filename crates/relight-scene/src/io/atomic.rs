//! Atomic writes, and the removal of temporaries left by killed processes.
//!
//! A file `dir/<name>` is written to a temporary `dir/.<name>.relight-tmp.<host>.<pid>.<random>`
//! (hidden, in the same folder so the rename cannot cross file systems), then renamed over
//! `dir/<name>`: a reader never sees a partial file. On an error the temporary is removed; a
//! process killed while writing (SIGKILL, power loss) cannot, so before each write every
//! temporary of that naming in the destination folder whose host is this machine and whose
//! process no longer runs (`/proc/<pid>` absent) is removed, with one line on stderr naming
//! it. Where `/proc` is not mounted nothing is removed. Temporaries of the naming used before
//! (`<name>.tmp-<pid>`, without a host) are removed by the next write of the same `<name>`
//! under the same condition. The rule and the naming are the same in `relight-bundle`, so
//! either crate cleans up after the other.
//!
//! Errors name the output file, never the temporary.

use crate::error::SceneError;
use std::path::{Path, PathBuf};

/// The marker between the output's name and the writer's identity in a temporary's name.
pub const TMP_MARKER: &str = ".relight-tmp.";

/// Write `path` atomically: `write` fills the temporary it is given (and must name `path`,
/// not the temporary, in its errors), which is then renamed over `path`. Stale temporaries
/// in the folder are removed first (see the module docs).
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), SceneError>,
) -> Result<(), SceneError> {
    let name = path
        .file_name()
        .ok_or_else(|| SceneError::malformed(path, "output path has no file name"))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    remove_stale_temporaries(dir, &name.to_string_lossy());
    let tmp = dir.join(temporary_name(&name.to_string_lossy()));
    let result =
        write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(|e| SceneError::io(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

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
/// unreadable), with path separators and dots replaced.
fn host_name() -> String {
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
    use crate::io::test_util::temp_dir;

    /// A process id that is not running: a child that has exited and been reaped.
    pub(crate) fn dead_pid() -> u32 {
        let mut c = std::process::Command::new("true")
            .spawn()
            .expect("run true");
        let pid = c.id();
        c.wait().unwrap();
        assert!(!Path::new(&format!("/proc/{pid}")).exists());
        pid
    }

    #[test]
    fn atomic_write_leaves_no_temporary() {
        let dir = temp_dir("atomic");
        let p = dir.join("out.bin");
        write_atomic(&p, |t| {
            std::fs::write(t, b"abc").map_err(|e| SceneError::io(&p, e))
        })
        .unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"abc");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    }

    #[test]
    fn temporary_names_parse_back() {
        let n = temporary_name("out.exr");
        assert!(n.starts_with(".out.exr.relight-tmp."), "{n}");
        assert_eq!(
            parse_temporary(&n),
            Some((host_name().as_str(), std::process::id()))
        );
        assert_eq!(parse_temporary("out.exr"), None);
        assert_eq!(parse_temporary(".out.exr.relight-tmp.h.12.xyz"), None);
        assert_eq!(
            parse_legacy_temporary("out.exr.tmp-12", "out.exr"),
            Some(12)
        );
        assert_eq!(parse_legacy_temporary("out.exr.tmp-12", "out"), None);
        assert_eq!(parse_legacy_temporary("out.exr.tmp-", "out.exr"), None);
    }

    #[test]
    fn stale_temporary_of_a_dead_process_is_removed_by_the_next_write() {
        if !Path::new("/proc/self").exists() {
            eprintln!("SKIP: no /proc: stale temporaries cannot be recognised here");
            return;
        }
        let dir = temp_dir("stale");
        let p = dir.join("img.hdr");
        let stale = dir.join(format!(
            ".img.hdr{TMP_MARKER}{}.{}.{:016x}",
            host_name(),
            dead_pid(),
            7
        ));
        std::fs::write(&stale, b"partial").unwrap();
        let legacy = dir.join(format!("img.hdr.tmp-{}", dead_pid()));
        std::fs::write(&legacy, b"partial").unwrap();
        // A temporary of a live process (this one) and one of another host are kept.
        let live = dir.join(temporary_name("other.hdr"));
        std::fs::write(&live, b"in progress").unwrap();
        let foreign = dir.join(format!(".x{TMP_MARKER}elsewhere.{}.{:016x}", dead_pid(), 1));
        std::fs::write(&foreign, b"other host").unwrap();
        crate::io::write_hdr(&p, 1, 1, &[crate::Vec3::ONE]).unwrap();
        assert!(!stale.exists(), "stale temporary left behind");
        assert!(
            !legacy.exists(),
            "stale temporary of the former naming left behind"
        );
        assert!(live.exists() && foreign.exists());
        assert!(p.exists());
    }

    #[test]
    fn write_errors_name_the_output_not_the_temporary() {
        let dir = temp_dir("wrerr");
        let p = dir.join("missing-folder").join("out.hdr");
        let (exr, png) = (p.with_extension("exr"), p.with_extension("png"));
        for (out, e) in [
            (
                &p,
                crate::io::write_hdr(&p, 1, 1, &[crate::Vec3::ONE]).unwrap_err(),
            ),
            (
                &exr,
                crate::io::write_exr(&exr, 1, 1, &[crate::Vec3::ONE]).unwrap_err(),
            ),
            (
                &png,
                crate::io::write_png_srgb8(&png, 1, 1, &[[0; 3]]).unwrap_err(),
            ),
        ] {
            let s = e.to_string();
            assert!(s.starts_with(&format!("{}: ", out.display())), "{s}");
        }
    }
}
