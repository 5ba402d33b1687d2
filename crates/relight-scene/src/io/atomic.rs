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
//! under the same condition. The naming and the rule are `relight_bundle::tmpfile`'s, so
//! either crate cleans up after the other.
//!
//! Errors name the output file, never the temporary.

use crate::error::SceneError;
use std::path::Path;

pub use relight_bundle::tmpfile::{remove_stale_temporaries, temporary_name, TMP_MARKER};

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
    fn stale_temporary_of_a_dead_process_is_removed_by_the_next_write() {
        if !Path::new("/proc/self").exists() {
            relight_testdata::skip_platform(
                "proc",
                "no /proc: stale temporaries cannot be recognised here",
            );
            return;
        }
        let dir = temp_dir("stale");
        let p = dir.join("img.hdr");
        let stale = dir.join(format!(
            ".img.hdr{TMP_MARKER}{}.{}.{:016x}",
            relight_bundle::tmpfile::host_name(),
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
