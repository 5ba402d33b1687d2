//! End-to-end: the `cuts_room` example baked with surface samples, rendered with a point
//! and a spot light at two positions; mismatched lighting and bad lights refused cleanly.

use std::path::Path;
mod common;
use common::{assert_clean_failure, examples, relight, stderr, tmpdir};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn room_bakes_renders_with_a_moving_light_and_refuses_bad_lighting() {
    let dir = tmpdir("cuts", "local");
    let scene = examples().join("cuts_room.json");
    let b = dir.join("room.relight");
    let small = ["--width", "32", "--height", "24", "--supersample", "1"];
    let o = relight(&[
        "bake",
        s(&scene),
        "-o",
        s(&b),
        "--method",
        "cuts",
        "--cut-samples",
        "surface",
        "--cut-lights",
        "2048",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut means = Vec::new();
    for (k, p) in ["0,1.7,0", "0.6,1.2,0.5"].iter().enumerate() {
        let img = dir.join(format!("room{k}.exr"));
        let mut a = vec!["render", s(&b), "-o", s(&img), "--point-light", p];
        a.extend_from_slice(&["--light-intensity", "2,2,2"]);
        a.extend_from_slice(&small);
        let o = relight(&a);
        assert!(o.status.success(), "{}", stderr(&o));
        let (_, _, px) = relight_scene::io::image::read_exr(&img).unwrap();
        means.push(px.iter().map(|p| p.x as f64).sum::<f64>() / px.len() as f64);
    }
    assert!(
        means[0] > 0.0 && (means[0] - means[1]).abs() > 1e-3 * means[0],
        "{means:?}"
    );
    let spot = dir.join("spot.exr");
    let mut a = vec!["render", s(&b), "-o", s(&spot), "--point-light", "0,1.9,0"];
    a.extend_from_slice(&["--light-intensity", "6,6,6", "--spot-dir", "0,-1,-0.3"]);
    a.extend_from_slice(&["--spot-angle", "35"]);
    a.extend_from_slice(&small);
    let o = relight(&a);
    assert!(o.status.success(), "{}", stderr(&o));

    // Refusals: no light for a surface bake, a bad angle, a light inside the sphere, an
    // environment bake given a point light.
    let out = dir.join("bad.exr");
    let o = relight(&["render", s(&b), "-o", s(&out)]);
    assert_clean_failure(&o, "--point-light", &out);
    let base = ["render", s(&b), "-o", s(&out), "--light-intensity", "1,1,1"];
    let mut a = base.to_vec();
    a.extend_from_slice(&[
        "--point-light",
        "0,1,0",
        "--spot-dir",
        "0,-1,0",
        "--spot-angle",
        "0",
    ]);
    assert_clean_failure(&relight(&a), "spot angle", &out);
    let mut a = base.to_vec();
    a.extend_from_slice(&["--point-light", "-0.4,0.35,-0.3"]);
    assert_clean_failure(&relight(&a), "inside geometry", &out);
    let env = dir.join("env.relight");
    let o = relight(&[
        "bake",
        s(&scene),
        "-o",
        s(&env),
        "--method",
        "cuts",
        "--cut-lights",
        "64",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&[
        "render",
        s(&env),
        "-o",
        s(&out),
        "--point-light",
        "0,1,0",
        "--light-intensity",
        "1,1,1",
    ]);
    assert_clean_failure(&o, "surface samples", &out);
    let o = relight(&[
        "reference",
        s(&scene),
        "-o",
        s(&out),
        "--spp",
        "1",
        "--point-light",
        "0,1,0",
    ]);
    assert_clean_failure(&o, "--light-intensity", &out);
    let _ = std::fs::remove_dir_all(&dir);
}
