//! `vmf` bundle tensors (prefixed `vmf_`; docs/BUNDLE.md), for `V` baked vertices and `S`
//! slices in all:
//! * `vmf_levels [V]` (U32): the icosahedral level of each vertex's views; vertex `x` has
//!   one slice per view of its level (`relight_bake::vmf::views_of_level`, in that order), so
//!   its slices start at the sum of the view counts of the vertices before it (no offsets are
//!   stored: they follow from the levels);
//! * `vmf_lobes [S, 6, 7]` (F32, or F16 with `f16`): per slice, its lobes in the order
//!   (diffuse term at the point, glossy term) x (direct, indirect diffuse, indirect glossy),
//!   each as axis x, y, z (world frame, towards the light), `kappa`, amplitude r, g, b (the
//!   lobe's integral, eq. 4-5 and 15);
//! * `vmf_diffuse_sh [V, n^2, 3]` (F32, or F16), only when the settings'
//!   `diffuse_sh_order` `n` is above 0: per vertex, the diffuse term's SH transfer
//!   (`relight_bake::vmf::diffuse_sh`; an all-zero row: the vertex keeps its diffuse lobes).
//!
//! Version and checksums are the bundle layer's (`relight_bundle`). An f16 bundle rounds every
//! value: the reader renormalises axes within 1 % of unit length and brings a `kappa` within
//! 0.1 % above `kappa_max` back to it; anything further is refused as invalid.

use super::VmfBaked;
use crate::store::{float_tensor, BakedScene, TensorReader};
use crate::{BakeKind, MethodError};
use glam::Vec3;
use relight_bake::vmf::{view_counts, TransferSlice, VmfBake, VmfBakeSettings};
use relight_bundle::{Bundle, Tensor};
use relight_sphere::vmf::VmfLobe;
use std::path::Path;

/// Floats per stored lobe: axis x, y, z, kappa, amplitude r, g, b.
pub const VMF_LOBE_FLOATS: usize = 7;

/// Lobes per slice: 2 terms x 3 classes.
const LOBES: usize = 6;

/// The bundle of a `vmf` bake.
///
/// # Errors
/// [`MethodError::Settings`] if the settings cannot be recorded.
pub fn store(b: &VmfBaked) -> Result<Bundle, MethodError> {
    let mut out = Bundle::new();
    b.scene
        .store(&mut out, BakeKind::Vmf.name(), &b.settings, &b.record)?;
    let levels: Vec<u32> = b.bake.levels.iter().map(|&l| u32::from(l)).collect();
    out.insert("vmf_levels", Tensor::from_u32(vec![levels.len()], &levels));
    let flat: Vec<f32> = b
        .bake
        .slices
        .iter()
        .flat_map(|s| s.lobes.iter().flatten())
        .flat_map(|l| {
            let (a, m) = (l.axis, l.amplitude);
            [a.x, a.y, a.z, l.kappa, m.x, m.y, m.z]
        })
        .collect();
    out.insert(
        "vmf_lobes",
        float_tensor(
            vec![b.bake.slices.len(), LOBES, VMF_LOBE_FLOATS],
            &flat,
            b.record.f16,
        ),
    );
    let n = b.bake.diffuse_sh_len();
    if b.settings.diffuse_sh_order > 0 {
        let flat: Vec<f32> = b
            .bake
            .diffuse_sh
            .iter()
            .flat_map(|c| c.to_array())
            .collect();
        out.insert(
            "vmf_diffuse_sh",
            float_tensor(vec![levels.len(), n, 3], &flat, b.record.f16),
        );
    }
    Ok(out)
}

/// Read and check a `vmf` bundle read from `path` (named in errors).
///
/// # Errors
/// [`MethodError::Invalid`] or [`MethodError::Bundle`] naming the file, the tensor and the
/// problem; a bundle of another method names that method.
pub fn load(b: &Bundle, path: &Path) -> Result<VmfBaked, MethodError> {
    let r = TensorReader { b, path };
    let method = r.meta("method")?;
    if method != BakeKind::Vmf.name() {
        return Err(r.invalid(format!(
            "holds a '{method}' bake, not a 'vmf' bake (render it with --method {method}, or bake the scene with --method vmf)"
        )));
    }
    let settings: VmfBakeSettings = r.json("settings")?;
    settings
        .validate()
        .map_err(|e| r.invalid(format!("metadata 'settings': {e}")))?;
    let record = r.record()?;
    let scene = BakedScene::load(&r)?;
    let v = r.rows("vmf_levels")?;
    let raw = r.u32s("vmf_levels", &[v])?;
    let counts = view_counts();
    let mut levels = Vec::with_capacity(v);
    let mut offsets = Vec::with_capacity(v + 1);
    offsets.push(0usize);
    for (x, &l) in raw.iter().enumerate() {
        let Some(&n) = counts.get(l as usize) else {
            return Err(r.invalid(format!(
                "tensor 'vmf_levels': level {l} of vertex {x} is above {}",
                counts.len() - 1
            )));
        };
        levels.push(l as u8);
        offsets.push(offsets[x] + n);
    }
    let s = offsets[v];
    let flat = r.f32s("vmf_lobes", &[s, LOBES, VMF_LOBE_FLOATS])?;
    let kmax = settings.kappa_max;
    let lobe = |c: &[f32]| {
        let mut axis = Vec3::new(c[0], c[1], c[2]);
        let mut kappa = c[3];
        if record.f16 {
            if (axis.length() - 1.0).abs() < 1e-2 {
                axis = axis.normalize();
            }
            if kappa > kmax && kappa <= kmax * 1.001 {
                kappa = kmax;
            }
        }
        VmfLobe {
            axis,
            kappa,
            amplitude: Vec3::new(c[4], c[5], c[6]),
        }
    };
    let slices = flat
        .chunks_exact(LOBES * VMF_LOBE_FLOATS)
        .map(|c| {
            let l = |k: usize| lobe(&c[k * VMF_LOBE_FLOATS..(k + 1) * VMF_LOBE_FLOATS]);
            TransferSlice {
                lobes: [[l(0), l(1), l(2)], [l(3), l(4), l(5)]],
            }
        })
        .collect();
    let diffuse_sh = if settings.diffuse_sh_order > 0 {
        let n = relight_sphere::sh::sh_count(settings.diffuse_sh_order as usize);
        r.f32s("vmf_diffuse_sh", &[v, n, 3])?
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    } else {
        vec![]
    };
    let baked = VmfBaked {
        scene,
        bake: VmfBake {
            settings,
            levels,
            offsets,
            slices,
            diffuse_sh,
        },
        settings,
        record,
    };
    baked.validate().map_err(|e| r.invalid(e.0))?;
    Ok(baked)
}
