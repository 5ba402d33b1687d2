//! End-to-end tests of the `sg` method in the `relight` binary: bake, render, info, storage
//! as f32 and f16, and bad input. The tests that bake need `relight_bake::sg::bake`.

use std::path::{Path, PathBuf};
mod common;
use common::{assert_clean_failure, relight, stderr, stdout, tmpdir};
use std::process::Output;

/// A small glossy sphere under a constant environment of radiance 1: a convex object sees
/// only the environment, so every pixel's radiance is the material's directional albedo,
/// between 0 and 1.
fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("glossy.json");
    std::fs::write(
        &p,
        r#"{
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 6,
              "material": {"type": "ggx_plastic", "diffuse": [0.5, 0.3, 0.2],
                           "specular": [1, 1, 1], "alpha": 0.2, "ior": 1.5}}],
  "environment": {"type": "constant", "radiance": [1, 1, 1]},
  "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov_deg": 40, "width": 16, "height": 12}
}"#,
    )
    .unwrap();
    p
}

/// Bake `scene` with small cube maps and few iterations (plus `extra` flags).
fn bake_sg(scene: &Path, bundle: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "bake",
        scene.to_str().unwrap(),
        "-o",
        bundle.to_str().unwrap(),
        "--method",
        "sg",
        "--direct-res",
        "8",
        "--indirect-res",
        "4",
        "--indirect-paths",
        "4",
        "--sh-order",
        "3",
        "--fit-iterations",
        "5",
        "--seed",
        "3",
    ];
    args.extend_from_slice(extra);
    relight(&args)
}

fn read_exr(p: &Path) -> (usize, usize, Vec<[f32; 3]>) {
    let (w, h, px) = relight_scene::io::image::read_image(p).unwrap();
    (w, h, px.iter().map(|c| c.to_array()).collect())
}

/// The named tensor of a bundle file as f32 (F32 or F16), parsed as docs/BUNDLE.md says.
fn tensor(path: &Path, name: &str) -> (String, Vec<usize>, Vec<f32>) {
    let raw = std::fs::read(path).unwrap();
    let n = u64::from_le_bytes(raw[..8].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&raw[8..8 + n]).unwrap();
    let t = &header[name];
    let dtype = t["dtype"].as_str().unwrap().to_string();
    let shape = t["shape"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap() as usize)
        .collect();
    let [a, b] = [0, 1].map(|i| t["data_offsets"][i].as_u64().unwrap() as usize);
    let data = &raw[8 + n + a..8 + n + b];
    let values = match dtype.as_str() {
        "F32" => data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect(),
        "F16" => data
            .chunks_exact(2)
            .map(|c| f16_to_f32(u16::from_le_bytes([c[0], c[1]])))
            .collect(),
        d => panic!("dtype {d}"),
    };
    (dtype, shape, values)
}

/// IEEE half to single (normal, subnormal, zero; no inf/NaN in bundles).
fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let e = ((h >> 10) & 0x1f) as i32;
    let m = (h & 0x3ff) as f32;
    sign * if e == 0 {
        m * 2f32.powi(-24)
    } else {
        (1.0 + m / 1024.0) * 2f32.powi(e - 15)
    }
}

#[test]
fn help_lists_every_sg_setting_with_its_default() {
    let o = relight(&["bake", "--help"]);
    assert!(o.status.success());
    let s = stdout(&o);
    for flag in [
        "--direct-res",
        "--indirect-res",
        "--indirect-paths",
        "--bounces",
        "--sh-order",
        "--horizon-deg",
        "--direct-lobes",
        "--indirect-lobes",
        "--fit-iterations",
        "--mean-weight",
        "--width-weight",
        "--spatial-weight",
        "--relax-sweeps",
        "--regions",
        "--blend-to",
        "--blend-axis",
    ] {
        assert!(s.contains(flag), "bake --help misses {flag}:\n{s}");
    }
    assert!(s.contains("[default: 32]") && s.contains("SG bake"), "{s}");
}

