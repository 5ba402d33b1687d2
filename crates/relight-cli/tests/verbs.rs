//! The verbs as a user drives them: the hybrid render, `--json` summaries, options that do
//! not apply to the chosen method, outputs checked before any work, and the binary run from
//! an unrelated folder.

use std::path::{Path, PathBuf};
mod common;
use common::{assert_clean_failure, relight, relight_in, stderr, stdout, tmpdir};
use serde_json::Value;

/// A Lambert sphere on a plane under the procedural sky (whose sun the hybrid extracts), and
/// the same under a constant environment of radiance 2.
fn scenes(dir: &Path) -> (PathBuf, PathBuf) {
    let body = |env: &str| {
        format!(
            r#"{{"shapes": [{{"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 16,
                  "material": {{"type": "lambert", "albedo": [0.5, 0.5, 0.5]}}}},
                 {{"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 8}}],
               "environment": {env},
               "camera": {{"origin": [0, 0.6, 4], "target": [0, 0.6, 0], "up": [0, 1, 0],
                          "fov_deg": 40, "width": 48, "height": 32}}}}"#
        )
    };
    let sky = dir.join("sky.json");
    std::fs::write(
        &sky,
        body(r#"{"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 30, "turbidity": 3, "ground_albedo": [0.3, 0.3, 0.3]}"#),
    )
    .unwrap();
    let flat = dir.join("flat.json");
    std::fs::write(
        &flat,
        body(r#"{"type": "constant", "radiance": [2, 2, 2]}"#),
    )
    .unwrap();
    (sky, flat)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn json(o: &std::process::Output) -> Value {
    assert!(o.status.success(), "{}", stderr(o));
    serde_json::from_str(&stdout(o)).unwrap_or_else(|e| panic!("{e}: {}", stdout(o)))
}

fn bake(scene: &Path, bundle: &Path) {
    let o = relight(&[
        "bake",
        s(scene),
        "-o",
        s(bundle),
        "--samples",
        "64",
        "--sh-order",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn hybrid_render_extracts_the_sun_and_matches_sh_without_lights() {
    let d = tmpdir("verbs", "hybrid");
    let (sky, flat) = scenes(&d);
    let (bs, bf) = (d.join("sky.relight"), d.join("flat.relight"));
    bake(&sky, &bs);
    bake(&flat, &bf);
    // Under the sky: at least the sun is extracted, and the image differs from SH-only.
    let (h, sh) = (d.join("h.exr"), d.join("sh.exr"));
    let o = relight(&[
        "render",
        s(&bs),
        "--method",
        "hybrid",
        "-o",
        s(&h),
        "--shadow-map-size",
        "512",
        "--json",
    ]);
    let v = json(&o);
    assert_eq!(v["method"], "hybrid");
    let summary = v["summary"].as_str().unwrap();
    let lights: usize = summary.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(lights >= 1, "{summary}");
    assert!(relight(&["render", s(&bs), "-o", s(&sh)]).status.success());
    let (_, _, a) = relight_scene::io::image::read_image(&h).unwrap();
    let (_, _, b) = relight_scene::io::image::read_image(&sh).unwrap();
    let diff = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (*x - *y).abs().max_element())
        .fold(0f32, f32::max);
    assert!(diff > 0.01, "hybrid equals SH-only under a sun: {diff}");
    // Under a constant environment nothing is extracted: the hybrid is the SH frame.
    let (h, sh) = (d.join("hf.exr"), d.join("shf.exr"));
    assert!(
        relight(&["render", s(&bf), "--method", "hybrid", "-o", s(&h)])
            .status
            .success()
    );
    assert!(relight(&["render", s(&bf), "-o", s(&sh)]).status.success());
    let (_, _, a) = relight_scene::io::image::read_image(&h).unwrap();
    let (_, _, b) = relight_scene::io::image::read_image(&sh).unwrap();
    for (x, y) in a.iter().zip(&b) {
        // The decomposition's SH part of a constant map is its projection, up to the
        // decomposition's own quadrature.
        assert!((*x - *y).abs().max_element() < 2e-3, "{x} {y}");
    }
}

#[test]
fn options_of_other_methods_are_refused() {
    let d = tmpdir("verbs", "foreign");
    let (_, flat) = scenes(&d);
    let b = d.join("f.relight");
    bake(&flat, &b);
    let never = d.join("never.relight");
    let img = d.join("never.png");
    let never_eval = d.join("never-eval");
    let examples = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    for (args, want, out) in [
        (
            vec![
                "bake",
                s(&flat),
                "-o",
                s(&never),
                "--method",
                "sg",
                "--transfer",
                "shadowed",
            ],
            "--transfer applies to --method sh or hybrid",
            &never,
        ),
        (
            vec!["bake", s(&flat), "-o", s(&never), "--direct-lobes", "2"],
            "--direct-lobes applies to --method sg",
            &never,
        ),
        (
            vec!["bake", s(&flat), "-o", s(&never), "--bounces", "2"],
            "--bounces applies to --transfer interreflected",
            &never,
        ),
        (
            vec![
                "render",
                s(&b),
                "-o",
                s(&img),
                "--method",
                "hybrid",
                "--window",
                "hann",
            ],
            "--window applies to --method sh",
            &img,
        ),
        (
            vec!["render", s(&b), "-o", s(&img), "--prefilter-size", "64"],
            "--prefilter-size applies to --method sg",
            &img,
        ),
        (
            vec!["render", s(&b), "-o", s(&img), "--threshold", "0.1"],
            "--threshold applies to --method hybrid",
            &img,
        ),
        (
            vec!["render", s(&b), "-o", s(&img), "--method", "sg"],
            "holds a `sh` bake",
            &img,
        ),
        (
            vec!["render", s(&b), "-o", s(&img), "--sh-order", "9"],
            "SH order 9",
            &img,
        ),
        (
            vec![
                "eval",
                "-o",
                s(&never_eval),
                "--experiments",
                "fig3-4_conductor",
            ],
            "--experiments applies to --method sg",
            &never_eval,
        ),
        (
            vec![
                "eval",
                "--method",
                "sg",
                "--examples",
                s(&examples),
                "-o",
                s(&never_eval),
                "--experiments",
                "fig3-4_conductor,no_such_experiment",
            ],
            "unknown experiment \"no_such_experiment\" (known: fig3-4_conductor,",
            &never_eval,
        ),
    ] {
        let o = relight(&args);
        assert_clean_failure(&o, want, out);
    }
}

#[test]
fn outputs_are_checked_before_any_work() {
    let d = tmpdir("verbs", "outputs");
    let (_, flat) = scenes(&d);
    let b = d.join("f.relight");
    bake(&flat, &b);
    // A missing folder: refused at once, before the bake starts.
    let o = relight(&["bake", s(&flat), "-o", s(&d.join("no/such/dir/x.relight"))]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("does not exist") && !stderr(&o).contains("baking"),
        "{}",
        stderr(&o)
    );
    // The scene as the output: refused, the scene untouched.
    let before = std::fs::read(&flat).unwrap();
    let o = relight(&["bake", s(&flat), "-o", s(&flat)]);
    assert!(!o.status.success());
    assert_eq!(std::fs::read(&flat).unwrap(), before);
    // The environment read as an output: refused.
    let env = d.join("e.exr");
    relight_scene::io::image::write_exr(&env, 8, 4, &[glam::Vec3::ONE; 32]).unwrap();
    let o = relight(&["render", s(&b), "--env", s(&env), "-o", s(&env)]);
    assert!(
        !o.status.success() && stderr(&o).contains("also an input"),
        "{}",
        stderr(&o)
    );
    // Several outputs, one of them bad: nothing is written.
    let good = d.join("good.png");
    let o = relight(&["render", s(&b), "-o", s(&good), "-o", s(&d.join("bad.txt"))]);
    assert_clean_failure(&o, "bad.txt", &good);
}

#[test]
fn json_summaries_of_every_verb() {
    let d = tmpdir("verbs", "json");
    let (sky, flat) = scenes(&d);
    let b = d.join("f.relight");
    let v = json(&relight(&[
        "bake",
        s(&flat),
        "-o",
        s(&b),
        "--samples",
        "16",
        "--sh-order",
        "3",
        "--json",
    ]));
    assert_eq!(
        (v["command"].as_str(), v["method"].as_str()),
        (Some("bake"), Some("sh"))
    );
    assert_eq!(v["settings"]["order"], 3);
    assert!(v["seconds"].as_f64().unwrap() >= 0.0 && v["bytes"].as_u64().unwrap() > 0);
    let v = json(&relight(&["info", s(&b), "--json"]));
    assert_eq!(
        (v["valid"].as_bool(), v["method"].as_str()),
        (Some(true), Some("sh"))
    );
    assert!(v["tensors"]["transfer"]["shape"].is_array());
    let part = d.join("p.relight");
    let bake_part = [
        "bake",
        s(&flat),
        "-o",
        s(&part),
        "--samples",
        "16",
        "--shard",
        "0/1",
    ];
    let v = json(&relight(&[&bake_part[..], &["--json"]].concat()));
    assert_eq!(v["shard"]["count"], 1, "{v}");
    // Peak memory: at least the binary and the scene, far below this machine's.
    let peak = v["peak_rss_mib"].as_f64().unwrap();
    assert!((1.0..4096.0).contains(&peak), "{v}");
    let m = d.join("m.relight");
    let v = json(&relight(&["merge", s(&part), "-o", s(&m), "--json"]));
    assert_eq!(v["command"].as_str(), Some("merge"));
    assert_eq!(v["parts"].as_array().map(Vec::len), Some(1));
    assert_eq!(
        v["bytes"].as_u64(),
        Some(std::fs::metadata(&m).unwrap().len())
    );
    let (x, y) = (d.join("x.exr"), d.join("y.exr"));
    let v = json(&relight(&["render", s(&b), "-o", s(&x), "--json"]));
    assert_eq!(v["outputs"][0].as_str(), Some(s(&x)));
    assert!(v["frame_ms"]["pixel_ms"].as_f64().is_some());
    assert!(
        relight(&["render", s(&b), "-o", s(&y), "--rotate-env", "-30"])
            .status
            .success()
    );
    let v = json(&relight(&[
        "compare",
        s(&x),
        s(&y),
        "--json",
        "-o",
        s(&d.join("h.png")),
    ]));
    assert!(v["rel_rmse"].as_f64().unwrap() < 1e-4, "{v}");
    // An environment file for project and decompose: the sky scene's map, written as EXR.
    let env = relight_scene::scene_file::SceneDesc::read(&sky).unwrap();
    let map = relight_scene::scene_file::build_env(&env.environment)
        .unwrap()
        .map;
    let e = d.join("sky.exr");
    assert_eq!(map.layout(), relight_sphere::envmap::EnvLayout::LatLong);
    relight_scene::io::image::write_exr(&e, map.width(), map.height(), map.texels()).unwrap();
    let v = json(&relight(&["project", s(&e), "--sh-order", "2", "--json"]));
    assert_eq!(v["coefficients"].as_array().unwrap().len(), 4);
    let v = json(&relight(&["decompose", s(&e), "--json"]));
    assert!(!v["lights"].as_array().unwrap().is_empty(), "{v}");
}

#[test]
fn runs_from_any_folder_with_relative_paths() {
    // What an installed binary does: no file of the build tree is needed at run time.
    let d = tmpdir("verbs", "cwd");
    let (_, flat) = scenes(&d);
    assert!(flat.starts_with(&d));
    let o = relight_in(
        &d,
        &["bake", "flat.json", "-o", "b.relight", "--samples", "16"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight_in(
        &d,
        &["render", "b.relight", "-o", "b.png", "--method", "hybrid"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("b.png").is_file());
    let o = relight_in(&d, &["info", "b.relight"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The default eval experiments name the folder they need instead of reading the build tree.
    let o = relight_in(&d, &["eval", "--method", "sg"]);
    assert!(
        !o.status.success() && stderr(&o).contains("--examples"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn no_build_tree_paths_outside_tests() {
    // `env!("CARGO_MANIFEST_DIR")` in library or binary code ties the binary to the build tree.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut bad = vec![];
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = e.path();
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            if p.is_dir() {
                // Test-only code: integration tests and the dev-only test-data crate.
                if name != "tests" && name != "target" && name != "relight-testdata" {
                    stack.push(p);
                }
            } else if name.ends_with(".rs") && name != "tests.rs" {
                let text = std::fs::read_to_string(&p).unwrap();
                let code = text.split("#[cfg(test)]").next().unwrap();
                if code.contains(concat!("env!(\"CARGO_", "MANIFEST_DIR\")")) {
                    bad.push(p.display().to_string());
                }
            }
        }
    }
    assert!(bad.is_empty(), "build-tree paths in: {bad:?}");
}

#[test]
fn bench_json_lists_every_section_with_numbers() {
    // The smallest run: a smoke test of the report's shape, not a measurement.
    let o = relight(&[
        "bench",
        "--quick",
        "--rays",
        "5000",
        "--relight-vertices",
        "5000",
        "--json",
    ]);
    let v = json(&o);
    let sections = v["sections"].as_array().unwrap();
    let titles: Vec<&str> = sections
        .iter()
        .map(|s| s["title"].as_str().unwrap())
        .collect();
    for want in [
        "Ray throughput",
        "SH bake",
        "SH relight",
        "SH projection of a latlong map",
        "Hybrid: environment decomposition",
        "Hybrid frame",
        "Gaussian-prefiltered",
        "SG fitter",
        "SG bake",
        "SG frame",
        "Cuts bake",
        "Cuts frame",
        "Cuts local-light frame",
    ] {
        assert!(
            titles.iter().any(|t| t.starts_with(want)),
            "{want} missing: {titles:?}"
        );
    }
    for s in sections {
        let cols = s["columns"].as_array().unwrap().len();
        for r in s["rows"].as_array().unwrap() {
            assert_eq!(r.as_array().unwrap().len(), cols, "{s}");
        }
    }
}
