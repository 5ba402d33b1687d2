//! Shared by relight's fuzz targets: the loaders read paths (that is what users call, with
//! its file checks and path rule), so each input is written to a file in a folder of this
//! process first. See fuzz/README.md.

use std::path::{Path, PathBuf};

/// This process's scratch folder (one per fuzzing process, reused across inputs).
fn dir() -> &'static Path {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let base = Path::new("/dev/shm");
        let base = if base.is_dir() {
            base.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let d = base.join(format!("relight-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("scratch folder");
        d
    })
}

/// Write `files` (name, bytes) into the scratch folder and call `f` with the first one's
/// path. Errors are the expected outcome of most inputs; a panic, an abort or a timeout is
/// a finding.
pub fn with_files(files: &[(&str, &[u8])], f: impl FnOnce(&Path)) {
    for (name, bytes) in files {
        std::fs::write(dir().join(name), bytes).expect("write the input");
    }
    f(&dir().join(files[0].0));
}

/// Split `data` at its first NUL: (before, after), or (all, empty).
pub fn split_nul(data: &[u8]) -> (&[u8], &[u8]) {
    match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[]),
    }
}

/// Load `data` as the environment file `name` (`e.hdr`, `e.exr`) in the layout its first
/// byte picks (latlong, vertical cross, angular probe, or detected from the aspect ratio).
pub fn load_env_any_layout(name: &str, data: &[u8]) {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let layout = ["latlong", "cube", "probe", "auto"][pick as usize % 4];
    with_files(&[(name, file)], |p| {
        let _ = relight_scene::io::load_env(p, relight_scene::scene_file::parse_layout(layout));
    });
}
