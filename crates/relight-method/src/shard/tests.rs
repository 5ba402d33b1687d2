//! Sharded bakes: the partition, merges byte-identical to the whole bake, and every way a set
//! of parts can fail to make one bake.

use super::*;
use crate::sh::Sh;
use crate::test_scene::with_input;
use relight_bake::sh::{ShBakeSettings, ShTransferKind};

fn settings(transfer: ShTransferKind, seed: u64) -> ShBakeSettings {
    ShBakeSettings {
        order: 3,
        samples: 32,
        seed,
        transfer,
        ..Default::default()
    }
}

/// Bake `shard` (or the whole, for `None`) of the scene with `radius`.
fn bake(radius: f32, s: &ShBakeSettings, shard: Option<Shard>) -> Result<Baked, MethodError> {
    with_input(radius, |input| {
        let ctx = BakeContext::default();
        match shard {
            Some(sh) => bake_part::<Sh>(input, s, sh, &ctx),
            None => Ok(Sh::bake(input, s, 0..input.scene.mesh.vertex_count(), &ctx)?.into()),
        }
    })
}

fn parts(radius: f32, s: &ShBakeSettings, n: usize) -> Vec<(PathBuf, Baked)> {
    (0..n)
        .map(|index| {
            let b = bake(radius, s, Some(Shard { index, count: n })).unwrap();
            (PathBuf::from(format!("part-{index}.relight")), b)
        })
        .collect()
}

fn bytes(b: &Baked) -> Vec<u8> {
    b.to_bundle().unwrap().to_bytes()
}

#[test]
fn parts_tile_the_vertices_in_order() {
    for v in [1usize, 7, 64, 1000, 1 << 20] {
        for n in [1usize, 2, 3, 7, 64] {
            if n > v {
                continue;
            }
            let mut next = 0;
            for index in 0..n {
                let r = Shard { index, count: n }.range(v);
                assert_eq!(r.start, next, "v {v} n {n} part {index}");
                // Balanced: part sizes differ by at most one vertex.
                assert!(r.len() == v / n || r.len() == v / n + 1, "{r:?}");
                next = r.end;
            }
            assert_eq!(next, v);
        }
    }
}

#[test]
fn shard_text_is_parsed_or_refused_by_name() {
    assert_eq!(Shard::parse("2/4").unwrap(), Shard { index: 2, count: 4 });
    for bad in ["4/4", "1/0", "-1/3", "a/3", "3", "1/99999999", ""] {
        let e = Shard::parse(bad).unwrap_err().to_string();
        assert!(e.contains("--shard") && e.contains("I/N"), "{bad}: {e}");
    }
}

#[test]
fn merged_parts_are_the_whole_bake_byte_for_byte() {
    for transfer in [ShTransferKind::Unshadowed, ShTransferKind::Shadowed] {
        let s = settings(transfer, 5);
        let whole = bytes(&bake(0.5, &s, None).unwrap());
        for n in [1, 2, 3, 5] {
            let mut p = parts(0.5, &s, n);
            // The order the parts are given in does not matter.
            p.reverse();
            let merged = merge(p.into_iter().map(Ok)).unwrap();
            assert_eq!(merged.record().shard, None);
            assert!(bytes(&merged) == whole, "{transfer:?}, {n} parts");
        }
    }
}

#[test]
fn part_bundles_round_trip_and_are_not_rendered() {
    let s = settings(ShTransferKind::Shadowed, 1);
    let p = parts(0.5, &s, 3);
    let path = Path::new("mem.relight");
    let back = crate::from_bundle(
        &relight_bundle::Bundle::from_bytes(path, &bytes(&p[1].1)).unwrap(),
        path,
    )
    .unwrap();
    assert_eq!(back.record().shard, Some(Shard { index: 1, count: 3 }));
    let e = back
        .frame(&crate::FrameSettings::default_for(crate::MethodKind::Sh))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("part bundle"), "{e}");
}

/// `merge(parts)`'s error, which must name `who` and contain `what`.
fn refused(parts: Vec<(PathBuf, Baked)>, who: &str, what: &str) {
    let e = merge(parts.into_iter().map(Ok))
        .expect_err("refused")
        .to_string();
    assert!(e.contains(who) && e.contains(what), "{e}");
}

