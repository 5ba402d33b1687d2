//! Objects keep their names through a bake: `relight info` lists them, and
//! `relight render --method cuts --material NAME=MATERIAL` edits one object's material after
//! the bake while the others stay as baked.

use std::path::{Path, PathBuf};
mod common;
use common::{assert_clean_failure, relight, stderr, stdout, tmpdir};

/// Two grey Lambertian spheres named "left" and "right", side by side under a constant
/// environment, seen from the front: each fills one half of the frame.
fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("two.json");
    std::fs::write(
        &p,
        r#"{
  "shapes": [
    {"type": "sphere", "name": "left", "center": [-1.1, 0, 0], "radius": 1, "rings": 12,
     "material": {"type": "lambert", "albedo": [0.5, 0.5, 0.5]}},
    {"type": "sphere", "name": "right", "center": [1.1, 0, 0], "radius": 1, "rings": 12,
     "material": {"type": "lambert", "albedo": [0.5, 0.5, 0.5]}}],
  "environment": {"type": "constant", "radiance": [1, 1, 1]},
  "camera": {"origin": [0, 0, 6], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov_deg": 50, "width": 40, "height": 20}
}"#,
    )
    .unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The baked two-sphere bundle in a fresh folder.
fn baked(tag: &str) -> (PathBuf, PathBuf) {
    let dir = tmpdir("objects", tag);
    let b = dir.join("two.relight");
    let o = relight(&[
        "bake",
        s(&scene(&dir)),
        "-o",
        s(&b),
        "--method",
        "cuts",
        "--cut-lights",
        "512",
        "--seed",
        "3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    (dir, b)
}

/// Render `bundle` with the cuts frame and `extra` options; the linear pixels.
fn render(bundle: &Path, out: &Path, extra: &[&str]) -> Vec<[f32; 3]> {
    let mut a = vec!["render", s(bundle), "--method", "cuts", "-o", s(out)];
    a.extend_from_slice(extra);
    let o = relight(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, px) = relight_scene::io::image::read_image(out).unwrap();
    assert_eq!((w, h), (40, 20));
    px.into_iter().map(|p| p.to_array()).collect()
}

#[test]
fn info_lists_the_objects_with_their_sizes_and_materials() {
    let (_dir, b) = baked("info");
    let o = relight(&["info", s(&b)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("objects (2):"), "{text}");
    assert!(
        text.lines().any(|l| l.contains("left")
            && l.contains("triangles")
            && l.contains("lambert(albedo=[0.5,0.5,0.5])")),
        "{text}"
    );
    let o = relight(&["--json", "info", s(&b)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let objects = j["objects"].as_array().unwrap();
    let names: Vec<&str> = objects
        .iter()
        .map(|o| o["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["left", "right"]);
    // Two identical spheres: the same counts, the second starting where the first ends.
    let t = objects[0]["triangles"].as_u64().unwrap();
    assert!(t > 0);
    assert_eq!(objects[1]["triangles"].as_u64(), Some(t));
    assert_eq!(objects[1]["first_triangle"].as_u64(), Some(t));
    assert_eq!(objects[0]["vertices"], objects[1]["vertices"]);
    assert_eq!(objects[1]["materials"][0]["kind"], "lambert");
    assert_eq!(j["triangles"].as_u64(), Some(2 * t));
}

#[test]
fn a_named_material_edits_only_its_object() {
    let (dir, b) = baked("edit");
    let red = dir.join("red.json");
    std::fs::write(&red, r#"{"type": "lambert", "albedo": [0.9, 0.1, 0.1]}"#).unwrap();
    let plain = render(&b, &dir.join("plain.exr"), &[]);
    let edited = render(
        &b,
        &dir.join("edited.exr"),
        &["--material", &format!("right={}", s(&red))],
    );
    let (mut left, mut right) = (0usize, 0usize);
    for (i, (p, e)) in plain.iter().zip(&edited).enumerate() {
        let x = i % 40;
        if x < 20 {
            // The left half shows the left sphere (and the empty background) alone: the same
            // frame computed from the same bake, so equal up to float noise.
            for c in 0..3 {
                assert!(
                    (p[c] - e[c]).abs() <= 1e-5 * p[c].abs().max(1.0),
                    "pixel {i}: {p:?} vs {e:?}"
                );
            }
            left += usize::from(p[1] > 0.05);
        } else if p[1] > 0.05 {
            // A right-sphere pixel: albedo 0.5 grey became (0.9, 0.1, 0.1), so green drops to
            // a fifth and red rises by 1.8 (pure Lambert: radiance is linear in the albedo);
            // 2 % covers the silhouette pixels' partial coverage being the same in both.
            assert!(
                (e[1] / p[1] - 0.2).abs() < 0.02,
                "pixel {i}: {p:?} vs {e:?}"
            );
            assert!(
                (e[0] / p[0] - 1.8).abs() < 0.02 * 1.8,
                "pixel {i}: {p:?} vs {e:?}"
            );
            right += 1;
        }
    }
    // Both spheres cover a good share of their halves (negative control: the checks ran).
    assert!(
        left > 100 && right > 100,
        "{left} left, {right} right pixels"
    );
    // A bare material still means every surface: the left sphere turns red too.
    let all = render(&b, &dir.join("all.exr"), &["--material", s(&red)]);
    let centre_left = 10 * 40 + 9;
    assert!(all[centre_left][1] < 0.5 * plain[centre_left][1]);
}

#[test]
fn unknown_duplicate_and_mixed_names_are_refused() {
    let (dir, b) = baked("errors");
    let red = dir.join("red.json");
    std::fs::write(&red, r#"{"type": "lambert", "albedo": [0.9, 0.1, 0.1]}"#).unwrap();
    let out = dir.join("never.exr");
    let run = |m: &[String]| {
        let mut a: Vec<String> = ["render", s(&b), "--method", "cuts", "-o", s(&out)]
            .iter()
            .map(|x| x.to_string())
            .collect();
        for x in m {
            a.push("--material".into());
            a.push(x.clone());
        }
        let refs: Vec<&str> = a.iter().map(String::as_str).collect();
        relight(&refs)
    };
    let r = s(&red);
    let o = run(&[format!("middle={r}")]);
    assert_clean_failure(&o, "no object \"middle\"", &out);
    assert!(stderr(&o).contains("left, right"), "{}", stderr(&o));
    let o = run(&[format!("left={r}"), format!("left={r}")]);
    assert_clean_failure(&o, "\"left\" is given twice", &out);
    let o = run(&[r.to_string(), format!("left={r}")]);
    assert_clean_failure(&o, "give one or the other", &out);
    let o = run(&[format!("left={}", s(&dir.join("missing.json")))]);
    assert_clean_failure(&o, "missing.json", &out);
}
