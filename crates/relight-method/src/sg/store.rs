//! `sg` bundle tensors and metadata (docs/BUNDLE.md):
//! * `sg_direct [V, views, N, 7]`, `sg_indirect [V, views, M, 7]` (absent when `M = 0`):
//!   per lobe axis x, y, z, sharpness, amplitude r, g, b (F32 or F16; the number of views
//!   `10 f^2 + 2` gives the icosahedron's frequency `f`);
//! * `sg_diffuse [V, n^2, 1]`: the diffuse SH transfer;
//! * `sg_vertex_material [V]` (U32) into the metadata `sg_materials` (JSON list);
//! * metadata `sg_stats`: the fit's statistics.
//!
//! Bundles from before schema 2 recorded the settings flat with the fit's fields prefixed
//! `fit_` and the blend as a description string; [`migrate_settings`] reads them.

use super::{SgBaked, SgPartRows, SgSettings};
use crate::store::{float_tensor, json, BakedScene, TensorReader};
use crate::{BakeKind, MethodError};
use glam::Vec3;
use relight_bake::sg::{SgBake, SgFitStats, SgLobes};
use relight_bake::sh::{ShTransfer, ShTransferKind};
use relight_bundle::{Bundle, DType, Tensor};
use relight_scene::material::Material;
use relight_sphere::sg::SgLobe;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::path::Path;

/// Floats per stored lobe: axis x, y, z, sharpness, amplitude r, g, b.
pub const SG_LOBE_FLOATS: usize = 7;

/// `SgFitStats` as recorded in a bundle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct RecordedStats {
    mean_relative_error: [f64; 2],
    iterations: u64,
    flips: u64,
    flips_after_relaxation: u64,
}

fn lobes_flat(l: &SgLobes) -> Vec<f32> {
    l.lobes
        .iter()
        .flat_map(|g| {
            let (a, m) = (g.axis, g.amplitude);
            [a.x, a.y, a.z, g.sharpness, m.x, m.y, m.z]
        })
        .collect()
}

/// The bundle of an `sg` bake.
pub(super) fn store(b: &SgBaked) -> Result<Bundle, MethodError> {
    let mut out = Bundle::new();
    b.scene
        .store(&mut out, BakeKind::Sg.name(), &b.settings, &b.record)?;
    let st = &b.bake.stats;
    let stats = RecordedStats {
        mean_relative_error: st.mean_relative_error,
        iterations: st.iterations,
        flips: st.flips,
        flips_after_relaxation: st.flips_after_relaxation,
    };
    out.metadata.insert("sg_stats".into(), json(&stats)?);
    // Distinct per-vertex materials (one per vertex only when blended).
    let v = b
        .part
        .as_ref()
        .map_or(b.scene.mesh.vertex_count(), |p| p.vertices.len());
    let mut palette: Vec<Material> = vec![];
    let mut ids = Vec::with_capacity(v);
    for mat in &b.bake.materials {
        let id = match palette.iter().position(|p| p == mat) {
            Some(i) => i,
            None => {
                palette.push(*mat);
                palette.len() - 1
            }
        };
        ids.push(id as u32);
    }
    out.metadata.insert("sg_materials".into(), json(&palette)?);
    out.insert("sg_vertex_material", Tensor::from_u32(vec![v], &ids));
    // A part keeps f32 whatever the bake's precision: the merge aligns regions on the exact
    // lobes, as one process does, and only the merged bundle is rounded.
    let f16 = b.record.f16 && b.part.is_none();
    if let Some(p) = &b.part {
        out.insert("sg_part_vertices", Tensor::from_u32(vec![v], &p.vertices));
        let views = b.bake.direct.view_count;
        out.insert(
            "sg_part_errors",
            Tensor::from_f32(vec![p.errors.len(), v, views], &p.errors.concat()),
        );
    }
    for (name, l) in [
        ("sg_direct", Some(&b.bake.direct)),
        ("sg_indirect", b.bake.indirect.as_ref()),
    ] {
        if let Some(l) = l {
            let shape = vec![v, l.view_count, l.lobe_count, SG_LOBE_FLOATS];
            out.insert(name, float_tensor(shape, &lobes_flat(l), f16));
        }
    }
    let d = &b.bake.diffuse;
    out.insert(
        "sg_diffuse",
        float_tensor(vec![v, d.coeff_count(), 1], &d.data, f16),
    );
    Ok(out)
}

/// The settings of a bundle from before schema 2 (flat, fit fields prefixed `fit_`, the blend
/// a description, the record's fields mixed in) in today's form. The old blend description
/// cannot be turned back into a material; the per-vertex materials it made are in
/// `sg_vertex_material`, so it is dropped.
pub(super) fn migrate_settings(old: &Map<String, Value>) -> Value {
    let mut new = Map::new();
    let mut fit = Map::new();
    for (k, v) in old {
        match k.strip_prefix("fit_") {
            Some(f) => {
                fit.insert(f.to_string(), v.clone());
            }
            None if k == "blend" => {}
            None => {
                new.insert(k.clone(), v.clone());
            }
        }
    }
    new.insert("fit".into(), Value::Object(fit));
    Value::Object(new)
}