#[test]
fn parts_of_different_bakes_are_refused_naming_the_part() {
    let s = settings(ShTransferKind::Shadowed, 1);
    let p = parts(0.5, &s, 3);
    // Missing and repeated parts.
    refused(p[..2].to_vec(), "part-0", "parts 2 of 3 are missing");
    let mut twice = p.clone();
    twice[2] = (PathBuf::from("again.relight"), p[1].1.clone());
    refused(twice, "again.relight", "given twice");
    // Another seed, another scene, another split.
    let mut seed = p.clone();
    seed[1].1 = parts(0.5, &settings(ShTransferKind::Shadowed, 2), 3)[1]
        .1
        .clone();
    refused(seed, "part-1", "settings (or seed)");
    let mut scene = p.clone();
    scene[2].1 = parts(0.45, &s, 3)[2].1.clone();
    refused(scene, "part-2", "scene");
    let mut split = p.clone();
    split[2].1 = parts(0.5, &s, 4)[3].1.clone();
    refused(split, "part-2", "split differently");
    // A whole bake is not a part.
    let mut whole = p;
    whole[0].1 = bake(0.5, &s, None).unwrap();
    refused(whole, "part-0", "not a part");
    refused(vec![], "merge", "no parts");
}

#[test]
fn methods_that_cannot_be_split_say_why() {
    let s = settings(ShTransferKind::Interreflected, 1);
    let e = bake(0.5, &s, Some(Shard { index: 0, count: 2 }))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("interreflected") && e.contains("every vertex"),
        "{e}"
    );
    // One part of one is the whole bake (interreflected too), once merged.
    let one = bake(0.5, &s, Some(Shard { index: 0, count: 1 })).unwrap();
    let one = merge([Ok((PathBuf::from("one.relight"), one))]).unwrap();
    assert!(bytes(&one) == bytes(&bake(0.5, &s, None).unwrap()));
    let e = bake(
        0.5,
        &settings(ShTransferKind::Shadowed, 1),
        Some(Shard {
            index: 0,
            count: 1 << 16,
        }),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("at most") && e.contains("one per vertex"), "{e}");
}

#[test]
fn part_numbers_beyond_the_limit_are_refused_on_load() {
    let s = settings(ShTransferKind::Shadowed, 1);
    let good = parts(0.5, &s, 2)[1].1.to_bundle().unwrap();
    let path = Path::new("hostile.relight");
    for bad in [
        r#"{"index":1,"count":18446744073709551615}"#,
        r#"{"index":2,"count":2}"#,
    ] {
        let mut b = good.clone();
        let rec = b.metadata["record"].replace(r#"{"index":1,"count":2}"#, bad);
        assert_ne!(rec, b.metadata["record"], "the test changes the record");
        b.metadata.insert("record".into(), rec);
        let e = crate::from_bundle(&b, path).err().unwrap().to_string();
        assert!(
            e.contains("hostile.relight") && e.contains("part number"),
            "{e}"
        );
    }
}

#[test]
fn corrupt_part_and_merged_bundles_are_detected() {
    let s = settings(ShTransferKind::Shadowed, 1);
    let p = parts(0.5, &s, 2);
    let merged = merge(p.clone().into_iter().map(Ok)).unwrap();
    let path = Path::new("c.relight");
    for b in [&p[0].1, &p[1].1, &merged] {
        let bytes = bytes(b);
        // Every 97th byte (all of the header and a spread of the data): each flip is caught
        // by the header or data CRC-32, and each truncation by the layout checks.
        for at in (0..bytes.len()).step_by(97) {
            let mut c = bytes.clone();
            c[at] ^= 0x20;
            assert!(
                relight_bundle::Bundle::from_bytes(path, &c).is_err(),
                "flip at {at}"
            );
            assert!(relight_bundle::Bundle::from_bytes(path, &bytes[..at]).is_err());
        }
    }
}

#[test]
fn streamed_merges_of_part_files_are_the_whole_bake_byte_for_byte() {
    let d = std::env::temp_dir().join(format!("relight-merge-files-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let s = settings(ShTransferKind::Shadowed, 6);
    let whole = bytes(&bake(0.5, &s, None).unwrap());
    let mut paths = vec![];
    for (path, b) in parts(0.5, &s, 3) {
        let p = d.join(path);
        b.write(&p).unwrap();
        paths.push(p);
    }
    paths.rotate_left(1);
    let out = d.join("merged.relight");
    let summary = merge_files(&paths, &out).unwrap();
    assert!(std::fs::read(&out).unwrap() == whole);
    assert_eq!(
        summary.vertices,
        with_input(0.5, |i| i.scene.mesh.vertex_count())
    );
    assert!(summary.record.shard.is_none() && summary.record.range.is_none());
    // A missing part: refused by name, nothing written.
    let out2 = d.join("not.relight");
    let e = merge_files(&paths[..2], &out2).unwrap_err().to_string();
    assert!(e.contains("missing"), "{e}");
    assert!(!out2.exists());
    std::fs::remove_dir_all(&d).unwrap();
}
