//! `cuts` bundle tensors (prefixed `cuts_`), for `N` lights, `V` baked vertices and `E` cut
//! nodes in all:
//! * `cuts_dirs [N, 3]` (F32 always: the tree's centres and the cluster directions derive from
//!   them), `cuts_solid_angles [N]` (F32, or F16 with `f16`);
//! * `cuts_leaf_order [N]` (U32): the lights left to right; the complete tree's shape is fixed
//!   by `N`, so this is the whole light tree (geometric or data-driven);
//! * `cuts_offsets [V + 1]` (U32), `cuts_index [E]` (U32): vertex `v`'s cut is the post-order
//!   nodes `cuts_index[offsets[v]..offsets[v + 1]]`; leftmost leaves are the tree's, not stored;
//! * `cuts_value [E, 2]` (U8): each node's quantised mean, a little-endian u16;
//! * `cuts_capped [K]` (U32): the vertices (of the baked range) whose cut hit the cap.
//!
//! A bake of surface samples (local lights, settings `samples: "surface"`) holds, instead of
//! `cuts_dirs` and `cuts_solid_angles`: `cuts_positions [N, 3]`, `cuts_normals [N, 3]`,
//! `cuts_areas [N]` (F32 always: the areas must sum to the scene's area) and
//! `cuts_triangles [N]` (U32); the tree is rebuilt over the positions.
//!
//! **Layout version** (metadata `cuts_version`): [`CUTS_VERSION`] = 2 since surface samples;
//! bundles without the key are version 1 (environment only: their settings have no
//! `samples` and read as environment). A version above this reader's is refused by name
//! rather than misread.

use super::CutsBaked;
use crate::store::{flat3, unflat3, BakedScene, TensorReader};
use crate::MethodError;
use relight_bake::cuts::cut::VertexCuts;
use relight_bake::cuts::samples::EnvSamples;
use relight_bake::cuts::surface::SurfaceSamples;
use relight_bake::cuts::tree::LightTree;
use relight_bake::cuts::{CutsBake, CutsBakeSettings, LightSampleKind};
use relight_bundle::{Bundle, DType, Tensor};
use std::path::Path;

/// The method name in bundles.
const METHOD: &str = "cuts";

/// Layout version of `cuts` bundles written by this version (module docs).
pub const CUTS_VERSION: u32 = 2;

/// The bundle of a `cuts` bake.
///
/// # Errors
/// [`MethodError::Settings`] if the settings cannot be recorded or the cuts have more than
/// `u32::MAX` nodes in all.
pub fn store(b: &CutsBaked) -> Result<Bundle, MethodError> {
    let mut out = Bundle::new();
    b.scene.store(&mut out, METHOD, &b.settings, &b.record)?;
    out.metadata
        .insert("cuts_version".into(), CUTS_VERSION.to_string());
    let (s, c) = (&b.bake.samples, &b.bake.cuts);
    let n = b.bake.tree.light_count();
    if let Some(p) = &b.bake.surface {
        out.insert(
            "cuts_positions",
            Tensor::from_f32(vec![n, 3], &flat3(&p.positions)),
        );
        out.insert(
            "cuts_normals",
            Tensor::from_f32(vec![n, 3], &flat3(&p.normals)),
        );
        out.insert("cuts_areas", Tensor::from_f32(vec![n], &p.areas));
        out.insert("cuts_triangles", Tensor::from_u32(vec![n], &p.triangles));
    } else {
        out.insert("cuts_dirs", Tensor::from_f32(vec![n, 3], &flat3(&s.dirs)));
        out.insert(
            "cuts_solid_angles",
            crate::store::float_tensor(vec![n], &s.solid_angles, b.record.f16),
        );
    }
    out.insert(
        "cuts_leaf_order",
        Tensor::from_u32(vec![n], &b.bake.tree.lights_in_order()),
    );
    let offsets: Vec<u32> = c
        .offsets
        .iter()
        .map(|&o| u32::try_from(o))
        .collect::<Result<_, _>>()
        .map_err(|_| {
            MethodError::Settings(format!(
                "{} cut nodes in all: more than a bundle's U32 offsets hold",
                c.index.len()
            ))
        })?;
    out.insert(
        "cuts_offsets",
        Tensor::from_u32(vec![offsets.len()], &offsets),
    );
    out.insert(
        "cuts_index",
        Tensor::from_u32(vec![c.index.len()], &c.index),
    );
    out.insert(
        "cuts_value",
        Tensor {
            dtype: DType::U8,
            shape: vec![c.value.len(), 2],
            bytes: c.value.iter().flat_map(|v| v.to_le_bytes()).collect(),
        },
    );
    out.insert(
        "cuts_capped",
        Tensor::from_u32(vec![c.capped.len()], &c.capped),
    );
    Ok(out)
}

