//! `relight view` as a user runs it (feature `view`): under Xvfb with a Vulkan driver
//! (lavapipe in CI), the viewer is driven by a `--script` of actions on a tiny bundle baked
//! here, and its screenshots are checked: not empty, the object where expected, a change
//! after rotating the environment and after orbiting, the other method, the reference's
//! error. Bad input: a bundle of a method the viewer cannot show, an environment with a NaN
//! texel and a missing bundle are shown in the window (a scripted run then exits 1 and
//! prints them on stdout); a script that does not parse and a missing Vulkan driver end with
//! a message and exit 1 before any window. Without Xvfb or a Vulkan adapter the window tests
//! skip with a printed reason (and fail under `RELIGHT_REQUIRE_REFERENCE=1`). A build without
//! the feature says which feature to build with; there the tests that need the viewer skip
//! for the platform precondition `feature-view` (`relight_testdata::skip_platform`).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::Duration;
mod common;
use common::{assert_clean_failure, relight, stderr, stdout, tmpdir};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The shared sky-sphere bundle ([`common::sky_sphere_sh_bundle`]) of this file's tests.
fn bundle(dir: &Path) -> PathBuf {
    common::sky_sphere_sh_bundle(dir, 0.6, [0.0, 1.2, 3.0], [0.0, 0.5, 0.0])
}

/// An X server for the test's windows, killed when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Start `Xvfb` on a free display, or `None` after a printed skip (a failure under
/// `RELIGHT_REQUIRE_REFERENCE=1`). Xvfb picks the display itself (`-displayfd`: it takes the
/// display's lock and writes its number once it accepts connections), so tests running in
/// parallel never share a server: choosing the number here raced, two tests could both see a
/// display free, and one test's server was killed under the other's window.
fn xvfb() -> Option<Xvfb> {
    let child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "1280x1024x24",
            "-nolisten",
            "tcp",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn();
    let mut child = match child {
        Ok(c) => c,
        Err(e) => {
            relight_testdata::skip(&format!("cannot start Xvfb ({e}): apt-get install xvfb"));
            return None;
        }
    };
    let out = child.stdout.take().expect("piped stdout");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(out), &mut line);
        let _ = tx.send(line);
    });
    match rx.recv_timeout(Duration::from_secs(20)) {
        Ok(line) if line.trim().parse::<u32>().is_ok() => Some(Xvfb {
            child,
            display: format!(":{}", line.trim()),
        }),
        other => {
            let _ = child.kill();
            let _ = child.wait();
            relight_testdata::skip(&format!("Xvfb did not report a display: {other:?}"));
            None
        }
    }
}

/// `relight view` on `display` with lavapipe (unless `WGPU_ADAPTER_NAME` is set) and `args`.
fn view(x: &Xvfb, cwd: &Path, args: &[&str]) -> Output {
    let adapter = std::env::var("WGPU_ADAPTER_NAME").unwrap_or_else(|_| "llvmpipe".into());
    Command::new(env!("CARGO_BIN_EXE_relight"))
        .current_dir(cwd)
        .arg("view")
        .args(args)
        .env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("WGPU_ADAPTER_NAME", adapter)
        .output()
        .expect("run relight view")
}

/// Whether `o` failed for want of a Vulkan adapter (then skip, printed).
fn no_vulkan(o: &Output) -> bool {
    if !o.status.success() && stderr(o).contains("no Vulkan GPU adapter") {
        relight_testdata::skip(&format!("no Vulkan adapter: {}", stderr(o)));
        return true;
    }
    false
}

/// A build without the feature `view`: skip what needs it, through the skip policy (the
/// platform precondition `feature-view`; CI runs this file once with the feature, once
/// without and that skip allowed).
fn no_view_feature(what: &str) {
    relight_testdata::skip_platform(
        "feature-view",
        &format!("{what}: built without --features view"),
    );
}

