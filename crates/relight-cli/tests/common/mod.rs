//! Helpers shared by the end-to-end tests of the `relight` binary.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run the `relight` binary with `args`.
pub fn relight(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relight"))
        .args(args)
        .output()
        .expect("run relight")
}

/// A fresh, empty temporary folder named after the test file's `prefix` and `tag`.
pub fn tmpdir(prefix: &str, tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("relight-{prefix}-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The standard error of a run, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// The standard output of a run, as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).to_string()
}

/// Whether Mitsuba-backed evaluations can run here (`../shared` and Mitsuba 3 present); prints
/// the reason for skipping otherwise.
pub fn can_evaluate() -> bool {
    if relight_testdata::require_shared_dir("this evaluation").is_none() {
        return false;
    }
    if let Err(e) = relight_render::mitsuba::mitsuba_python() {
        relight_testdata::skip(&format!("Mitsuba 3 not available: {e}"));
        return false;
    }
    true
}

/// The repository's `examples/` folder (test-only: the binary never reads the build tree).
pub fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .canonicalize()
        .unwrap()
}

/// Run the `relight` binary with `args` from the folder `cwd`, as an installed binary run
/// from anywhere.
pub fn relight_in(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relight"))
        .current_dir(cwd)
        .args(args)
        .output()
        .expect("run relight")
}

/// `o` failed cleanly: non-zero exit, an error naming `must_name`, no panic, and no (partial)
/// output at `out`.
pub fn assert_clean_failure(o: &Output, must_name: &str, out: &Path) {
    assert!(!o.status.success(), "expected failure");
    let e = stderr(o);
    assert!(
        e.contains(must_name),
        "error does not name {must_name}: {e}"
    );
    assert!(!e.contains("panicked"), "panic instead of an error: {e}");
    assert!(
        !out.exists(),
        "partial output {} left behind",
        out.display()
    );
}

/// Run `relight eval` with `args` from `cwd`, writing to `out`, and return the rows of its
/// `results.json`.
pub fn eval_rows(cwd: &Path, out: &Path, args: &[&str]) -> Vec<serde_json::Value> {
    let mut all = vec!["eval"];
    all.extend_from_slice(args);
    all.extend(["-o", out.to_str().unwrap()]);
    let o = relight_in(cwd, &all);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("results.json")).unwrap()).unwrap();
    rows.as_array().unwrap().clone()
}

/// A Lambert sphere (albedo `albedo`) on a plane under the procedural sky (sun at azimuth 30
/// degrees, so a rotation of the environment moves the light), seen from `origin` towards
/// `target` at 64 x 48, baked as `sh` (order 3, 32 samples) into `dir/b.relight`.
pub fn sky_sphere_sh_bundle(
    dir: &Path,
    albedo: f32,
    origin: [f32; 3],
    target: [f32; 3],
) -> PathBuf {
    let scene = dir.join("scene.json");
    std::fs::write(
        &scene,
        format!(
            r#"{{"shapes": [{{"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 16,
              "material": {{"type": "lambert", "albedo": [{albedo}, {albedo}, {albedo}]}}}},
             {{"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 8}}],
           "environment": {{"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 30,
                           "turbidity": 3, "ground_albedo": [0.3, 0.3, 0.3]}},
           "camera": {{"origin": {origin:?}, "target": {target:?}, "up": [0, 1, 0],
                      "fov_deg": 40, "width": 64, "height": 48}}}}"#
        ),
    )
    .unwrap();
    let b = dir.join("b.relight");
    let (sc, bs) = (scene.to_str().unwrap(), b.to_str().unwrap());
    let o = relight(&["bake", sc, "-o", bs, "--samples", "32", "--sh-order", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    b
}

/// The 8-bit RGB pixels of a PNG (relight's or the asset builder's).
pub fn read_png(path: &Path) -> Vec<[u8; 3]> {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    buf[..info.buffer_size()]
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}