/// Read and check a `cuts` bundle read from `path` (named in errors).
///
/// # Errors
/// [`MethodError::Invalid`] or [`MethodError::Bundle`] naming the file, the tensor and the
/// problem.
pub fn load(b: &Bundle, path: &Path) -> Result<CutsBaked, MethodError> {
    let r = TensorReader { b, path };
    let method = r.meta("method")?;
    if method != METHOD {
        return Err(r.invalid(format!("holds a '{method}' bake, not '{METHOD}'")));
    }
    let version = match b.metadata.get("cuts_version") {
        None => 1,
        Some(v) => v
            .parse::<u32>()
            .map_err(|_| r.invalid(format!("metadata 'cuts_version' {v:?} is not a number")))?,
    };
    if version > CUTS_VERSION {
        return Err(r.invalid(format!(
            "cuts layout version {version} is newer than this relight's {CUTS_VERSION}: update relight to read it"
        )));
    }
    let settings: CutsBakeSettings = r.json("settings")?;
    if version < 2 && settings.samples != LightSampleKind::Environment {
        return Err(r.invalid("cuts layout version 1 holds environment samples only"));
    }
    settings
        .validate()
        .map_err(|e| r.invalid(format!("metadata 'settings': {e}")))?;
    let record = r.record()?;
    let scene = BakedScene::load(&r)?;
    let n = settings.lights as usize;
    let (samples, surface) = match settings.samples {
        LightSampleKind::Environment => {
            let dirs = unflat3(&r.f32s("cuts_dirs", &[n, 3])?);
            let solid_angles = r.f32s("cuts_solid_angles", &[n])?;
            (EnvSamples { dirs, solid_angles }, None)
        }
        LightSampleKind::Surface => {
            let surface = SurfaceSamples {
                positions: unflat3(&r.f32s("cuts_positions", &[n, 3])?),
                normals: unflat3(&r.f32s("cuts_normals", &[n, 3])?),
                areas: r.f32s("cuts_areas", &[n])?,
                triangles: r.u32s("cuts_triangles", &[n])?,
            };
            (EnvSamples::default(), Some(surface))
        }
    };
    let positions = match &surface {
        Some(s) => &s.positions,
        None => &samples.dirs,
    };
    let order = r.u32s("cuts_leaf_order", &[n])?;
    let tree = LightTree::from_leaf_order(positions, &order)
        .map_err(|e| r.invalid(format!("tensor 'cuts_leaf_order': {e}")))?;
    let rows = r.rows("cuts_offsets")?;
    let offsets = r.u32s("cuts_offsets", &[rows])?;
    let e = r.rows("cuts_index")?;
    let index = r.u32s("cuts_index", &[e])?;
    let nodes = tree.nodes().len();
    if let Some(k) = index.iter().position(|&p| p as usize >= nodes) {
        return Err(r.invalid(format!(
            "tensor 'cuts_index': node {} at entry {k} is outside the tree's {nodes} nodes",
            index[k]
        )));
    }
    let value_t = r.shaped("cuts_value", &[e, 2])?;
    if value_t.dtype != DType::U8 {
        return Err(r.invalid("tensor 'cuts_value' is not U8"));
    }
    let value = value_t
        .bytes
        .chunks_exact(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    let k = r.rows("cuts_capped")?;
    let capped = r.u32s("cuts_capped", &[k])?;
    let cuts = VertexCuts {
        offsets: offsets.iter().map(|&o| o as u64).collect(),
        leftleaf: index.iter().map(|&p| tree.node(p).leftleaf).collect(),
        index,
        value,
        capped,
    };
    let baked = CutsBaked {
        scene,
        bake: CutsBake {
            samples,
            surface,
            tree,
            cuts,
        },
        settings,
        record,
    };
    baked.validate().map_err(|e| r.invalid(e.0))?;
    Ok(baked)
}
