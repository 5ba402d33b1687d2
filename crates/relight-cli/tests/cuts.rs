//! End-to-end tests of the `cuts` method in the `relight` binary: bake, info, render, a
//! sharded bake merged byte for byte, bad settings and foreign options refused.

use std::path::{Path, PathBuf};
mod common;
use common::{assert_clean_failure, relight, stderr, stdout, tmpdir};

/// A white-ish Lambertian sphere alone under a constant environment of radiance 1: convex,
/// so every point sees the whole upper hemisphere and reflects exactly its albedo.
fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("sphere.json");
    std::fs::write(
        &p,
        r#"{
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 12,
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
        "cuts",
        "--cut-lights",
        "2048",
        "--seed",
        "4",
    ];
    a.extend_from_slice(extra);
    relight(&a)
}

#[test]
fn bake_info_render_a_convex_lambert_sphere() {
    let dir = tmpdir("cuts", "render");
    let (sc, b) = (scene(&dir), dir.join("s.relight"));
    let o = bake(&sc, &b, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&["info", s(&b)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("renders with --method cuts"),
        "{}",
        stdout(&o)
    );
    let img = dir.join("s.exr");
    let o = relight(&[
        "render",
        s(&b),
        "-o",
        s(&img),
        "--light-cut",
        "128",
        "--supersample",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, px) = relight_scene::io::image::read_image(&img).unwrap();
    assert_eq!((w, h), (24, 18));
    // Pixels well inside the disc: the albedo, within the cut approximation (cosine cut
    // means times light cluster means, 16-bit quantisation) and the faceted sphere's
    // interpolated normals: 2%.
    let (cx, cy) = (12.0, 9.0);
    let mut inside = 0;
    for (k, p) in px.iter().enumerate() {
        let (x, y) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
        if (x - cx).hypot(y - cy) < 4.0 {
            inside += 1;
            for (c, a) in p.to_array().iter().zip([0.5f32, 0.4, 0.3]) {
                assert!((c - a).abs() < 0.02 * a, "pixel {k}: {p}");
            }
        }
    }
    assert!(inside > 20);
    // Materials are not baked: another one at render time, inline or from a file.
    let mat = dir.join("white.json");
    std::fs::write(&mat, r#"{"type": "lambert", "albedo": [0.9, 0.9, 0.9]}"#).unwrap();
    for m in [s(&mat), r#"{"type": "lambert", "albedo": [0.9, 0.9, 0.9]}"#] {
        let o = relight(&[
            "render",
            s(&b),
            "-o",
            s(&img),
            "--light-cut",
            "128",
            "--supersample",
            "1",
            "--material",
            m,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let (_, _, px) = relight_scene::io::image::read_image(&img).unwrap();
        let centre = px[9 * w + 12];
        // As above: 2%.
        assert!(
            (centre - glam::Vec3::splat(0.9)).abs().max_element() < 0.02 * 0.9,
            "{centre}"
        );
    }
    let bad = dir.join("bad.exr");
    let o = relight(&[
        "render",
        s(&b),
        "-o",
        s(&bad),
        "--material",
        r#"{"type": "lambert", "albedo": [2, 0, 0]}"#,
    ]);
    assert_clean_failure(&o, "material", &bad);
    let o = relight(&[
        "render",
        s(&b),
        "-o",
        s(&bad),
        "--material",
        "/nonexistent/m.json",
    ]);
    assert_clean_failure(&o, "m.json", &bad);
}

#[test]
fn a_sharded_bake_merges_to_the_same_bytes() {
    let dir = tmpdir("cuts", "shard");
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
        s(&parts[2]),
        s(&parts[0]),
        s(&parts[1]),
        "-o",
        s(&merged),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(&merged).unwrap(),
        std::fs::read(&whole).unwrap()
    );
    // A part renders nothing until merged.
    let img = dir.join("part.exr");
    let o = relight(&["render", s(&parts[0]), "-o", s(&img)]);
    assert_clean_failure(&o, "merge the parts", &img);
}

#[test]
fn bad_settings_and_foreign_options_are_refused() {
    let dir = tmpdir("cuts", "bad");
    let sc = scene(&dir);
    let b = dir.join("bad.relight");
    assert_clean_failure(&bake(&sc, &b, &["--cut-sigma=-1"]), "sigma", &b);
    assert_clean_failure(&bake(&sc, &b, &["--cut-lights", "1"]), "lights", &b);
    assert_clean_failure(&bake(&sc, &b, &["--cut-beta", "2"]), "beta", &b);
    assert_clean_failure(&bake(&sc, &b, &["--direct-res", "8"]), "direct-res", &b);
    let good = dir.join("good.relight");
    assert!(bake(&sc, &good, &[]).status.success());
    let img = dir.join("x.exr");
    let o = relight(&["render", s(&good), "-o", s(&img), "--light-cut", "0"]);
    assert_clean_failure(&o, "light cut", &img);
    let o = relight(&["render", s(&good), "-o", s(&img), "--prefilter-size", "64"]);
    assert_clean_failure(&o, "prefilter-size", &img);
    let o = relight(&["render", s(&good), "-o", s(&img), "--method", "sh"]);
    assert_clean_failure(&o, "cuts", &img);
    // Materials chosen at render time: an unknown BRDF and an out-of-range parameter.
    let o = relight(&[
        "render",
        s(&good),
        "-o",
        s(&img),
        "--material",
        r#"{"type": "velvet"}"#,
    ]);
    assert_clean_failure(&o, "velvet", &img);
    let rough = r#"{"type": "ggx_conductor", "specular": [0.9, 0.9, 0.9], "alpha": 7}"#;
    let o = relight(&["render", s(&good), "-o", s(&img), "--material", rough]);
    assert_clean_failure(&o, "alpha", &img);
    let missing = dir.join("no-such-material.json");
    let o = relight(&["render", s(&good), "-o", s(&img), "--material", s(&missing)]);
    assert_clean_failure(&o, "no-such-material.json", &img);
    // A bundle of another method given to --method cuts: the message names both.
    let sh = dir.join("sh.relight");
    let o = relight(&[
        "bake",
        s(&sc),
        "-o",
        s(&sh),
        "--method",
        "sh",
        "--samples",
        "64",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&["render", s(&sh), "-o", s(&img), "--method", "cuts"]);
    assert_clean_failure(&o, "sh", &img);
    assert!(stderr(&o).contains("cuts"), "{}", stderr(&o));
}

/// `--material` naming texture maps: a half-black diffuse map blackens part of the sphere and
/// leaves the rest as the constant material renders it; maps that are missing or leave
/// the material file's folder fail cleanly (no output), the latter unless
/// `--material-allow-outside-paths`.
#[test]
fn a_material_with_maps_renders_and_bad_maps_fail_cleanly() {
    let dir = tmpdir("cuts", "maps");
    let (sc, b) = (scene(&dir), dir.join("s.relight"));
    let o = bake(&sc, &b, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mats = dir.join("materials");
    std::fs::create_dir_all(&mats).unwrap();
    // Left half (u < 0.5) black, right half white: u is the sphere's longitude.
    let px: Vec<[u8; 3]> = (0..8 * 2)
        .map(|i| if i % 8 < 4 { [0; 3] } else { [255; 3] })
        .collect();
    relight_scene::io::write_png_srgb8(&mats.join("half.png"), 8, 2, &px).unwrap();
    let write = |name: &str, maps: &str| {
        let p = mats.join(name);
        let text = format!(r#"{{"type": "lambert", "albedo": [0.9, 0.9, 0.9], "maps": {maps}}}"#);
        std::fs::write(&p, text).unwrap();
        p
    };
    let img = dir.join("mapped.exr");
    let good = write("good.json", r#"{"diffuse": "half.png"}"#);
    let o = relight(&[
        "render",
        s(&b),
        "-o",
        s(&img),
        "--supersample",
        "1",
        "--material",
        s(&good),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, mapped) = relight_scene::io::image::read_image(&img).unwrap();
    let plain = dir.join("plain.exr");
    let m = r#"{"type": "lambert", "albedo": [0.9, 0.9, 0.9]}"#;
    let o = relight(&[
        "render",
        s(&b),
        "-o",
        s(&plain),
        "--supersample",
        "1",
        "--material",
        m,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, plain) = relight_scene::io::image::read_image(&plain).unwrap();
    // On the sphere (lit without maps): black where the map is, unchanged elsewhere (the
    // map's white is 1; 1e-4 for f32 rounding of the same sums).
    let on: Vec<_> = mapped
        .iter()
        .zip(&plain)
        .filter(|(_, p)| p.x > 0.3)
        .collect();
    let black = on.iter().filter(|(m, _)| m.x < 1e-3).count();
    let same = on.iter().filter(|(m, p)| (m.x - p.x).abs() < 1e-4).count();
    assert!(
        black > 20 && same > 20,
        "{black} black, {same} unchanged of {}",
        on.len()
    );
    let bad = dir.join("bad.exr");
    let missing = write("missing.json", r#"{"diffuse": "nope.png"}"#);
    let o = relight(&["render", s(&b), "-o", s(&bad), "--material", s(&missing)]);
    assert_clean_failure(&o, "nope.png", &bad);
    relight_scene::io::write_png_srgb8(&dir.join("up.png"), 1, 1, &[[255; 3]]).unwrap();
    let out = write("out.json", r#"{"diffuse": "../up.png"}"#);
    let o = relight(&["render", s(&b), "-o", s(&bad), "--material", s(&out)]);
    assert_clean_failure(&o, "--material-allow-outside-paths", &bad);
    let o = relight(&[
        "render",
        s(&b),
        "-o",
        s(&bad),
        "--material",
        s(&out),
        "--material-allow-outside-paths",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}
