//! Checks of output paths before any work starts, so that a long bake or render never ends
//! on a folder that does not exist, a file name the writer does not know, or an input about
//! to be overwritten.

use std::path::{Path, PathBuf};

/// Why an output path is refused. Every message names the output.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// Its extension is not one of those the writer knows.
    #[error("{}: unknown output extension '{ext}' (expected {expected})", path.display())]
    Extension {
        /// The output.
        path: PathBuf,
        /// Its extension (lower case, may be empty).
        ext: String,
        /// The extensions accepted, comma-separated.
        expected: String,
    },
    /// Its folder does not exist, or it names a folder.
    #[error("{}: {problem}", path.display())]
    Place {
        /// The output.
        path: PathBuf,
        /// What is wrong with where it goes.
        problem: String,
    },
    /// Its folder cannot be written.
    #[error("{}: cannot write in {}: {error}", path.display(), dir.display())]
    NotWritable {
        /// The output.
        path: PathBuf,
        /// Its folder.
        dir: PathBuf,
        /// The OS error.
        error: std::io::Error,
    },
    /// It is also an input, or given twice.
    #[error("{}: {problem}", path.display())]
    Clash {
        /// The output.
        path: PathBuf,
        /// Which clash.
        problem: &'static str,
    },
}

/// Check `outs` before any work: an extension in `exts` (lower case), an existing folder that
/// can be written (a probe file is created and removed), not a folder, not one of `inputs`
/// (compared after resolving links), not given twice.
///
/// # Errors
/// The first [`OutputError`].
pub fn check_outputs(outs: &[&Path], exts: &[&str], inputs: &[&Path]) -> Result<(), OutputError> {
    let inputs: Vec<PathBuf> = inputs
        .iter()
        .filter_map(|p| p.canonicalize().ok())
        .collect();
    for (i, out) in outs.iter().enumerate() {
        let path = out.to_path_buf();
        let ext = out
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if !exts.contains(&ext.as_str()) {
            return Err(OutputError::Extension {
                path,
                ext,
                expected: exts.join(", "),
            });
        }
        let dir = match out.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let place = |problem: String| OutputError::Place {
            path: out.to_path_buf(),
            problem,
        };
        if !dir.is_dir() {
            return Err(place(format!(
                "the folder {} does not exist",
                dir.display()
            )));
        }
        if out.is_dir() {
            return Err(place("is a folder, not a file name".into()));
        }
        let probe = dir.join(format!(".relight-write-check-{}", std::process::id()));
        std::fs::write(&probe, b"").map_err(|error| OutputError::NotWritable {
            path: path.clone(),
            dir: dir.to_path_buf(),
            error,
        })?;
        let _ = std::fs::remove_file(&probe);
        if out.canonicalize().is_ok_and(|c| inputs.contains(&c)) {
            return Err(OutputError::Clash {
                path,
                problem: "is also an input; refusing to overwrite it",
            });
        }
        if outs[..i].contains(out) {
            return Err(OutputError::Clash {
                path,
                problem: "given twice as an output",
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_checked_before_work() {
        let dir = std::env::temp_dir().join(format!("relight-outputs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let input = dir.join("scene.json");
        std::fs::write(&input, "{}").unwrap();
        let ok = dir.join("a.png");
        let exts = ["png", "exr"];
        assert!(check_outputs(&[&ok], &exts, &[&input]).is_ok());
        for (bad, want) in [
            (dir.join("a.txt"), "unknown output extension 'txt'"),
            (dir.join("missing/a.png"), "does not exist"),
        ] {
            let e = check_outputs(&[&bad], &exts, &[]).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains(bad.to_str().unwrap()), "{e}");
        }
        let e = check_outputs(&[&input], &["json"], &[&input])
            .unwrap_err()
            .to_string();
        assert!(e.contains("also an input"), "{e}");
        let e = check_outputs(&[&ok, &ok], &exts, &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("twice"), "{e}");
        // Nothing is left behind by the checks.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
