//! The `sh` method: diffuse SH PRT (Sloan, Kautz & Snyder 2002; hybrid thesis 4.2). The bake
//! is `relight_bake::sh` (what a transfer vector holds is stated there); the frame is
//! `relight_render::shade_sh` + the rasteriser. `hybrid` renders the same bake.
//!
//! Tensors: `albedo [V, 3]` (F32, per-vertex diffuse albedo, applied at render time to
//! single-channel transfer) and `transfer [V, n^2, channels]` (F32 or F16, layout of
//! [`ShTransfer`]).

pub(crate) mod frame;

pub use frame::{world_light, ShFrame, ShFrameSettings};

use crate::store::{flat3, float_tensor, unflat3, BakeRecord, BakedScene, TensorReader};
use crate::{build_caster, BakeContext, BakeInput, BakeKind, Method, MethodError};
use glam::Vec3;
use relight_bake::sh::{bake_range, ShBakeSettings, ShTransfer, ShTransferKind};
use relight_bundle::{Bundle, Tensor};
use relight_scene::error::Invalid;
use relight_sphere::sh::{sh_count, MAX_ORDER};
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

/// The `sh` method's bake verbs.
pub struct Sh;

/// The tensors of an `sh` bundle with one row per vertex ([`Sh::store`]): what a merge
/// concatenates over the parts ([`crate::shard::merge_files`]).
pub const ROW_TENSORS: [&str; 2] = ["albedo", "transfer"];

/// Everything an `sh` bundle holds.
#[derive(Clone, Debug)]
pub struct ShBaked {
    /// The scene it was baked from.
    pub scene: BakedScene,
    /// Per-vertex diffuse albedo (of the vertices baked).
    pub albedo: Vec<Vec3>,
    /// The transfer (of the vertices baked: `record.range`, else all).
    pub transfer: ShTransfer,
    /// The settings.
    pub settings: ShBakeSettings,
    /// How the bake ran.
    pub record: BakeRecord,
}

impl ShBaked {
    /// Check every invariant of the contents: transfer layout and values, one finite albedo
    /// in `[0, 1]` per baked vertex.
    ///
    /// # Errors
    /// A message naming the first violation.
    pub fn validate(&self) -> Result<(), Invalid> {
        self.validate_msg().map_err(Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        self.transfer
            .validate()
            .map_err(|e| format!("transfer: {e}"))?;
        if self.transfer.order != self.settings.order
            || self.transfer.kind != self.settings.transfer
        {
            return Err(format!(
                "transfer of order {} ({:?}) does not match the settings (order {}, {:?})",
                self.transfer.order,
                self.transfer.kind,
                self.settings.order,
                self.settings.transfer
            ));
        }
        let n = self.scene.mesh.vertex_count();
        let (start, end) = self.record.range.unwrap_or((0, n));
        if start > end || end > n || self.transfer.vertex_count != end - start {
            return Err(format!(
                "transfer of {} vertices does not match the range {start}..{end} of {n}",
                self.transfer.vertex_count
            ));
        }
        if self.albedo.len() != self.transfer.vertex_count {
            return Err(format!(
                "{} albedos for {} vertices",
                self.albedo.len(),
                self.transfer.vertex_count
            ));
        }
        if let Some(i) = self
            .albedo
            .iter()
            .position(|a| !(a.is_finite() && a.min_element() >= 0.0 && a.max_element() <= 1.0))
        {
            return Err(format!(
                "albedo {} of vertex {i} is not in [0, 1]",
                self.albedo[i]
            ));
        }
        Ok(())
    }
}

impl Method for Sh {
    const KIND: BakeKind = BakeKind::Sh;
    type Settings = ShBakeSettings;
    type Baked = ShBaked;

    fn validate(s: &ShBakeSettings) -> Result<(), MethodError> {
        Ok(s.validate()?)
    }

    fn bake(
        input: BakeInput,
        settings: &ShBakeSettings,
        range: Range<usize>,
        ctx: &BakeContext,
    ) -> Result<ShBaked, MethodError> {
        Sh::validate(settings)?;
        let t0 = Instant::now();
        let scene = input.scene;
        let n = scene.mesh.vertex_count();
        if settings.transfer == ShTransferKind::Interreflected && range != (0..n) {
            // relight_bake::sh::bake_range would trace the whole mesh for any range.
            return Err(MethodError::Settings(format!(
                "interreflected transfer cannot be baked in parts (asked vertices {}..{} of {n}): each bounce gathers the previous bounce of every vertex, so every part would trace the whole mesh; bake it whole, or shard a shadowed bake",
                range.start, range.end
            )));
        }
        let caster = build_caster(&input, ctx)?;
        let settings = ShBakeSettings {
            progress: ctx.progress,
            ..*settings
        };
        let transfer = bake_range(
            &scene.mesh,
            &scene.materials,
            caster.as_ref(),
            &settings,
            range.clone(),
        )?;
        let albedo = relight_bake::transport::vertex_albedo(&scene.mesh, &scene.materials)
            [range.clone()]
        .to_vec();
        Ok(ShBaked {
            scene: BakedScene::of(&input),
            albedo,
            transfer,
            settings: ShBakeSettings {
                progress: false,
                threads: None,
                ..settings
            },
            record: BakeRecord::new(
                caster.name(),
                t0.elapsed().as_secs_f64(),
                ctx.f16,
                &range,
                n,
            ),
        })
    }

    /// The transfer (every array a pass holds) and the albedo.
    fn row_bytes(_: BakeInput, s: &ShBakeSettings) -> u64 {
        relight_bake::sh::transfer_bytes(s, 1) as u64 + 12
    }

    fn settings_line(s: &ShBakeSettings) -> String {
        format!(
            "SH order {}, {} transfer, {} samples",
            s.order,
            s.transfer.name(),
            s.samples
        )
    }

    fn streams(s: &ShBakeSettings) -> Option<&'static str> {
        (s.transfer == ShTransferKind::Interreflected)
            .then_some("each interreflection bounce gathers the previous bounce of every vertex")
    }

    fn store(b: &ShBaked) -> Result<Bundle, MethodError> {
        let mut out = Bundle::new();
        b.scene
            .store(&mut out, Self::KIND.name(), &b.settings, &b.record)?;
        let v = b.transfer.vertex_count;
        out.insert("albedo", Tensor::from_f32(vec![v, 3], &flat3(&b.albedo)));
        let tr = &b.transfer;
        let shape = vec![v, tr.coeff_count(), tr.channels];
        out.insert("transfer", float_tensor(shape, &tr.data, b.record.f16));
        Ok(out)
    }

    fn load(b: &Bundle, path: &Path) -> Result<ShBaked, MethodError> {
        let r = TensorReader { b, path };
        let settings: ShBakeSettings = r.json("settings")?;
        let record = r.record()?;
        let scene = BakedScene::load(&r)?;
        if !(1..=MAX_ORDER).contains(&settings.order) {
            return Err(r.invalid(format!("SH order {} is out of range", settings.order)));
        }
        let v = r.rows("transfer")?;
        let albedo = unflat3(&r.f32s("albedo", &[v, 3])?);
        let kind = settings.transfer;
        let data = r.f32s("transfer", &[v, sh_count(settings.order), kind.channels()])?;
        let baked = ShBaked {
            scene,
            albedo,
            transfer: ShTransfer {
                order: settings.order,
                kind,
                vertex_count: v,
                channels: kind.channels(),
                data,
            },
            settings,
            record,
        };
        baked.validate().map_err(|e| r.invalid(e))?;
        Ok(baked)
    }
}

#[cfg(test)]
mod tests;
