//! Sharded `sg` bakes: parts are flood-fill regions, and their merge is the whole bake byte
//! for byte (with two lobes, so the merge's region alignment has work to do).

use super::*;
use crate::sg::{Sg, SgSettings};
use relight_bake::sg::{SgBakeSettings, SgFitSettings};
use relight_scene::scene_file::SceneDesc;

/// A glossy sphere on a glossy plane: 2 direct and 1 indirect lobes on coarse cube maps, about
/// 5 regions.
fn settings(f16: bool) -> (SgSettings, bool) {
    let s = SgSettings {
        bake: SgBakeSettings {
            direct_res: 4,
            indirect_res: 2,
            indirect_paths: 4,
            max_depth: 1,
            diffuse_order: 2,
            direct_lobes: 2,
            indirect_lobes: 1,
            fit: SgFitSettings {
                regions: 5,
                max_iterations: 8,
                ..Default::default()
            },
            seed: 3,
            ..Default::default()
        },
        blend: None,
    };
    (s, f16)
}

fn desc() -> SceneDesc {
    serde_json::from_str(
        r#"{"shapes": [
              {"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "rings": 5,
               "material": {"type": "ggx_plastic", "diffuse": [0.4, 0.3, 0.2],
                            "specular": [1, 1, 1], "alpha": 0.3, "ior": 1.5}},
              {"type": "plane", "center": [0, 0, 0], "size": 3, "divisions": 3,
               "material": {"type": "ggx_conductor", "specular": [0.9, 0.8, 0.6],
                            "alpha": 0.4}}],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"origin": [0, 1.5, 3], "target": [0, 0.4, 0], "up": [0, 1, 0],
                       "fov_deg": 40, "width": 8, "height": 8}}"#,
    )
    .expect("test scene")
}

/// Run `f` with the bake input of [`desc`] and a context storing f16 or not.
fn with_input<T>(f16: bool, f: impl FnOnce(BakeInput, &BakeContext) -> T) -> T {
    let d = desc();
    let origin = Path::new("<test>");
    let scene = d.build(origin).expect("test scene");
    let input = BakeInput {
        desc: &d,
        scene: &scene,
        origin,
    };
    let ctx = BakeContext {
        f16,
        ..BakeContext::default()
    };
    f(input, &ctx)
}

/// Bake `shard` (or the whole, for `None`).
fn bake((s, f16): &(SgSettings, bool), shard: Option<Shard>) -> Result<Baked, MethodError> {
    with_input(*f16, |input, ctx| match shard {
        Some(sh) => bake_part::<Sg>(input, s, sh, ctx),
        None => Ok(Sg::bake(input, s, 0..input.scene.mesh.vertex_count(), ctx)?.into()),
    })
}

fn bytes(b: &Baked) -> Vec<u8> {
    b.to_bundle().unwrap().to_bytes()
}

/// Part bundles through their bytes (store and load), as a merge reads them.
fn parts(s: &(SgSettings, bool), n: usize) -> Vec<(PathBuf, Baked)> {
    (0..n)
        .map(|index| {
            let path = PathBuf::from(format!("part-{index}.relight"));
            let b = bake(s, Some(Shard { index, count: n })).unwrap();
            let bundle = relight_bundle::Bundle::from_bytes(&path, &bytes(&b)).unwrap();
            let back = crate::from_bundle(&bundle, &path).unwrap();
            assert!(bytes(&back) == bytes(&b), "part {index}/{n} round trip");
            (path, back)
        })
        .collect()
}

#[test]
fn merged_sg_parts_are_the_whole_bake_byte_for_byte() {
    for f16 in [false, true] {
        let s = settings(f16);
        let whole = bake(&s, None).unwrap();
        let Baked::Sg(w) = &whole else { unreachable!() };
        // The whole bake had regions to align and lobes to permute.
        assert!(w.bake.stats.flips > 0, "{:?}", w.bake.stats);
        let whole = bytes(&whole);
        for n in [1, 2, 5] {
            let mut p = parts(&s, n);
            p.reverse();
            let merged = merge(p.into_iter().map(Ok)).unwrap();
            assert!(merged.record().shard.is_none());
            assert!(bytes(&merged) == whole, "f16 {f16}, {n} parts");
        }
    }
}

#[test]
fn sg_parts_that_do_not_make_the_bake_are_refused() {
    let s = settings(false);
    // One part per region at most.
    let mesh = desc().build(Path::new("<test>")).unwrap().mesh;
    let r = relight_bake::sg::region_plan(&mesh, &s.0.bake).region_count();
    assert!(r >= 5, "{r} regions");
    let e = bake(
        &s,
        Some(Shard {
            index: 0,
            count: r + 1,
        }),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains(&format!("at most {r} parts")) && e.contains("--regions"),
        "{e}"
    );
    // Relaxation refits across region borders after the fill.
    let mut relaxed = s;
    relaxed.0.bake.fit.relax_sweeps = 1;
    let e = bake(&relaxed, Some(Shard { index: 0, count: 2 }))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("relaxation") && e.contains("cannot be split"),
        "{e}"
    );
    // Two parts renumbered: each holds the other's regions.
    let mut p = parts(&s, 3);
    let (one, two) = (p[1].1.clone(), p[2].1.clone());
    for (i, b) in [(1, two), (2, one)] {
        let Baked::Sg(mut b) = b else { unreachable!() };
        b.record.shard = Some(Shard { index: i, count: 3 });
        p[i].1 = Baked::Sg(b);
    }
    let e = merge(p.into_iter().map(Ok)).err().unwrap().to_string();
    assert!(
        e.contains("part-1") && e.contains("flood-fill regions"),
        "{e}"
    );
    // A part is not rendered.
    let part = &parts(&s, 2)[1].1;
    let e = part
        .frame(&crate::FrameSettings::default_for(crate::MethodKind::Sg))
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("part 1/2"), "{e}");
}

#[test]
fn a_resumed_sg_bake_is_the_uninterrupted_one_byte_for_byte() {
    let s = settings(true);
    let d = std::env::temp_dir().join(format!("relight-sg-ckpt-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let want = bytes(&bake(&s, None).unwrap());
    // Chunks of 1 vertex: as many chunks as regions. One chunk is there from a killed run.
    let r = with_input(true, |i, _| {
        relight_bake::sg::region_plan(&i.scene.mesh, &s.0.bake).region_count()
    });
    let out = d.join("sg.relight");
    let dir = crate::checkpoint::folder(&out);
    std::fs::create_dir_all(&dir).unwrap();
    bake(&s, Some(Shard { index: 2, count: r }))
        .unwrap()
        .write(&dir.join(format!("chunk-2-of-{r}.relight")))
        .unwrap();
    let mut chunks = vec![];
    with_input(true, |input, ctx| {
        crate::checkpoint::bake_resumable::<Sg>(input, &s.0, ctx, &out, 1, true, |i, n| {
            chunks.push((i, n))
        })
    })
    .unwrap();
    assert_eq!(chunks.len(), r);
    assert!(std::fs::read(&out).unwrap() == want);
    assert!(!dir.exists());
    std::fs::remove_dir_all(&d).unwrap();
}
