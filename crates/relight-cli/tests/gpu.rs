//! `relight render --gpu` as a user runs it: the GPU frame next to the CPU frame of the same
//! bundle (feature `gpu`), a clear message when the binary was built without the feature,
//! and without a Vulkan driver a message saying what to install, a non-zero exit, no output,
//! and the CPU render still working. `scripts/test.sh` runs this file with `--features gpu`;
//! without it the tests that need the GPU skip for the platform precondition `feature-gpu`
//! (`relight_testdata::skip_platform`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
mod common;
use common::{assert_clean_failure, relight, stderr, tmpdir};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The shared sky-sphere bundle ([`common::sky_sphere_sh_bundle`]) of this file's tests.
fn bundle(dir: &Path) -> PathBuf {
    common::sky_sphere_sh_bundle(dir, 0.5, [0.0, 1.5, 3.0], [0.0, 0.4, 0.0])
}

/// `relight` with extra environment variables.
fn relight_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_relight"));
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().unwrap()
}

/// A build without the feature `gpu`: skip what needs it, through the skip policy (the
/// platform precondition `feature-gpu`; CI runs this file once with the feature, once without
/// and that skip allowed).
fn no_gpu_feature(what: &str) {
    relight_testdata::skip_platform(
        "feature-gpu",
        &format!("{what}: built without --features gpu"),
    );
}

fn read(p: &Path) -> Vec<glam::Vec3> {
    relight_render::read_image(p).unwrap().pixels
}

#[test]
fn render_gpu_matches_the_cpu_render_or_says_how_to_get_it() {
    let dir = tmpdir("gpu", "render");
    let b = bundle(&dir);
    let (cpu, gpu) = (dir.join("cpu.exr"), dir.join("gpu.exr"));
    for method in ["sh", "hybrid"] {
        let extra: &[&str] = if method == "hybrid" {
            &["--shadow-map-size", "512"]
        } else {
            &[]
        };
        let mut a = vec!["render", s(&b), "--method", method, "-o", s(&cpu)];
        a.extend(extra);
        let o = relight(&a);
        assert!(o.status.success(), "{}", stderr(&o));
        let mut a = vec![
            "render",
            s(&b),
            "--method",
            method,
            "--gpu",
            "--json",
            "-o",
            s(&gpu),
        ];
        a.extend(extra);
        let o = relight(&a);
        if !cfg!(feature = "gpu") {
            assert_clean_failure(&o, "--features gpu", &gpu);
            no_gpu_feature("the GPU frame is not compared with the CPU frame");
            return;
        }
        if !o.status.success() && stderr(&o).contains("no Vulkan GPU adapter") {
            relight_testdata::skip(&format!("no Vulkan adapter: {}", stderr(&o)));
            return;
        }
        assert!(o.status.success(), "{}", stderr(&o));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let frame = &j["gpu"]["frame"];
        assert!(
            frame["adapter"].as_str().is_some_and(|a| !a.is_empty()),
            "{j}"
        );
        assert!(frame["draw_calls"].as_u64().unwrap() >= 2, "{j}");
        // Same image up to f32 rounding (relight-gpu's tests bound the differences pixel by
        // pixel; here the mean over lit pixels, silhouettes included, within 1e-3).
        let (c, g) = (read(&cpu), read(&gpu));
        let (mut sum, mut n) = (0.0f64, 0);
        for (c, g) in c.iter().zip(&g) {
            if c.max_element() > 0.0 {
                sum += ((*g - *c).abs().max_element() / c.max_element()) as f64;
                n += 1;
            }
        }
        assert!(n > 1000, "{method}: {n} lit pixels");
        assert!(
            sum / (n as f64) < 1e-3,
            "{method}: mean relative difference {}",
            sum / n as f64
        );
    }
}

