//! Resumable bakes as a user meets them: a checkpointed bake killed with SIGKILL at several
//! moments and finished with --resume writes the uninterrupted bake's bundle byte for byte;
//! a rerun without --resume says what it found.

mod common;

use common::{relight, stderr, tmpdir};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// A scene whose bake takes a few hundred milliseconds here (~8K vertices x 256 samples).
fn scene(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("scene.json");
    std::fs::write(
        &p,
        r#"{"shapes": [{"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 48},
                     {"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 40}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 16, "height": 12}}"#,
    )
    .unwrap();
    p
}

fn args<'a>(scene: &'a str, out: &'a str) -> Vec<&'a str> {
    vec![
        "bake",
        scene,
        "-o",
        out,
        "--samples",
        "256",
        "--seed",
        "3",
        "--backend",
        "bvh",
        "--threads",
        "1",
    ]
}

#[test]
fn a_bake_killed_at_any_moment_resumes_to_the_same_bytes() {
    let d = tmpdir("resume", "kill");
    let s = scene(&d);
    let (s, whole) = (s.to_str().unwrap(), d.join("whole.relight"));
    let t0 = Instant::now();
    let o = relight(&args(s, whole.to_str().unwrap()));
    assert!(o.status.success(), "{}", stderr(&o));
    let full = t0.elapsed();
    let want = std::fs::read(&whole).unwrap();

    let out = d.join("b.relight");
    let mut a = args(s, out.to_str().unwrap());
    a.extend(["--checkpoint-vertices", "400"]);
    // Kill at spread moments of the bake (pseudo-random fractions of its length, fixed so
    // that the test is repeatable), each run resuming the previous one's checkpoint.
    let mut kills = 0;
    for (k, frac) in [0.15, 0.5, 0.35, 0.8].into_iter().enumerate() {
        let mut run = a.clone();
        if k > 0 {
            run.push("--resume");
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_relight"))
            .args(&run)
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(full.mul_f64(frac).max(Duration::from_millis(20)));
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap(); // SIGKILL
            kills += 1;
        }
        child.wait().unwrap();
        if out.exists() {
            break; // finished before the kill
        }
    }
    assert!(kills > 0, "no run was killed (the bake took {full:?})");
    let chunks = std::fs::read_dir(d.join("b.relight.checkpoint")).map_or(0, |r| r.count());
    eprintln!("bake {full:?}; killed {kills} times; {chunks} chunk files left to resume from");
    let ckpt = d.join("b.relight.checkpoint");
    if out.exists() && ckpt.exists() {
        // The last kill landed after the bundle was renamed into place and before the folder
        // was removed (checkpoint module docs; seen once in CI on a loaded machine, session
        // 27): the bundle is complete, and a rerun with --resume rewrites the same bundle
        // from the chunks and removes the folder.
        let mut run = a.clone();
        run.push("--resume");
        let o = relight(&run);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    if !out.exists() {
        // A rerun without --resume says what it found, and changes nothing.
        let o = relight(&a);
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(
            e.contains("b.relight.checkpoint") && e.contains("--resume"),
            "{e}"
        );
        let mut run = a.clone();
        run.push("--resume");
        let o = relight(&run);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    assert!(
        std::fs::read(&out).unwrap() == want,
        "resumed bundle differs"
    );
    assert!(!ckpt.exists(), "the checkpoint is removed at the end");
}

#[test]
fn a_bake_over_its_memory_limit_is_chunked_to_the_same_bytes_or_refused() {
    let d = tmpdir("resume", "memory");
    let s = scene(&d);
    let (s, whole) = (s.to_str().unwrap(), d.join("whole.relight"));
    // At SH order 24 (2.3 KB per vertex) a whole bake is estimated at about 54 MiB, 10 of
    // them before the rows: 32 MiB leaves room for chunks only.
    let out = d.join("limited.relight");
    let mut a = args(s, out.to_str().unwrap());
    a.extend(["--sh-order", "24", "--memory-limit", "32M"]);
    let mut w = args(s, whole.to_str().unwrap());
    w.extend(["--sh-order", "24"]);
    let o = relight(&w);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = relight(&a);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("baking chunks of") && err.contains("chunk 2 of"),
        "{err}"
    );
    assert!(std::fs::read(&out).unwrap() == std::fs::read(&whole).unwrap());
    assert!(!d.join("limited.relight.checkpoint").exists());
    // sg cannot stream its merge: refused with the estimate, nothing written.
    let sg = d.join("sg.relight");
    let o = relight(&[
        "bake",
        s,
        "--method",
        "sg",
        "--memory-limit",
        "40M",
        "-o",
        sg.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert!(
        !o.status.success() && err.contains("GiB") && err.contains("sg merge"),
        "{err}"
    );
    assert!(!sg.exists());
    // A size that is not one.
    let o = relight(&[
        "bake",
        s,
        "--memory-limit",
        "lots",
        "-o",
        sg.to_str().unwrap(),
    ]);
    assert!(!o.status.success() && stderr(&o).contains("not a size"));
}
