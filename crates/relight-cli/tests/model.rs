//! One command from a model file: `relight bake MODEL`, `relight reference MODEL` (and
//! `relight view MODEL`, tests/view.rs) build the same scene from a `.obj`, `.ply`, `.gltf`
//! or `.glb` by one rule (`relight_scene::scene_file::model`): the framed camera, the
//! default sky or `--env`, and `--ground`. Checked here: the choices are printed, the bundle's
//! frame and the reference see the model at the same pixels (the same camera), and bad input
//! fails cleanly.

mod common;

use common::{assert_clean_failure, relight, stderr, tmpdir};
use relight_render::read_image;
use std::f32::consts::PI;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// A UV sphere of radius 0.5 standing on y = 0 (8 rings, 16 slices), as an OBJ.
fn sphere_obj(dir: &Path) -> PathBuf {
    let (rings, slices) = (8, 16);
    let mut s = String::from("o ball\n");
    for i in 0..=rings {
        let t = PI * i as f32 / rings as f32;
        for j in 0..slices {
            let p = 2.0 * PI * j as f32 / slices as f32;
            let (x, y, z) = (t.sin() * p.cos(), t.cos(), t.sin() * p.sin());
            writeln!(s, "v {} {} {}", 0.5 * x, 0.5 + 0.5 * y, 0.5 * z).unwrap();
        }
    }
    let v = |i: usize, j: usize| i * slices + (j % slices) + 1;
    for i in 0..rings {
        for j in 0..slices {
            let (a, b, c, d) = (v(i, j), v(i, j + 1), v(i + 1, j + 1), v(i + 1, j));
            if i > 0 {
                writeln!(s, "f {a} {b} {d}").unwrap();
            }
            if i + 1 < rings {
                writeln!(s, "f {b} {c} {d}").unwrap();
            }
        }
    }
    let path = dir.join("ball.obj");
    std::fs::write(&path, s).unwrap();
    path
}

/// Which pixels are lit (any channel above a small threshold; the background is black).
fn lit(path: &Path) -> (u32, u32, Vec<bool>) {
    let img = read_image(path).unwrap();
    let mask = img.pixels.iter().map(|p| p.max_element() > 1e-3).collect();
    (img.width as u32, img.height as u32, mask)
}

#[test]
fn a_model_file_bakes_renders_and_path_traces_with_one_camera() {
    let d = tmpdir("model", "one-camera");
    let obj = sphere_obj(&d);
    let b = d.join("ball.relight");
    let o = relight(&[
        "bake",
        obj.to_str().unwrap(),
        "-o",
        b.to_str().unwrap(),
        "--sh-order",
        "3",
        "--samples",
        "64",
    ]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    for said in [
        "framed on the model's bounds",
        "the default sky",
        "method: sh",
    ] {
        assert!(e.contains(said), "bake does not say '{said}': {e}");
    }
    let frame = d.join("frame.exr");
    let o = relight(&["render", b.to_str().unwrap(), "-o", frame.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let truth = d.join("truth.exr");
    let o = relight(&[
        "reference",
        obj.to_str().unwrap(),
        "-o",
        truth.to_str().unwrap(),
        "--spp",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, f) = lit(&frame);
    let (w2, h2, t) = lit(&truth);
    assert_eq!((w, h), (640, 480));
    assert_eq!((w2, h2), (w, h));
    let covered = t.iter().filter(|&&x| x).count();
    let differ = f.iter().zip(&t).filter(|(a, b)| a != b).count();
    // The sphere covers ~10 % of the frame; a silhouette one pixel off all round differs by
    // a few hundred pixels, a camera that moved by its whole width.
    assert!(
        covered > 10_000,
        "the framed model covers only {covered} pixels"
    );
    assert!(
        (differ as f64) < 0.05 * covered as f64,
        "frame and reference differ at {differ} of {covered} pixels: not the same camera"
    );
}

#[test]
fn ground_and_env_options_are_checked() {
    let d = tmpdir("model", "options");
    let obj = sphere_obj(&d);
    let truth = d.join("g.exr");
    // With a ground plane under the default sky, the plane is lit around the model.
    let o = relight(&[
        "reference",
        obj.to_str().unwrap(),
        "--ground",
        "--env",
        "sky",
        "-o",
        truth.to_str().unwrap(),
        "--spp",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, lit_pixels) = lit(&truth);
    let n = lit_pixels.len();
    // The framed camera looks down 20 degrees: the plane (8 radii wide) fills the lower
    // half of the frame at least.
    assert!(
        lit_pixels[n / 2..].iter().filter(|&&x| x).count() > n / 4,
        "the ground is not under the model"
    );

    let bad_env = d.join("nope.hdr");
    let out = d.join("x.exr");
    let o = relight(&[
        "reference",
        obj.to_str().unwrap(),
        "--env",
        bad_env.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "nope.hdr", &out);

    let scene = d.join("s.json");
    std::fs::write(
        &scene,
        r#"{"shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 8, "height": 8}}"#,
    )
    .unwrap();
    let o = relight(&[
        "reference",
        scene.to_str().unwrap(),
        "--ground",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "--ground", &out);

    let broken = d.join("broken.obj");
    std::fs::write(&broken, "v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap();
    let b = d.join("b.relight");
    let o = relight(&["bake", broken.to_str().unwrap(), "-o", b.to_str().unwrap()]);
    assert_clean_failure(&o, "broken.obj", &b);
}