#[test]
fn without_a_vulkan_driver_render_gpu_says_what_to_install_and_the_cpu_render_works() {
    if !cfg!(feature = "gpu") {
        no_gpu_feature("the refusal without a Vulkan driver is not checked");
        return;
    }
    let dir = tmpdir("gpu", "no-driver");
    let b = bundle(&dir);
    let out = dir.join("x.png");
    // The Vulkan loader reads its drivers from these lists: point them at nothing.
    let none = [
        ("VK_DRIVER_FILES", "/nonexistent/icd.json"),
        ("VK_ICD_FILENAMES", "/nonexistent/icd.json"),
    ];
    let o = relight_env(&["render", s(&b), "--gpu", "-o", s(&out)], &none);
    assert_clean_failure(&o, "mesa-vulkan-drivers", &out);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let o = relight_env(&["render", s(&b), "-o", s(&out)], &none);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.is_file());
}

#[test]
fn render_gpu_of_an_sg_bundle_matches_the_cpu_render() {
    if !cfg!(feature = "gpu") {
        no_gpu_feature("the sg frame is not compared with the CPU frame");
        return;
    }
    let dir = tmpdir("gpu", "sg");
    let scene = dir.join("scene.json");
    std::fs::write(
        &scene,
        r#"{"shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "rings": 12,
              "material": {"type": "ggx_conductor", "specular": [0.9, 0.7, 0.4], "alpha": 0.2}}],
           "environment": {"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 30,
                           "turbidity": 3, "ground_albedo": [0.3, 0.3, 0.3]},
           "camera": {"origin": [0, 0.5, 4], "target": [0, 0, 0], "up": [0, 1, 0],
                      "fov_deg": 40, "width": 64, "height": 48}}"#,
    )
    .unwrap();
    let b = dir.join("sg.relight");
    let o = relight(&[
        "bake",
        s(&scene),
        "-o",
        s(&b),
        "--method",
        "sg",
        "--direct-res",
        "8",
        "--indirect-lobes",
        "0",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (cpu, gpu) = (dir.join("cpu.exr"), dir.join("gpu.exr"));
    let o = relight(&["render", s(&b), "--prefilter-size", "64", "-o", s(&cpu)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&[
        "render",
        s(&b),
        "--prefilter-size",
        "64",
        "--gpu",
        "-o",
        s(&gpu),
    ]);
    if !o.status.success() && stderr(&o).contains("no Vulkan GPU adapter") {
        relight_testdata::skip(&format!("no Vulkan adapter: {}", stderr(&o)));
        return;
    }
    assert!(o.status.success(), "{}", stderr(&o));
    let (c, g) = (read(&cpu), read(&gpu));
    let (mut sum, mut n) = (0.0f64, 0);
    for (c, g) in c.iter().zip(&g) {
        if c.max_element() > 0.0 {
            sum += ((*g - *c).abs().max_element() / c.max_element()) as f64;
            n += 1;
        }
    }
    // The sphere covers about a third of the image; mean over lit pixels, silhouettes
    // included, within 1e-3 (relight-gpu's tests bound every pixel).
    assert!(n > 500, "{n} lit pixels");
    assert!(
        sum / (n as f64) < 1e-3,
        "mean relative difference {}",
        sum / n as f64
    );
    // With the environment drawn behind: the same image, background pixels included.
    let o = relight(&[
        "render",
        s(&b),
        "--prefilter-size",
        "64",
        "--background",
        "-o",
        s(&cpu),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let a = [
        "render",
        s(&b),
        "--prefilter-size",
        "64",
        "--background",
        "--gpu",
        "-o",
        s(&gpu),
    ];
    let o = relight(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let (c, g) = (read(&cpu), read(&gpu));
    let mean = c
        .iter()
        .zip(&g)
        .map(|(c, g)| ((*g - *c).abs().max_element() / c.max_element().max(1e-6)) as f64)
        .sum::<f64>()
        / c.len() as f64;
    assert!(
        mean < 1e-3,
        "mean relative difference with background {mean}"
    );
}

#[test]
fn wgpu_adapter_name_picks_the_adapter_or_lists_them() {
    if !cfg!(feature = "gpu") {
        no_gpu_feature("WGPU_ADAPTER_NAME is not checked");
        return;
    }
    let dir = tmpdir("gpu", "adapter");
    let b = bundle(&dir);
    let out = dir.join("x.exr");
    let o = relight_env(
        &["render", s(&b), "--gpu", "-o", s(&out)],
        &[("WGPU_ADAPTER_NAME", "no-such-adapter")],
    );
    assert_clean_failure(&o, "WGPU_ADAPTER_NAME=no-such-adapter matches none", &out);
    // Lavapipe by name (wgpu calls it llvmpipe), where it is installed: no adapter of that
    // name skips (a failure in CI, which installs it); any other failure is the render's.
    let o = relight_env(
        &["render", s(&b), "--gpu", "--json", "-o", s(&out)],
        &[("WGPU_ADAPTER_NAME", "llvmpipe")],
    );
    if !o.status.success() && stderr(&o).contains("no Vulkan GPU adapter") {
        relight_testdata::skip(&format!("lavapipe not installed: {}", stderr(&o)));
        return;
    }
    assert!(
        o.status.success(),
        "the render on llvmpipe failed: {}",
        stderr(&o)
    );
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let name = j["gpu"]["frame"]["adapter"].as_str().unwrap();
    assert!(name.to_lowercase().contains("llvmpipe"), "{name}");
}

#[test]
fn cuts_renders_on_the_gpu_and_what_it_does_not_render_is_refused_by_name() {
    if !cfg!(feature = "gpu") {
        no_gpu_feature("the cuts frame is not rendered");
        return;
    }
    let dir = tmpdir("gpu", "cuts");
    let b = bundle(&dir);
    let scene = dir.join("scene.json");
    let cuts = dir.join("cuts.relight");
    let o = relight(&[
        "bake",
        s(&scene),
        "-o",
        s(&cuts),
        "--method",
        "cuts",
        "--cut-lights",
        "256",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.join("x.exr");
    let o = relight(&["render", s(&cuts), "--gpu", "-o", s(&out)]);
    if stderr(&o).contains("no Vulkan GPU adapter") {
        relight_testdata::skip(&format!("no Vulkan adapter: {}", stderr(&o)));
        return;
    }
    // The cuts frame renders (pixel-by-pixel checks: relight-gpu's tests/cpu_vs_gpu_cuts.rs).
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(read(&out).iter().any(|p| p.max_element() > 0.0));
    std::fs::remove_file(&out).unwrap();
    // A material the GPU does not shade yet, by name.
    let phong = r#"{"type": "blinn_phong", "diffuse": [0.5, 0.5, 0.5], "specular": [0.3, 0.3, 0.3], "exponent": 20}"#;
    let o = relight(&[
        "render",
        s(&cuts),
        "--gpu",
        "--material",
        phong,
        "-o",
        s(&out),
    ]);
    assert_clean_failure(&o, "is not supported on the GPU yet", &out);
    // And a bundle of the wrong kind for the method, in the CPU frame's words.
    let o = relight(&["render", s(&b), "--gpu", "--method", "sg", "-o", s(&out)]);
    assert_clean_failure(&o, "holds a `sh` bake", &out);
}

#[test]
fn an_environment_with_nan_texels_is_refused_before_the_gpu_starts() {
    let dir = tmpdir("gpu", "nan");
    let b = bundle(&dir);
    // A latlong with a NaN texel, written with the exr crate (relight's writer refuses NaN).
    let env = dir.join("nan.exr");
    exr::prelude::write_rgb_file(&env, 8, 4, |x, y| {
        if (x, y) == (3, 1) {
            (1.0, f32::NAN, 0.0)
        } else {
            (1.0, 1.0, 1.0)
        }
    })
    .unwrap();
    let out = dir.join("x.png");
    // The same refusal with or without the feature, and without any Vulkan driver: the
    // environment is read and checked before the GPU is opened.
    let o = relight_env(
        &["render", s(&b), "--gpu", "--env", s(&env), "-o", s(&out)],
        &[("VK_DRIVER_FILES", "/nonexistent/icd.json")],
    );
    let expect = if cfg!(feature = "gpu") {
        "nan.exr"
    } else {
        "--features gpu"
    };
    assert_clean_failure(&o, expect, &out);
}
