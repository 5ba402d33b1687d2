//! Model files (section "gltf"): a textured GLB against the same mesh as an OBJ, from the
//! file to a bundle, as `relight bake MODEL` does it.
//!
//! `--gltf FILE.glb` names the GLB; its OBJ twin is the `.obj` of the same stem beside it
//! (the test assets' folder, `target/relight-gltf-assets/<hash>/`, holds `spot.glb`, made by
//! obj2gltf, beside the `spot.obj` it was made from). Measured for each file:
//! 1. loading the model (parse, buffers, images decoded: the baseline is the OBJ's parse),
//!    median of 5;
//! 2. the whole bake as `relight bake MODEL --method cuts` runs it: the model scene
//!    ([`SceneDesc::for_model`]: load, frame, build), the cuts bake with its defaults and
//!    the bundle written (the GLB's holds its texels as well), one run each.

use super::{median_ms, Section};
use crate::{EvalError, Result};
use relight_bake::cuts::CutsBakeSettings;
use relight_method::cuts::Cuts;
use relight_method::job::{bake_to_file, BakeJob};
use relight_method::{BakeContext, BakeInput};
use relight_scene::io::{load_mesh_with, LoadOptions};
use relight_scene::scene_file::SceneDesc;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The section, for the GLB `glb` and its OBJ twin.
///
/// # Errors
/// No `--gltf` given, a twin missing, a model that cannot be read or a bake that fails.
pub(super) fn section(glb: &Option<PathBuf>, quick: bool) -> Result<Section> {
    let glb = glb.as_ref().ok_or_else(|| {
        EvalError::Options(
            "bench: section 'gltf' needs --gltf FILE.glb (with FILE.obj beside it; the test \
             assets' spot.glb is one: cargo test -p relight-cli --test gltf_assets builds them \
             under target/relight-gltf-assets/)"
                .into(),
        )
    })?;
    let obj = glb.with_extension("obj");
    if !obj.is_file() {
        return Err(EvalError::Options(format!(
            "bench: section 'gltf' compares {} with its OBJ twin {}, which is missing",
            glb.display(),
            obj.display()
        )));
    }
    let mut s = Section::new(
        "Model files: a textured GLB against the same mesh as OBJ",
        &[
            "file",
            "vertices",
            "triangles",
            "textures (Mtexels)",
            "load (ms)",
            "load / OBJ",
            "bake to bundle (s)",
            "bake / OBJ",
            "bundle (MiB)",
        ],
    );
    let tmp = std::env::temp_dir().join(format!("relight-bench-gltf-{}", std::process::id()));
    std::fs::create_dir_all(&tmp)
        .map_err(|e| EvalError::Options(format!("{}: {e}", tmp.display())))?;
    let runs = if quick { 2 } else { 5 };
    let mut base: Option<(f64, f64)> = None;
    for file in [obj.as_path(), glb.as_path()] {
        let opts = LoadOptions::default();
        let loaded = load_mesh_with(file, &opts)?;
        let texels: usize = (loaded.maps.iter())
            .flat_map(|m| m.textures().into_iter().flatten())
            .map(|t| t.width() * t.height())
            .sum();
        let load_ms = median_ms(runs, || {
            load_mesh_with(file, &opts).expect("read once already");
        });
        let (secs, bytes) = bake(file, &tmp)?;
        let (l0, b0) = *base.get_or_insert((load_ms, secs));
        s.row(vec![
            json!(file
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into())),
            json!(loaded.mesh.vertex_count()),
            json!(loaded.mesh.triangle_count()),
            json!(texels as f64 / 1e6),
            json!(load_ms),
            json!(load_ms / l0),
            json!(secs),
            json!(secs / b0),
            json!(bytes as f64 / (1 << 20) as f64),
        ]);
    }
    std::fs::remove_dir_all(&tmp).ok();
    Ok(s)
}

/// `relight bake FILE --method cuts` in-process: seconds and the bundle's size.
fn bake(file: &Path, tmp: &Path) -> Result<(f64, u64)> {
    let out = tmp.join("b.relight");
    let t0 = Instant::now();
    let (desc, _) = SceneDesc::for_model(file, None, false, &LoadOptions::default())?;
    let scene = desc.build(file)?;
    let input = BakeInput {
        desc: &desc,
        scene: &scene,
        origin: file,
    };
    let ctx = BakeContext {
        backend: relight_scene::accel::Backend::available()[0],
        f16: false,
        progress: false,
    };
    let job = BakeJob {
        shard: None,
        checkpoint_vertices: None,
        memory_limit: None,
        resume: false,
        resident: 0,
    };
    bake_to_file::<Cuts>(
        input,
        &CutsBakeSettings::default(),
        &job,
        &ctx,
        &out,
        |_| {},
    )?;
    let secs = t0.elapsed().as_secs_f64();
    let bytes = std::fs::metadata(&out).map_or(0, |m| m.len());
    Ok((secs, bytes))
}
