//! Sharded bakes end to end: `bake --shard` + `merge` give the one-process bundle byte for
//! byte, and the same through a real Slurm (a one-node cluster on localhost started by
//! deploy/slurm/local-cluster.sh, the array and merge jobs of deploy/slurm/submit.sh).

mod common;

use common::{relight, stderr, tmpdir};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A small scene: a sphere on a plane under a sky (~300 vertices).
fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("scene.json");
    std::fs::write(
        &p,
        r#"{"shapes": [
              {"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 12,
               "material": {"type": "lambert", "albedo": [0.8, 0.3, 0.2]}},
              {"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 6}],
            "environment": {"type": "sky", "sun_elevation_deg": 40, "sun_azimuth_deg": 30,
                            "turbidity": 3, "ground_albedo": [0.3, 0.3, 0.3]},
            "camera": {"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 32, "height": 24}}"#,
    )
    .unwrap();
    p
}

const BAKE: [&str; 6] = ["--samples", "64", "--seed", "7", "--backend", "bvh"];

/// The one-process bake of `scene` into `out`.
fn whole(scene: &Path, out: &Path) -> Vec<u8> {
    let mut a = vec!["bake", scene.to_str().unwrap(), "-o", out.to_str().unwrap()];
    a.extend(BAKE);
    let o = relight(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::read(out).unwrap()
}

#[test]
fn sharded_bake_merges_to_the_one_process_bundle() {
    let d = tmpdir("slurm", "local");
    let s = scene(&d);
    let want = whole(&s, &d.join("whole.relight"));
    let mut parts = vec![];
    for i in 0..3 {
        let p = d.join(format!("p{i}.relight"));
        let shard = format!("{i}/3");
        let mut a = vec!["bake", s.to_str().unwrap(), "-o", p.to_str().unwrap()];
        a.extend(["--shard", &shard]);
        a.extend(BAKE);
        let o = relight(&a);
        assert!(o.status.success(), "{}", stderr(&o));
        parts.push(p);
    }
    let merged = d.join("merged.relight");
    let arg = |p: &PathBuf| p.to_str().unwrap().to_string();
    let run = |ps: &[&PathBuf]| {
        let mut a = vec!["merge".to_string()];
        a.extend(ps.iter().map(|p| arg(p)));
        a.extend(["-o".into(), arg(&merged)]);
        relight(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let o = run(&[&parts[2], &parts[0], &parts[1]]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read(&merged).unwrap() == want);
    // A missing part is named, and nothing is written.
    std::fs::remove_file(&merged).unwrap();
    let o = run(&[&parts[0], &parts[2]]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("parts 1 of 3 are missing"),
        "{}",
        stderr(&o)
    );
    assert!(!merged.exists());
}

/// Stops the local cluster when the test ends, passed or not.
struct Cluster {
    script: PathBuf,
    dir: PathBuf,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(&self.script)
            .args(["stop", self.dir.to_str().unwrap()])
            .status();
    }
}

/// Why Slurm cannot run here, if it cannot.
fn slurm_missing() -> Option<String> {
    for tool in ["munged", "slurmctld", "slurmd", "sbatch", "sinfo"] {
        let found = std::env::var_os("PATH")
            .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()))
            || Path::new("/usr/sbin").join(tool).is_file();
        if !found {
            return Some(format!(
                "{tool} not found (Debian's slurm-wlm and munge; scripts/setup.sh installs them)"
            ));
        }
    }
    let uid = Command::new("id").arg("-u").output().ok()?;
    (String::from_utf8_lossy(&uid.stdout).trim() != "0")
        .then(|| "the local Slurm cluster needs root (slurmd starts jobs as their user)".into())
}

#[test]
fn sharded_bake_on_slurm_is_the_one_process_bundle() {
    if let Some(why) = slurm_missing() {
        relight_testdata::skip(&format!("Slurm test: {why}"));
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../deploy/slurm");
    let d = tmpdir("slurm", "cluster");
    let s = scene(&d);
    let want = whole(&s, &d.join("whole.relight"));
    let cluster = Cluster {
        script: root.join("local-cluster.sh"),
        dir: d.join("cluster"),
    };
    let o = Command::new("bash")
        .arg(&cluster.script)
        .args(["start", cluster.dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "cluster start: {}", stderr(&o));
    let submit = |out: &Path, extra: &[&str]| {
        Command::new("bash")
            .arg(root.join("submit.sh"))
            .args(["--wait", s.to_str().unwrap(), out.to_str().unwrap(), "4"])
            .args(BAKE)
            .args(extra)
            .env("SLURM_CONF", cluster.dir.join("slurm.conf"))
            .env("RELIGHT", env!("CARGO_BIN_EXE_relight"))
            .output()
            .unwrap()
    };
    let out = d.join("slurm.relight");
    let o = submit(&out, &[]);
    let log = |o: &std::process::Output| {
        format!(
            "{}{}\n{:?}",
            String::from_utf8_lossy(&o.stdout),
            stderr(o),
            std::fs::read_dir(d.join("slurm.parts")).map(|r| r.count())
        )
    };
    assert!(o.status.success(), "{}", log(&o));
    for i in 0..4 {
        assert!(d
            .join(format!("slurm.parts/part-{i}-of-4.relight"))
            .is_file());
    }
    assert!(
        std::fs::read(&out).unwrap() == want,
        "merged bundle differs"
    );
    // A failing part cancels the merge (afterok): no bundle, and a failed submission.
    let bad = d.join("bad.relight");
    let o = submit(&bad, &["--samples", "0"]);
    assert!(!o.status.success(), "{}", log(&o));
    assert!(!bad.exists());
    drop(cluster);
}
