//! Resumable bakes: a resumed bake is the uninterrupted one byte for byte; stale and foreign
//! checkpoints are refused with what to do.

use super::*;
use crate::sh::Sh;
use crate::test_scene::with_input;
use relight_bake::sh::ShBakeSettings;

fn settings() -> ShBakeSettings {
    ShBakeSettings {
        order: 3,
        samples: 32,
        seed: 4,
        ..Default::default()
    }
}

fn tmp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("relight-ckpt-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn resumable(
    radius: f32,
    out: &Path,
    chunk: usize,
    resume: bool,
) -> Result<BakeSummary, MethodError> {
    with_input(radius, |input| {
        bake_resumable::<Sh>(
            input,
            &settings(),
            &BakeContext::default(),
            out,
            chunk,
            resume,
            |_, _| {},
        )
    })
}

#[test]
fn a_resumed_bake_is_the_uninterrupted_one_byte_for_byte() {
    let d = tmp("resume");
    let whole = d.join("whole.relight");
    resumable(0.5, &whole, 40, false).unwrap();
    assert!(
        !folder(&whole).exists(),
        "the checkpoint is removed at the end"
    );
    let want = std::fs::read(&whole).unwrap();
    // An interrupted bake: some chunks written (as the bake writes them), then a resume.
    let out = d.join("resumed.relight");
    let dir = folder(&out);
    std::fs::create_dir_all(&dir).unwrap();
    let v = with_input(0.5, |i| i.scene.mesh.vertex_count());
    let n = v.div_ceil(40);
    assert!(n >= 4, "{v} vertices");
    for index in [0, 2, n - 1] {
        let part = with_input(0.5, |input| {
            bake_part::<Sh>(
                input,
                &settings(),
                Shard { index, count: n },
                &BakeContext::default(),
            )
        })
        .unwrap();
        part.write(&dir.join(format!("chunk-{index}-of-{n}.relight")))
            .unwrap();
    }
    let mut baked = vec![];
    with_input(0.5, |input| {
        bake_resumable::<Sh>(
            input,
            &settings(),
            &BakeContext::default(),
            &out,
            40,
            true,
            |i, _| baked.push(i),
        )
    })
    .unwrap();
    assert_eq!(baked, (0..n).collect::<Vec<_>>());
    assert!(std::fs::read(&out).unwrap() == want);
    assert!(!dir.exists());
}

#[test]
fn stale_and_foreign_checkpoints_are_refused_with_what_to_do() {
    let d = tmp("stale");
    let out = d.join("b.relight");
    let dir = folder(&out);
    std::fs::create_dir_all(&dir).unwrap();
    let part = with_input(0.5, |input| {
        bake_part::<Sh>(
            input,
            &settings(),
            Shard { index: 0, count: 3 },
            &BakeContext::default(),
        )
    })
    .unwrap();
    part.write(&dir.join("chunk-0-of-3.relight")).unwrap();
    // Without --resume: says what it found.
    let e = resumable(0.5, &out, 1000, false).err().unwrap().to_string();
    assert!(
        e.contains("b.relight.checkpoint") && e.contains("--resume"),
        "{e}"
    );
    // Another split.
    let e = resumable(0.5, &out, 1000, true).err().unwrap().to_string();
    assert!(e.contains("chunk-0-of-3") && e.contains("chunks"), "{e}");
    // Another scene (same split).
    let v = with_input(0.5, |i| i.scene.mesh.vertex_count());
    let e = resumable(0.45, &out, v.div_ceil(3), true)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("another scene"), "{e}");
    assert!(!out.exists());
}
