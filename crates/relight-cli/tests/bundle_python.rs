//! The bundle is readable from Python exactly as docs/BUNDLE.md says: this test runs the
//! reader printed in that document (extracted from it, so the document cannot rot) on a
//! freshly baked bundle and checks what it returns. Skips when no Python with numpy exists.

use std::process::Command;

fn python_with_numpy() -> Option<std::path::PathBuf> {
    let mut candidates = Vec::new();
    if let Ok(p) = relight_render::mitsuba::mitsuba_python() {
        candidates.push(p);
    }
    candidates.push("python3".into());
    candidates.into_iter().find(|p| {
        Command::new(p)
            .args(["-c", "import numpy"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false)
    })
}

#[test]
fn python_reader_in_docs_reads_a_baked_bundle() {
    let Some(py) = python_with_numpy() else {
        relight_testdata::skip("no Python with numpy (run scripts/setup.sh)");
        return;
    };
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/BUNDLE.md"))
        .unwrap();
    let start = doc
        .find("```python\n")
        .expect("python block in docs/BUNDLE.md")
        + "```python\n".len();
    let code = &doc[start..start + doc[start..].find("```").unwrap()];
    let d = std::env::temp_dir().join(format!("relight-pybundle-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let scene = d.join("s.json");
    std::fs::write(
        &scene,
        r#"{"shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 8,
              "material": {"type": "lambert", "albedo": [0.5, 0.25, 1.0]}}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 40, "width": 8, "height": 8}}"#,
    )
    .unwrap();
    let bundle = d.join("s.relight");
    let o = Command::new(env!("CARGO_BIN_EXE_relight"))
        .args([
            "bake",
            scene.to_str().unwrap(),
            "-o",
            bundle.to_str().unwrap(),
            "--order",
            "3",
            "--samples",
            "8",
            "--f16",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let script = format!(
        "{code}\nmeta, arrays = read_bundle({:?})\n\
         assert meta['method'] == 'sh', meta\n\
         t = arrays['transfer']\n\
         assert t.dtype.name == 'float16' and t.shape[1:] == (9, 1), t.shape\n\
         assert arrays['positions'].shape == (t.shape[0], 3)\n\
         assert abs(float(t[1, 0, 0]) - 0.2821) < 1e-3, t[1, 0, 0]\n\
         print('ok', t.shape)\n",
        bundle.to_str().unwrap()
    );
    let o = Command::new(&py).args(["-c", &script]).output().unwrap();
    assert!(
        o.status.success(),
        "python: {}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    // And a corrupted copy is rejected by the same reader.
    let mut bytes = std::fs::read(&bundle).unwrap();
    let n = bytes.len();
    bytes[n - 3] ^= 0x40;
    let bad = d.join("bad.relight");
    std::fs::write(&bad, &bytes).unwrap();
    let script = format!("{code}\nread_bundle({:?})\n", bad.to_str().unwrap());
    let o = Command::new(&py).args(["-c", &script]).output().unwrap();
    assert!(!o.status.success(), "python accepted a corrupt bundle");
    assert!(String::from_utf8_lossy(&o.stderr).contains("data corrupt"));
}
