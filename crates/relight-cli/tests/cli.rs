//! End-to-end tests of the `relight` binary: a bake/render round trip checked against a closed
//! form, and bad input (clear error naming the file, non-zero exit, no partial output).

use std::path::{Path, PathBuf};
mod common;
use common::{assert_clean_failure, relight, stderr, tmpdir};

/// A white-furnace scene: one sphere of albedo 0.5 under constant radiance 2 (so every visible
/// sphere pixel has radiance 0.5 * 2 = 1 exactly: the sphere is convex, nothing shadows it).
fn furnace_scene(dir: &Path) -> PathBuf {
    let p = dir.join("furnace.json");
    std::fs::write(
        &p,
        r#"{
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 24,
              "material": {"type": "lambert", "albedo": [0.5, 0.5, 0.5]}}],
  "environment": {"type": "constant", "radiance": [2, 2, 2]},
  "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov_deg": 40, "width": 48, "height": 32}
}"#,
    )
    .unwrap();
    p
}

/// Bake `scene` into `bundle` with few samples (the closed forms below do not depend on them).
fn bake_quick(scene: &Path, bundle: &Path) {
    let o = relight(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        bundle.to_str().unwrap(),
        "--samples",
        "16",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

fn read_exr_pixels(p: &Path) -> (usize, usize, Vec<[f32; 3]>) {
    let (w, h, px) = relight_scene::io::image::read_image(p).unwrap();
    (w, h, px.iter().map(|c| c.to_array()).collect())
}

#[test]
fn help_lists_every_subcommand() {
    let o = relight(&["--help"]);
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    for c in [
        "demo",
        "bake",
        "render",
        "reference",
        "export-mitsuba",
        "compare",
        "info",
        "project",
        "bench",
    ] {
        assert!(s.contains(c), "--help misses {c}:\n{s}");
    }
}

#[test]
fn bake_render_info_round_trip_matches_the_furnace_closed_form() {
    let d = tmpdir("cli", "furnace");
    let scene = furnace_scene(&d);
    let bundle = d.join("f.relight");
    for transfer in ["unshadowed", "shadowed", "interreflected"] {
        let o = relight(&[
            "bake",
            scene.to_str().unwrap(),
            "-o",
            bundle.to_str().unwrap(),
            "--order",
            "3",
            "--samples",
            "64",
            "--transfer",
            transfer,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let exr = d.join(format!("f-{transfer}.exr"));
        let png = d.join(format!("f-{transfer}.png"));
        let o = relight(&[
            "render",
            bundle.to_str().unwrap(),
            "-o",
            exr.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--supersample",
            "1",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(png.is_file());
        let (w, h, px) = read_exr_pixels(&exr);
        assert_eq!((w, h), (48, 32));
        // The centre pixel sees the sphere: 0.5 * 2 = 1. The constant environment projects to
        // L00 only and T00 of a cosine lobe is exact under cosine-weighted sampling, so only
        // float rounding remains (1e-4). Interreflection adds nothing: a convex sphere cannot
        // see itself.
        let c = px[16 * 48 + 24];
        for ch in c {
            assert!(
                (ch - 1.0).abs() < 1e-4,
                "{transfer}: centre pixel {c:?}, expected 1"
            );
        }
        // Corners miss the sphere: black (no --background).
        assert_eq!(px[0], [0.0; 3]);
    }
    let o = relight(&["info", bundle.to_str().unwrap()]);
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.contains("method: sh")
            && s.contains("transfer")
            && s.contains("checksums and contents OK"),
        "{s}"
    );
}

/// An environment that rotation changes: a bright cap (radiance 10, half-angle 35 degrees)
/// about the map's +Z over a dim sky (0.05), a 64 x 32 latlong `.hdr`.
fn cap_env(dir: &Path) -> PathBuf {
    let (w, h) = (64, 32);
    let cos_cap = 35f32.to_radians().cos();
    let px: Vec<glam::Vec3> = (0..w * h)
        .map(|k| {
            let d = relight_sphere::latlong::texel_dir(w, h, k % w, k / w);
            glam::Vec3::splat(if d.z > cos_cap { 10.0 } else { 0.05 })
        })
        .collect();
    let p = dir.join("cap.hdr");
    relight_scene::io::image::write_hdr(&p, w, h, &px).unwrap();
    p
}

/// `--rotate-env` turns the environment about +Y (right-handed, Mitsuba's
/// `to_world = rotate([0, 1, 0], angle)`: `Environment::world_from_env`), so the map's +Z
/// cap lights the furnace sphere (seen from +Z, +X to the right of the picture) from the front
/// unrotated, from +X (the right half) at +90 degrees and from -X (the left half) at -90,
/// without re-baking: the bundle is not touched.
#[test]
fn rotating_the_environment_does_not_rebake_and_moves_the_light_its_way() {
    let d = tmpdir("cli", "rotate");
    let scene = furnace_scene(&d);
    let bundle = d.join("r.relight");
    let o = relight(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        bundle.to_str().unwrap(),
        "--samples",
        "256",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let baked = std::fs::read(&bundle).unwrap();
    let env = cap_env(&d);
    // Mean luminance of the left and right halves of the picture, and its centre pixel.
    let render = |deg: &str| {
        let out = d.join(format!("r{deg}.exr"));
        let o = relight(&[
            "render",
            bundle.to_str().unwrap(),
            "--env",
            env.to_str().unwrap(),
            "--rotate-env",
            deg,
            "--supersample",
            "1",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let (w, h, px) = read_exr_pixels(&out);
        let lum = |p: &[f32; 3]| (p[0] + p[1] + p[2]) as f64 / 3.0;
        let (mut left, mut right) = (0.0, 0.0);
        for (k, p) in px.iter().enumerate() {
            if k % w < w / 2 {
                left += lum(p);
            } else {
                right += lum(p);
            }
        }
        let centre = lum(&px[(h / 2) * w + w / 2]);
        eprintln!(
            "--rotate-env {deg}: left half {left:.2}, right half {right:.2}, centre {centre:.3}"
        );
        (left, right, centre, px)
    };
    let (l0, r0, c0, p0) = render("0");
    let (lp, rp, cp, _) = render("90");
    let (lm, rm, cm, _) = render("-90");
    // Unrotated, the cap faces the camera: both halves alike, the centre lit.
    assert!(
        (l0 - r0).abs() < 0.05 * (l0 + r0),
        "unrotated: {l0} vs {r0}"
    );
    // +90 degrees takes the map's +Z to world +X: the right half is lit, the left one dim.
    assert!(rp > 3.0 * lp, "+90: right {rp} not over 3x left {lp}");
    // -90 degrees: the mirror picture.
    assert!(lm > 3.0 * rm, "-90: left {lm} not over 3x right {rm}");
    assert!(
        (lm - rp).abs() < 0.05 * rp && (rm - lp).abs() < 0.05 * lp.max(0.05 * rp),
        "+90 ({lp}, {rp}) and -90 ({lm}, {rm}) are not mirrors"
    );
    // The cap turned away from the front: the centre darkens.
    assert!(cp < 0.8 * c0 && cm < 0.8 * c0, "centre {c0}, {cp}, {cm}");
    // A full turn is no turn.
    let (_, _, _, p360) = render("360");
    for (x, y) in p0.iter().zip(&p360) {
        for c in 0..3 {
            assert!(
                (x[c] - y[c]).abs() <= 1e-3 * x[c].abs() + 1e-4,
                "{x:?} vs {y:?}"
            );
        }
    }
    assert_eq!(std::fs::read(&bundle).unwrap(), baked, "the bundle changed");
    let a = d.join("r0.exr");
    let b = d.join("r90.exr");
    let o = relight(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--heatmap",
        d.join("h.png").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("h.png").is_file());
}

#[test]
fn corrupt_or_truncated_bundle_is_refused_without_output() {
    let d = tmpdir("cli", "badbundle");
    let scene = furnace_scene(&d);
    let bundle = d.join("b.relight");
    bake_quick(&scene, &bundle);
    let bytes = std::fs::read(&bundle).unwrap();
    let out = d.join("never.png");
    // Truncated.
    let t = d.join("trunc.relight");
    std::fs::write(&t, &bytes[..bytes.len() / 2]).unwrap();
    let o = relight(&["render", t.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_clean_failure(&o, "trunc.relight", &out);
    // One flipped byte in the data section.
    let mut c = bytes.clone();
    let k = c.len() - 10;
    c[k] ^= 1;
    let cp = d.join("corrupt.relight");
    std::fs::write(&cp, &c).unwrap();
    let o = relight(&["render", cp.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_clean_failure(&o, "corrupt.relight", &out);
    assert!(stderr(&o).contains("checksum"));
    // Not a bundle at all.
    let np = d.join("notabundle.relight");
    std::fs::write(&np, b"hello world, I am not a bundle").unwrap();
    let o = relight(&["info", np.to_str().unwrap()]);
    assert_clean_failure(&o, "notabundle.relight", &out);
}

#[test]
fn bad_scene_files_are_reported_with_their_name() {
    let d = tmpdir("cli", "badscene");
    let out = d.join("out.relight");
    // Missing file.
    let o = relight(&[
        "bake",
        d.join("missing.json").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "missing.json", &out);
    // Malformed JSON (with the line).
    let bad = d.join("bad.json");
    std::fs::write(&bad, "{\n  \"shapes\": [\n   oops\n}").unwrap();
    let o = relight(&["bake", bad.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_clean_failure(&o, "bad.json: line 3", &out);
    // A mesh file that does not exist, named in the error.
    let nomesh = d.join("nomesh.json");
    std::fs::write(
        &nomesh,
        r#"{"shapes": [{"type": "mesh", "file": "nothere.obj"}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 40, "width": 8, "height": 8}}"#,
    )
    .unwrap();
    let o = relight(&[
        "bake",
        nomesh.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "nothere.obj", &out);
    // Absurd settings.
    let scene = furnace_scene(&d);
    let o = relight(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--order",
        "99",
    ]);
    assert_clean_failure(&o, "order", &out);
}

#[test]
fn bad_environment_for_render_is_refused_without_output() {
    let d = tmpdir("cli", "badenv");
    let scene = furnace_scene(&d);
    let bundle = d.join("e.relight");
    bake_quick(&scene, &bundle);
    // A latlong with a NaN and a negative pixel, written as EXR (which can hold them).
    let env = d.join("nan.exr");
    // relight's own EXR writer refuses such pixels, so write it with the exr crate directly.
    let write = |p: &Path, bad: f32| {
        exr::prelude::write_rgb_file(p, 16, 8, |x, y| {
            if (x, y) == (5, 0) {
                (bad, 1.0f32, 1.0f32)
            } else {
                (1.0, 1.0, 1.0)
            }
        })
        .unwrap()
    };
    write(&env, f32::NAN);
    let out = d.join("never.exr");
    let o = relight(&[
        "render",
        bundle.to_str().unwrap(),
        "--env",
        env.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "nan.exr", &out);
    let env = d.join("negative.exr");
    write(&env, -1.0);
    let o = relight(&[
        "render",
        bundle.to_str().unwrap(),
        "--env",
        env.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "negative.exr", &out);
    // Missing environment.
    let o = relight(&[
        "render",
        bundle.to_str().unwrap(),
        "--env",
        "/nonexistent/sky.hdr",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "/nonexistent/sky.hdr", &out);
}

#[test]
fn compare_refuses_images_of_different_sizes() {
    let d = tmpdir("cli", "cmp");
    let a = d.join("a.exr");
    let b = d.join("b.exr");
    relight_scene::io::image::write_exr(&a, 4, 4, &[glam::Vec3::ONE; 16]).unwrap();
    relight_scene::io::image::write_exr(&b, 4, 2, &[glam::Vec3::ONE; 8]).unwrap();
    let o = relight(&["compare", a.to_str().unwrap(), b.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("same size"));
}
