//! Sharded bakes (sections "Sharded bake"): N parts baked one after the other and merged,
//! against the one-process bake of the same scene and seed measured in the same run; for `sh`
//! (vertex ranges) and `sg` (flood-fill regions).

use super::Section;
use crate::{EvalError, Result};
use relight_bake::sg::{SgBakeSettings, SgFitSettings};
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_method::sg::{Sg, SgSettings};
use relight_method::sh::Sh;
use relight_method::shard::{bake_part, merge, Shard};
use relight_method::{BakeContext, BakeInput, Baked, Method};
use relight_scene::scene_file::SceneDesc;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// The sections (each given to `push` when measured, so that its peak memory is its own), on
/// `bake_mesh`, else `<data>/data/meshes/bunny_watertight.obj`, else a
/// procedural sphere, on a plane: a shadowed order-4 `sh` bake (1024 samples, 128 with
/// `quick`), and an `sg` bake of one direct lobe on 6x8x8 cube maps with SH order 3 (20 fit
/// iterations, 4 with `quick`), each split into N = 1, 2 and 4 parts. Per N: the parts' total and slowest time (on a cluster the parts run at once,
/// so the wall time is the slowest part plus the merge), the merge (checks + serialising the
/// bundle, without disk IO), the overhead (parts + merge) / one process, and whether the
/// merged bundle is byte-identical to the one-process one.
///
/// # Errors
/// A mesh that cannot be read, or a bake that fails.
pub(super) fn section(
    bake_mesh: &Option<PathBuf>,
    data: &Option<PathBuf>,
    quick: bool,
    push: &mut dyn FnMut(Section),
) -> Result<()> {
    let path = bake_mesh.clone().or_else(|| {
        data.as_ref()
            .map(|d| d.join("data/meshes/bunny_watertight.obj"))
            .filter(|p| p.is_file())
    });
    // The mesh is named relative to a scene "file" in its folder (the path rule).
    let (origin, shape) = match &path {
        Some(p) => (
            p.with_file_name("<bench>.json"),
            json!({"type": "mesh", "file": p.file_name().map(|f| f.to_string_lossy()),
                   "fit": {"base": [0, 0, 0], "height": 1.0}}),
        ),
        None => (
            PathBuf::from("<bench>"),
            json!({"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "rings": 128}),
        ),
    };
    let mut desc: SceneDesc = serde_json::from_value(json!({
        "shapes": [shape, {"type": "plane", "center": [0, 0, 0], "size": 4, "divisions": 8}],
        "environment": {"type": "constant", "radiance": [1, 1, 1]},
        "camera": {"origin": [0, 1, 3], "target": [0, 0.5, 0], "up": [0, 1, 0],
                   "fov_deg": 40, "width": 64, "height": 48}
    }))
    .map_err(|e| EvalError::Options(format!("bench scene: {e}")))?;
    if let Some(dir) = path.as_ref().and_then(|p| p.parent()) {
        desc.resolve_paths(dir);
    }
    let scene = desc.build(&origin)?;
    let input = BakeInput {
        desc: &desc,
        scene: &scene,
        origin: &origin,
    };
    let name = path
        .as_ref()
        .map_or("procedural sphere".into(), |p| p.display().to_string());
    let sh = ShBakeSettings {
        order: 4,
        samples: if quick { 128 } else { 1024 },
        seed: 1,
        transfer: ShTransferKind::Shadowed,
        ..Default::default()
    };
    let sg = SgSettings {
        bake: SgBakeSettings {
            direct_res: 8,
            indirect_lobes: 0,
            diffuse_order: 3,
            fit: SgFitSettings {
                max_iterations: if quick { 4 } else { 20 },
                ..Default::default()
            },
            ..Default::default()
        },
        blend: None,
    };
    push(measure::<Sh>(
        input,
        &sh,
        format!(
            "Sharded bake: {name} ({} vertices), SH order 4, {} samples, shadowed",
            scene.mesh.vertex_count(),
            sh.samples
        ),
    )?);
    push(measure::<Sg>(
        input,
        &sg,
        format!(
            "Sharded sg bake: {name} ({} vertices, {} flood-fill regions), 1 direct lobe, 6x8x8, SH order 3",
            scene.mesh.vertex_count(),
            relight_bake::sg::region_plan(&scene.mesh, &sg.bake).region_count()
        ),
    )?);
    Ok(())
}

/// One method's section (see [`section`]).
fn measure<M: Method>(input: BakeInput, settings: &M::Settings, title: String) -> Result<Section>
where
    M::Baked: Into<Baked>,
{
    let ctx = BakeContext::default();
    let t0 = Instant::now();
    let v = input.scene.mesh.vertex_count();
    let whole: Baked = M::bake(input, settings, 0..v, &ctx)?.into();
    let whole_s = t0.elapsed().as_secs_f64();
    let whole_bytes = whole.to_bundle()?.to_bytes();
    drop(whole);
    let mut sec = Section::new(
        format!("{title}; one process: {whole_s:.2} s"),
        &[
            "parts N",
            "parts total (s)",
            "slowest part (s)",
            "merge (s)",
            "(parts + merge) / one process",
            "identical bytes",
        ],
    );
    for count in [1, 2, 4] {
        let mut parts = vec![];
        let (mut total, mut slowest) = (0.0f64, 0.0f64);
        for index in 0..count {
            let t = Instant::now();
            let p = bake_part::<M>(input, settings, Shard { index, count }, &ctx)?;
            let s = t.elapsed().as_secs_f64();
            (total, slowest) = (total + s, slowest.max(s));
            parts.push(Ok((PathBuf::from(format!("part-{index}")), p)));
        }
        let t = Instant::now();
        let merged = merge(parts)?.to_bundle()?.to_bytes();
        let merge_s = t.elapsed().as_secs_f64();
        sec.row(vec![
            json!(count),
            json!(total),
            json!(slowest),
            json!(merge_s),
            json!((total + merge_s) / whole_s),
            json!(if merged == whole_bytes { "yes" } else { "NO" }),
        ]);
    }
    Ok(sec)
}