fn read(p: &Path) -> relight_render::Image {
    relight_render::read_image(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Mean luminance over the box `[x0, x1) x [y0, y1)` given as fractions of the image.
fn mean(img: &relight_render::Image, x0: f32, x1: f32, y0: f32, y1: f32) -> f32 {
    let (w, h) = (img.width as f32, img.height as f32);
    let (mut sum, mut n) = (0.0, 0);
    for y in (y0 * h) as usize..(y1 * h) as usize {
        for x in (x0 * w) as usize..(x1 * w) as usize {
            sum += relight_render::compare::luminance(img.get(x, y));
            n += 1;
        }
    }
    sum / n.max(1) as f32
}

fn png_size(p: &Path) -> (u32, u32) {
    let b = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert_eq!(&b[1..4], b"PNG", "{} is not a PNG", p.display());
    let be = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    (be(16), be(20))
}

#[test]
fn the_viewer_runs_a_script_and_its_screenshots_show_the_object_and_the_changes() {
    let dir = tmpdir("view", "script");
    let b = bundle(&dir);
    if !cfg!(feature = "view") {
        let o = relight(&["view", s(&b)]);
        assert_clean_failure(&o, "--features view", &dir.join("none"));
        no_view_feature("the viewer's script is not run");
        return;
    }
    let Some(x) = xvfb() else { return };
    let script = dir.join("s.txt");
    std::fs::write(
        &script,
        "# as a user would: look, rotate the sky, orbit, switch method, compare\n\
         wait-frames 3\n\
         screenshot a.exr\n\
         screenshot a.png\n\
         rotate-env 90\n\
         screenshot b.exr\n\
         orbit 40 0\n\
         screenshot c.exr\n\
         method hybrid\n\
         wait-frames 2\n\
         screenshot d.exr\n\
         split heatmap\n\
         wait-reference 8\n\
         print-state\n\
         screenshot-window window.png\n\
         quit\n",
    )
    .unwrap();
    let o = view(
        &x,
        &dir,
        &[s(&b), "--script", s(&script), "--size", "640x420"],
    );
    if no_vulkan(&o) {
        return;
    }
    assert!(
        o.status.success(),
        "stdout {}\nstderr {}",
        stdout(&o),
        stderr(&o)
    );
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    let (a, b2, c, d) = (
        read(&dir.join("a.exr")),
        read(&dir.join("b.exr")),
        read(&dir.join("c.exr")),
        read(&dir.join("d.exr")),
    );
    assert!(
        a.width >= 200 && a.height >= 200,
        "{}x{}",
        a.width,
        a.height
    );
    // The sphere is at the centre of the bundle's view, lit by the sky; the corners above
    // the plane see nothing (no background): black. The centre is well above zero (a grey
    // Lambert sphere under a sky of a few kcd/m^2 has radiance of order 1).
    let centre = mean(&a, 0.4, 0.6, 0.35, 0.55);
    assert!(centre > 0.05, "centre luminance {centre}");
    assert_eq!(
        mean(&a, 0.0, 0.05, 0.0, 0.05),
        0.0,
        "top-left corner is not empty"
    );
    // Rotating the sky by 90 degrees moves the sun from one side of the sphere to another:
    // the shading of the centre region changes by far more than rendering noise (none: the
    // GPU frame is deterministic) -- at least 2 % of its luminance on average per pixel.
    let diff = |p: &relight_render::Image, q: &relight_render::Image| {
        p.pixels
            .iter()
            .zip(&q.pixels)
            .map(|(u, v)| (*u - *v).abs().max_element())
            .sum::<f32>()
            / p.pixels.len() as f32
    };
    assert!(
        diff(&a, &b2) > 0.02 * centre,
        "rotating the environment changed nothing"
    );
    assert!(diff(&b2, &c) > 0.02 * centre, "orbiting changed nothing");
    assert!(
        mean(&d, 0.4, 0.6, 0.35, 0.55) > 0.05,
        "the hybrid frame is empty"
    );
    assert!(png_size(&dir.join("a.png")) == (a.width as u32, a.height as u32));
    // The window: at least the size asked for, panels included.
    let (ww, wh) = png_size(&dir.join("window.png"));
    assert!(ww >= 640 && wh >= 420, "window screenshot {ww}x{wh}");
    let out = stdout(&o);
    let state = out.lines().find(|l| l.contains("state:")).unwrap_or("");
    assert!(state.contains("method=hybrid"), "{out}");
    let rmse: f64 = state
        .split("rel_rmse=")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|r| r.parse().ok())
        .unwrap_or_else(|| panic!("no relative RMSE in {state}"));
    // The hybrid frame of an order-3 shadowed bake against an 8-spp path-traced reference of
    // the same view with all bounces: a relative RMSE of a few tenths (reference noise,
    // interreflections the bake leaves out, order 3). A misaligned view or camera would be
    // near or above 1.
    assert!(rmse > 0.0 && rmse < 0.6, "relative RMSE {rmse}");
}

#[test]
fn the_viewer_shows_bad_input_in_its_window_and_a_scripted_run_exits_1() {
    if !cfg!(feature = "view") {
        no_view_feature("bad input in the window is not checked");
        return;
    }
    let dir = tmpdir("view", "bad");
    let b = bundle(&dir);
    let script = dir.join("s.txt");
    std::fs::write(
        &script,
        "wait-frames 3\nscreenshot-window w.png\nprint-state\nquit\n",
    )
    .unwrap();
    // A script that does not parse: file and line, before any window or GPU.
    let bad = dir.join("bad.txt");
    std::fs::write(&bad, "wait-frames 1\n\norbit 30\n").unwrap();
    let o = relight(&["view", s(&b), "--script", s(&bad)]);
    assert_clean_failure(&o, &format!("{}:3:", bad.display()), &dir.join("none"));
    let Some(x) = xvfb() else { return };
    // A vmf bundle: the GPU has no vmf renderer yet.
    let scene = dir.join("scene.json");
    let vmf = dir.join("vmf.relight");
    let o = relight(&[
        "bake",
        s(&scene),
        "-o",
        s(&vmf),
        "--method",
        "vmf",
        "--view-level",
        "1",
        "--paths",
        "64",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // An environment with a NaN texel (written with the exr crate: relight refuses to).
    let nan = dir.join("nan.exr");
    exr::prelude::write_rgb_file(&nan, 8, 4, |x, y| {
        if (x, y) == (3, 1) {
            (1.0, f32::NAN, 0.0)
        } else {
            (1.0, 1.0, 1.0)
        }
    })
    .unwrap();
    let missing = dir.join("missing.relight");
    for (args, must_show) in [
        (vec![s(&vmf)], "vmf"),
        (vec![s(&b), "--env", s(&nan)], "nan.exr"),
        (vec![s(&missing)], "missing.relight"),
    ] {
        let _ = std::fs::remove_file(dir.join("w.png"));
        let mut a = args.clone();
        a.extend(["--script", s(&script), "--size", "480x320"]);
        let o = view(&x, &dir, &a);
        if no_vulkan(&o) {
            return;
        }
        let (out, err) = (stdout(&o), stderr(&o));
        assert_eq!(
            o.status.code(),
            Some(1),
            "{args:?}: stdout {out}\nstderr {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let shown = out
            .lines()
            .find(|l| l.contains("shown in the window"))
            .unwrap_or_else(|| panic!("{args:?}: nothing shown: {out}"));
        assert!(shown.contains(must_show), "{args:?}: {shown}");
        assert!(err.contains(must_show), "{args:?}: {err}");
        // The window kept running: its screenshot was taken after the error.
        assert!(png_size(&dir.join("w.png")).0 >= 480, "{args:?}");
    }
}

#[test]
fn without_a_vulkan_driver_view_says_what_to_install_and_exits_1() {
    if !cfg!(feature = "view") {
        no_view_feature("the refusal without a Vulkan driver is not checked");
        return;
    }
    let dir = tmpdir("view", "no-driver");
    let b = bundle(&dir);
    let o = Command::new(env!("CARGO_BIN_EXE_relight"))
        .args(["view", s(&b)])
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .output()
        .unwrap();
    assert_clean_failure(&o, "mesa-vulkan-drivers libvulkan1", &dir.join("none"));
    assert_eq!(o.status.code(), Some(1));
    // `--help` lists the shortcuts and the script actions.
    let o = relight(&["view", "--help"]);
    assert!(o.status.success());
    for needle in ["ctrl + left drag", "rotate-env DEG", "screenshot FILE.png"] {
        assert!(stdout(&o).contains(needle), "--help lacks {needle}");
    }
}

/// `relight view MODEL`: a model file is baked first (the bake's choices printed) into a
/// cache under `XDG_CACHE_HOME`, then shown; the second view of the same file opens the
/// cached bundle without baking.
#[test]
fn viewing_a_model_file_bakes_it_once_into_the_cache() {
    if !cfg!(feature = "view") {
        return no_view_feature("view MODEL");
    }
    let Some(x) = xvfb() else { return };
    let d = tmpdir("view", "model");
    std::fs::write(
        d.join("pyramid.obj"),
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv 0 1.5 0\n\
         f 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
    std::fs::write(d.join("s.txt"), "wait-frames 3\nscreenshot w.png\nquit\n").unwrap();
    let cache = d.join("cache");
    let run = || {
        let adapter = std::env::var("WGPU_ADAPTER_NAME").unwrap_or_else(|_| "llvmpipe".into());
        Command::new(env!("CARGO_BIN_EXE_relight"))
            .current_dir(&d)
            .args([
                "view",
                "pyramid.obj",
                "--script",
                "s.txt",
                "--size",
                "640x420",
            ])
            .env("DISPLAY", &x.display)
            .env("XDG_CACHE_HOME", &cache)
            .env_remove("WAYLAND_DISPLAY")
            .env("WGPU_ADAPTER_NAME", adapter)
            .output()
            .expect("run relight view")
    };
    let o = run();
    if no_vulkan(&o) {
        return;
    }
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("view: baking pyramid.obj first"), "{e}");
    assert!(e.contains("method: sh"), "{e}");
    let cached: Vec<_> = std::fs::read_dir(cache.join("relight/view"))
        .unwrap()
        .map(|f| f.unwrap().path())
        .collect();
    assert_eq!(cached.len(), 1, "{cached:?}");
    assert!(d.join("w.png").is_file());
    let o = run();
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("using the bake of pyramid.obj cached at"), "{e}");
    assert!(!e.contains("baking"), "{e}");
}
