//! End-to-end tests of the `vmf` method in the `relight` binary: bake, info, render, a
//! sharded bake merged byte for byte, other methods' bundles and foreign options refused.

use std::path::{Path, PathBuf};
mod common;
use common::{assert_clean_failure, relight, stderr, stdout, tmpdir};

/// A Lambertian sphere alone under a constant environment of radiance 1: convex, so every
/// point reflects exactly its albedo.
fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("sphere.json");
    std::fs::write(
        &p,
        r#"{
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 8,
              "material": {"type": "lambert", "albedo": [0.5, 0.4, 0.3]}}],
  "environment": {"type": "constant", "radiance": [1, 1, 1]},
  "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov_deg": 40, "width": 24, "height": 18}
}"#,
    )
    .unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn bake(scene: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut a = vec![
        "bake",
        s(scene),
        "-o",
        s(out),
        "--method",
        "vmf",
        "--view-level",
        "1",
        "--paths",
        "256",
        "--seed",
        "4",
    ];
    a.extend_from_slice(extra);
    relight(&a)
}

#[test]
fn bake_info_render_a_convex_lambert_sphere() {
    let dir = tmpdir("vmf", "render");
    let (sc, b) = (scene(&dir), dir.join("s.relight"));
    let o = bake(&sc, &b, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&["info", s(&b)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("renders with --method vmf"), "{text}");
    assert!(
        text.contains("vmf_lobes") && text.contains("17.0 views per vertex"),
        "{text}"
    );
    let img = dir.join("s.exr");
    let o = relight(&["render", s(&b), "-o", s(&img), "--supersample", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, px) = relight_scene::io::image::read_image(&img).unwrap();
    assert_eq!((w, h), (24, 18));
    // Pixels well inside the disc: the albedo, within the Monte Carlo error of 256 paths per
    // slice drawn from the eq. 9 lobes (weights f / p vary where the vMF misses the cosine):
    // 3 %.
    let (cx, cy) = (12.0, 9.0);
    let mut inside = 0;
    for (k, p) in px.iter().enumerate() {
        let (x, y) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
        if (x - cx).hypot(y - cy) < 4.0 {
            inside += 1;
            for (c, a) in p.to_array().iter().zip([0.5f32, 0.4, 0.3]) {
                assert!((c - a).abs() < 0.03 * a, "pixel {k}: {p}");
            }
        }
    }
    assert!(inside > 20);
}

#[test]
fn a_sharded_bake_merges_to_the_same_bytes() {
    let dir = tmpdir("vmf", "shard");
    let sc = scene(&dir);
    let whole = dir.join("whole.relight");
    assert!(bake(&sc, &whole, &[]).status.success());
    let parts: Vec<PathBuf> = (0..3).map(|i| dir.join(format!("p{i}.relight"))).collect();
    for (i, p) in parts.iter().enumerate() {
        let shard = format!("{i}/3");
        let o = bake(&sc, p, &["--shard", &shard]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let merged = dir.join("merged.relight");
    let o = relight(&[
        "merge",
        s(&parts[1]),
        s(&parts[2]),
        s(&parts[0]),
        "-o",
        s(&merged),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&merged).unwrap(),
        std::fs::read(&whole).unwrap()
    );
    let img = dir.join("part.exr");
    let o = relight(&["render", s(&parts[0]), "-o", s(&img)]);
    assert_clean_failure(&o, "merge the parts", &img);
    // A checkpointed bake (chunks of 50 vertices, merged) writes the same bytes too.
    let ck = dir.join("ck.relight");
    let o = bake(&sc, &ck, &["--checkpoint-vertices", "50"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(&ck).unwrap(), std::fs::read(&whole).unwrap());
}

#[test]
fn other_methods_bundles_bad_settings_and_foreign_options_are_refused() {
    let dir = tmpdir("vmf", "bad");
    let sc = scene(&dir);
    let b = dir.join("bad.relight");
    let o = relight(&[
        "bake",
        s(&sc),
        "-o",
        s(&b),
        "--method",
        "vmf",
        "--view-level",
        "6",
    ]);
    assert_clean_failure(&o, "view_level", &b);
    let o = relight(&[
        "bake",
        s(&sc),
        "-o",
        s(&b),
        "--method",
        "vmf",
        "--paths",
        "0",
    ]);
    assert_clean_failure(&o, "paths", &b);
    assert_clean_failure(&bake(&sc, &b, &["--direct-res", "8"]), "direct-res", &b);
    // The bake cannot be chunked by streaming: refused with the reason before baking.
    assert_clean_failure(&bake(&sc, &b, &["--memory-limit", "1K"]), "vmf", &b);
    let good = dir.join("good.relight");
    assert!(bake(&sc, &good, &[]).status.success());
    let img = dir.join("x.exr");
    let o = relight(&[
        "render",
        s(&good),
        "-o",
        s(&img),
        "--vmf-prefilter-size",
        "100",
    ]);
    assert_clean_failure(&o, "prefilter size", &img);
    let o = relight(&["render", s(&good), "-o", s(&img), "--prefilter-size", "64"]);
    assert_clean_failure(&o, "prefilter-size", &img);
    // A vmf bundle given to another method, and another method's bundle to --method vmf.
    let o = relight(&["render", s(&good), "-o", s(&img), "--method", "sg"]);
    assert_clean_failure(&o, "`vmf` bake", &img);
    let sh = dir.join("sh.relight");
    let o = relight(&[
        "bake",
        s(&sc),
        "-o",
        s(&sh),
        "--samples",
        "16",
        "--sh-order",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&["render", s(&sh), "-o", s(&img), "--method", "vmf"]);
    assert_clean_failure(&o, "`sh` bake, but --method vmf", &img);
}

/// A Lambert plane with a box on it: the spatial refinement adds vertices, the bundle holds
/// the refined mesh, and the bake refuses to be split.
#[test]
fn a_spatially_refined_bake_renders_and_is_not_split() {
    let dir = tmpdir("vmf", "spatial");
    let sc = dir.join("box.json");
    std::fs::write(
        &sc,
        r#"{
  "shapes": [{"type": "plane", "center": [0, 0, 0], "size": 4, "divisions": 4,
              "material": {"type": "lambert", "albedo": [0.6, 0.6, 0.6]}},
             {"type": "box", "min": [0.6, 0, -0.5], "max": [1.4, 0.8, 0.5],
              "material": {"type": "lambert", "albedo": [0.4, 0.4, 0.4]}}],
  "environment": {"type": "constant", "radiance": [1, 1, 1]},
  "camera": {"origin": [0, 3, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov_deg": 50, "width": 24, "height": 18}
}"#,
    )
    .unwrap();
    let b = dir.join("s.relight");
    let o = bake(
        &sc,
        &b,
        &["--spatial-threshold", "0.05", "--spatial-batch", "8"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&["info", s(&b), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    // 25 plane vertices and 24 box vertices before the refinement.
    assert!(j["vertices"].as_u64().unwrap() > 49, "{j}");
    let img = dir.join("s.exr");
    let o = relight(&["render", s(&b), "-o", s(&img)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let p = dir.join("p.relight");
    let o = bake(&sc, &p, &["--spatial-threshold", "0.05", "--shard", "0/2"]);
    assert_clean_failure(&o, "spatial", &p);
}