/// The icosahedron frequency `f` of `views = 10 f^2 + 2` views, if there is one.
fn view_frequency(views: usize) -> Option<usize> {
    (1..=64).find(|f| 10 * f * f + 2 == views)
}

/// Read and check an `sg` bundle read from `path`.
pub(super) fn load(b: &Bundle, path: &Path) -> Result<SgBaked, MethodError> {
    let r = TensorReader { b, path };
    let settings: SgSettings = if r.is_legacy() {
        let old: Map<String, Value> = r.json("settings")?;
        serde_json::from_value(migrate_settings(&old)).map_err(|e| {
            r.invalid(format!(
                "metadata 'settings' (before schema 2) is not valid: {e}"
            ))
        })?
    } else {
        r.json("settings")?
    };
    let record = r.record()?;
    let scene = BakedScene::load(&r)?;
    let palette: Vec<Material> = r.json("sg_materials")?;
    let stats: RecordedStats = r.json("sg_stats")?;
    let part_vertices = match record.shard {
        None => None,
        Some(_) => {
            let t = b.tensor(path, "sg_part_vertices")?;
            let [n] = t.shape[..] else {
                return Err(r.invalid(format!(
                    "tensor 'sg_part_vertices' has shape {:?}, expected one dimension",
                    t.shape
                )));
            };
            if n > scene.mesh.vertex_count() {
                return Err(r.invalid(format!(
                    "a part of {n} vertices of a mesh of {}",
                    scene.mesh.vertex_count()
                )));
            }
            Some(r.u32s("sg_part_vertices", &[n])?)
        }
    };
    let v = part_vertices
        .as_ref()
        .map_or(scene.mesh.vertex_count(), Vec::len);
    let vertex_materials = r
        .u32s("sg_vertex_material", &[v])?
        .iter()
        .map(|&i| {
            palette.get(i as usize).copied().ok_or_else(|| {
                r.invalid(format!(
                    "vertex material {i} out of range ({} in sg_materials)",
                    palette.len()
                ))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let views = b
        .tensor(path, "sg_direct")?
        .shape
        .get(1)
        .copied()
        .unwrap_or(0);
    let f = view_frequency(views).ok_or_else(|| {
        r.invalid(format!(
            "tensor 'sg_direct' has {views} views, not 10 f^2 + 2 for a frequency f in 1..=64"
        ))
    })?;
    let lobes = |name: &str, count: usize| -> Result<SgLobes, MethodError> {
        let tensor = b.tensor(path, name)?;
        let raw = r.f32s(name, &[v, views, count, SG_LOBE_FLOATS])?;
        let renormalise = tensor.dtype == DType::F16;
        let lobes = raw
            .chunks_exact(SG_LOBE_FLOATS)
            .map(|c| {
                let axis = Vec3::new(c[0], c[1], c[2]);
                let len = axis.length();
                SgLobe {
                    axis: if renormalise && len > 0.0 {
                        axis / len
                    } else {
                        axis
                    },
                    sharpness: c[3],
                    amplitude: Vec3::new(c[4], c[5], c[6]),
                }
            })
            .collect();
        Ok(SgLobes {
            lobe_count: count,
            view_count: views,
            lobes,
        })
    };
    let s = &settings.bake;
    let direct = lobes("sg_direct", s.direct_lobes)?;
    let indirect = match s.indirect_lobes {
        0 => None,
        n => Some(lobes("sg_indirect", n)?),
    };
    let order = s.diffuse_order;
    if !(1..=relight_sphere::sh::MAX_ORDER).contains(&order) {
        return Err(r.invalid(format!("diffuse SH order {order} is out of range")));
    }
    let n2 = relight_sphere::sh::sh_count(order);
    let diffuse = ShTransfer {
        order,
        kind: ShTransferKind::Shadowed,
        vertex_count: v,
        channels: 1,
        data: r.f32s("sg_diffuse", &[v, n2, 1])?,
    };
    let part = match part_vertices {
        None => None,
        Some(vertices) => {
            let comps = 1 + usize::from(s.indirect_lobes > 0);
            let errors = r.f32s("sg_part_errors", &[comps, v, views])?;
            Some(SgPartRows {
                vertices,
                errors: (0..comps)
                    .map(|c| errors[c * v * views..(c + 1) * v * views].to_vec())
                    .collect(),
            })
        }
    };
    let baked = SgBaked {
        part,
        scene,
        bake: SgBake {
            view_frequency: f,
            direct,
            indirect,
            diffuse,
            materials: vertex_materials,
            stats: SgFitStats {
                mean_relative_error: stats.mean_relative_error,
                iterations: stats.iterations,
                flips: stats.flips,
                flips_after_relaxation: stats.flips_after_relaxation,
            },
            kernel: settings.bake.fit.lobe_kernel.kernel(),
            domain: settings.bake.fit.lobe_domain,
            horizon_deg: settings.bake.horizon_deg,
            lobe_order: settings.bake.fit.lobe_order,
        },
        settings,
        record,
    };
    baked.validate().map_err(|e| r.invalid(e))?;
    Ok(baked)
}