#[test]
fn bad_sg_settings_and_bundles_are_refused_before_any_work() {
    let d = tmpdir("sg", "bad");
    let sc = scene(&d);
    let out = d.join("never.relight");
    let o = bake_sg(&sc, &out, &["--direct-lobes", "0"]);
    assert_clean_failure(&o, "direct_lobes", &out);
    let o = bake_sg(&sc, &out, &["--blend-to", "{\"type\": \"lambert\""]);
    assert_clean_failure(&o, "--blend-to", &out);
    let o = bake_sg(
        &sc,
        &out,
        &[
            "--blend-to",
            "{\"type\": \"lambert\", \"albedo\": [1, 1, 1]}",
            "--blend-axis",
            "1,2",
        ],
    );
    assert_clean_failure(&o, "--blend-axis", &out);
    // An sh bundle rendered as sg: the error says what the bundle is.
    let sh = d.join("sh.relight");
    let o = relight(&[
        "bake",
        sc.to_str().unwrap(),
        "-o",
        sh.to_str().unwrap(),
        "--method",
        "sh",
        "--samples",
        "8",
        "--order",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = d.join("never.exr");
    let o = relight(&[
        "render",
        sh.to_str().unwrap(),
        "--method",
        "sg",
        "-o",
        img.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "holds a `sh` bake", &img);
}

/// Needs the SG bake.
#[test]
fn sg_bake_render_and_info() {
    let d = tmpdir("sg", "render");
    let sc = scene(&d);
    let bundle = d.join("g.relight");
    let o = bake_sg(&sc, &bundle, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("bytes per vertex"), "{}", stdout(&o));
    let (exr, png) = (d.join("g.exr"), d.join("g.png"));
    let o = relight(&[
        "render",
        bundle.to_str().unwrap(),
        "--method",
        "sg",
        "--rotate-y",
        "30",
        "--supersample",
        "1",
        "-o",
        exr.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(png.is_file());
    let (w, h, px) = read_exr(&exr);
    assert_eq!((w, h), (16, 12));
    // The centre sees the sphere: a directional albedo in (0, 1]. The bound is loose (the fit
    // of 8x8 cube maps with 5 iterations is coarse); 1.1 leaves 10 % for fitting error.
    let c = px[6 * 16 + 8];
    assert!(
        c.iter().all(|&x| x.is_finite() && x > 0.01 && x < 1.1),
        "{c:?}"
    );
    assert_eq!(px[0], [0.0; 3], "corners miss the sphere");
    let o = relight(&["info", bundle.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = stdout(&o);
    assert!(
        s.contains("method: sg") && s.contains("bytes per vertex") && s.contains("92 views"),
        "{s}"
    );
}

/// Needs the SG bake.
#[test]
fn f16_sg_bundle_matches_the_f32_one_within_half_precision() {
    let d = tmpdir("sg", "f16");
    let sc = scene(&d);
    let (a, b) = (d.join("a.relight"), d.join("b.relight"));
    for (p, extra) in [(&a, &[][..]), (&b, &["--f16"][..])] {
        let o = bake_sg(&sc, p, &[&["--indirect-lobes", "1"], extra].concat());
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // The bake is deterministic for a seed: the f16 file holds the f32 values rounded to
    // 11 significant bits (relative 2^-11, plus the f16 subnormal step near zero).
    for name in ["sg_direct", "sg_indirect", "sg_diffuse"] {
        let (ta, sa, va) = tensor(&a, name);
        let (tb, sb, vb) = tensor(&b, name);
        assert_eq!((ta.as_str(), tb.as_str()), ("F32", "F16"));
        assert_eq!(sa, sb);
        for (x, y) in va.iter().zip(&vb) {
            assert!(
                (x - y).abs() <= x.abs() * 2f32.powi(-11) + 6e-8,
                "{name}: {x} vs {y}"
            );
        }
    }
    assert!(std::fs::metadata(&b).unwrap().len() < std::fs::metadata(&a).unwrap().len());
    // Rendered: the same image up to the rounding (1 % relative, a few f16 steps summed).
    let render = |bundle: &Path, out: &Path| {
        let o = relight(&[
            "render",
            bundle.to_str().unwrap(),
            "--method",
            "sg",
            "--supersample",
            "1",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        read_exr(out).2
    };
    let (pa, pb) = (render(&a, &d.join("a.exr")), render(&b, &d.join("b.exr")));
    for (x, y) in pa.iter().zip(&pb) {
        for c in 0..3 {
            assert!(
                (x[c] - y[c]).abs() <= 0.01 * x[c].abs() + 1e-4,
                "{x:?} vs {y:?}"
            );
        }
    }
}

/// Needs the SG bake.
#[test]
fn corrupt_sg_bundle_is_refused_without_output() {
    let d = tmpdir("sg", "corrupt");
    let sc = scene(&d);
    let bundle = d.join("c.relight");
    let o = bake_sg(&sc, &bundle, &["--indirect-lobes", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut bytes = std::fs::read(&bundle).unwrap();
    let k = bytes.len() - 20;
    bytes[k] ^= 1;
    let bad = d.join("flipped.relight");
    std::fs::write(&bad, &bytes).unwrap();
    let out = d.join("never.exr");
    let o = relight(&[
        "render",
        bad.to_str().unwrap(),
        "--method",
        "sg",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_clean_failure(&o, "flipped.relight", &out);
    assert!(stderr(&o).contains("checksum"), "{}", stderr(&o));
    let o = relight(&["info", bad.to_str().unwrap()]);
    assert_clean_failure(&o, "flipped.relight", &out);
}

/// Needs the SG bake.
#[test]
fn blended_material_bake_records_per_vertex_materials() {
    let d = tmpdir("sg", "blend");
    let sc = scene(&d);
    let bundle = d.join("b.relight");
    let to = r#"{"type": "ggx_plastic", "diffuse": [0.1, 0.6, 0.1], "specular": [1, 1, 1], "alpha": 0.05, "ior": 1.5}"#;
    let o = bake_sg(
        &sc,
        &bundle,
        &[
            "--indirect-lobes",
            "0",
            "--blend-to",
            to,
            "--blend-axis",
            "0,1,0",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&["info", bundle.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = stdout(&o);
    // A 6-ring sphere has 7 distinct heights along +Y: at least that many materials.
    let line = s
        .lines()
        .find(|l| l.contains("distinct per-vertex materials"))
        .expect(&s);
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "distinct").expect(line);
    let n: usize = words[at - 1].parse().expect(line);
    assert!(n >= 5, "{line}");
    assert!(line.contains("blend to"), "{line}");
}

/// Needs the SG bake. Without lobe options the bake chooses the lobes by the scene's
/// materials (`LobeSetting::for_materials`: the half-vector GGX lobes, nested, for a GGX
/// conductor; the light-domain Gaussians otherwise), says so, and records it; a lobe option
/// given keeps the user's setting.
#[test]
fn lobes_are_chosen_by_material_unless_an_option_is_given() {
    let d = tmpdir("sg", "lobes");
    let plastic = scene(&d);
    let conductor = d.join("conductor.json");
    std::fs::write(
        &conductor,
        r#"{
  "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 6,
              "material": {"type": "ggx_conductor", "specular": [0.9, 0.8, 0.6], "alpha": 0.2}}],
  "environment": {"type": "constant", "radiance": [1, 1, 1]},
  "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0],
             "fov_deg": 40, "width": 16, "height": 12}
}"#,
    )
    .unwrap();
    let info = |b: &Path| {
        let o = relight(&["info", b.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        stdout(&o)
    };
    let half = "ggx, half-vector domain, additive";
    let light = "gaussian, light domain, joint";
    for (sc, extra, chosen, recorded) in [
        (&conductor, &[][..], Some(half), half),
        (&conductor, &["--direct-lobes", "2"][..], Some(half), half),
        (&conductor, &["--lobe-domain", "light"][..], None, light),
        (&plastic, &[][..], Some(light), light),
    ] {
        let b = d.join("b.relight");
        let _ = std::fs::remove_file(&b);
        let o = bake_sg(sc, &b, &[&["--indirect-lobes", "0"], extra].concat());
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let e = stderr(&o);
        match chosen {
            Some(c) => assert!(e.contains(&format!("sg lobes: {c} (")), "{extra:?}: {e}"),
            None => assert!(!e.contains("sg lobes:"), "{extra:?}: {e}"),
        }
        let i = info(&b);
        assert!(i.contains(&format!("({recorded})")), "{extra:?}: {i}");
    }
}
