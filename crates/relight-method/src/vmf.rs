//! The `vmf` method (Laurijssen & Dutré 2009, "Adaptive Precomputation of Glossy
//! Interreflections"): the bake is `relight_bake::vmf` (per vertex, transfer slices
//! of one vMF lobe per light-path class for the views of an icosahedral level, sections 3-5),
//! the frame `relight_render::shade_vmf` (eq. 6 interpolation across views and triangles,
//! lookup in a vMF-prefiltered environment chain whose kappa doubles per level, section
//! 6.2).
//!
//! Parts: vertices are independent (each slice is seeded by its vertex and view), so a part
//! is a vertex range and the merge concatenates rows ([`crate::shard`]).

mod frame;
mod store;

pub use frame::{VmfFrame, VmfFrameSettings};
pub use store::{load, store, VMF_LOBE_FLOATS};

use crate::store::{BakeRecord, BakedScene};
use crate::{build_caster, BakeContext, BakeInput, BakeKind, Method, MethodError};
use relight_bake::vmf::{view_counts, TransferSlice, VmfBake, VmfBakeSettings};
use relight_bundle::Bundle;
use relight_scene::error::Invalid;
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

/// The `vmf` method's bake verbs.
pub struct Vmf;

impl Method for Vmf {
    const KIND: BakeKind = BakeKind::Vmf;
    type Settings = VmfBakeSettings;
    type Baked = VmfBaked;

    fn validate(s: &VmfBakeSettings) -> Result<(), MethodError> {
        Ok(s.validate()?)
    }

    /// The slices of the finest level a vertex may have, in memory.
    fn row_bytes(_: BakeInput, s: &VmfBakeSettings) -> u64 {
        let (_, hi) = s.level_range();
        let views = view_counts()[hi.min(relight_bake::vmf::bake::MAX_VIEW_LEVEL) as usize];
        (views * std::mem::size_of::<TransferSlice>()) as u64 + 1
    }

    fn settings_line(s: &VmfBakeSettings) -> String {
        format!(
            "vmf, view level {}, {} paths per slice, {} bounce(s)",
            s.view_level, s.paths, s.max_bounces
        )
    }

    fn streams(_: &VmfBakeSettings) -> Option<&'static str> {
        Some("the vmf merge concatenates the parts' slices in memory (not streamed yet)")
    }

    /// Vertices are independent: a range bakes exactly those rows of the whole bake. With the
    /// adaptive spatial refinement (`spatial_threshold > 0`, paper section 4.3) the bake
    /// refines the mesh, which becomes the bundle's mesh; it couples neighbouring vertices, so
    /// only a whole bake is accepted.
    fn bake(
        input: BakeInput,
        settings: &VmfBakeSettings,
        range: Range<usize>,
        ctx: &BakeContext,
    ) -> Result<VmfBaked, MethodError> {
        Vmf::validate(settings)?;
        // Views are parametrised in each vertex's frame of its normal alone (section 4.2), so
        // an anisotropic BRDF, whose frame follows a tangent, is refused rather than baked in
        // another frame than the path tracer's.
        if let Some(i) = (input.scene.materials.iter())
            .position(|m| matches!(m, relight_scene::material::Material::Ward { .. }))
        {
            return Err(MethodError::Settings(format!(
                "material {i} is Ward (anisotropic): the vmf bake parametrises views by the normal alone; render Ward with --method cuts (or sg)"
            )));
        }
        let n = input.scene.mesh.vertex_count();
        let t0 = Instant::now();
        let caster = build_caster(&input, ctx)?;
        let run = VmfBakeSettings {
            progress: ctx.progress,
            threads: None,
            ..*settings
        };
        let mut scene = BakedScene::of(&input);
        let mut bake = if settings.spatial_threshold > 0.0 {
            if range != (0..n) {
                return Err(MethodError::Settings(format!(
                    "a vmf bake with spatial refinement (--spatial-threshold) cannot be baked in parts (vertices {range:?} of {n} asked: --shard, --checkpoint-vertices or --memory-limit): the refinement couples neighbouring vertices; bake it whole"
                )));
            }
            let (bake, mesh, _) = relight_bake::vmf::spatial::bake_refined(
                &input.scene.mesh,
                &input.scene.materials,
                None,
                caster.as_ref(),
                &run,
            )?;
            scene.mesh = mesh;
            // The refinement interleaves the objects' triangles: the names do not survive it.
            scene.objects = crate::store::objects_of_materials(&scene.mesh);
            bake
        } else {
            relight_bake::vmf::bake_vertices(
                &input.scene.mesh,
                &input.scene.materials,
                None,
                caster.as_ref(),
                &run,
                range.clone(),
            )?
        };
        let recorded = VmfBakeSettings {
            progress: false,
            threads: None,
            ..*settings
        };
        bake.settings = recorded;
        // A refined bake is whole, over the refined mesh.
        let n = scene.mesh.vertex_count();
        let range = if settings.spatial_threshold > 0.0 {
            0..n
        } else {
            range
        };
        Ok(VmfBaked {
            scene,
            bake,
            settings: recorded,
            record: BakeRecord::new(
                caster.name(),
                t0.elapsed().as_secs_f64(),
                ctx.f16,
                &range,
                n,
            ),
        })
    }

    fn store(b: &VmfBaked) -> Result<Bundle, MethodError> {
        store::store(b)
    }

    fn load(bundle: &Bundle, path: &Path) -> Result<VmfBaked, MethodError> {
        store::load(bundle, path)
    }
}

/// Everything a `vmf` bundle holds.
#[derive(Clone, Debug)]
pub struct VmfBaked {
    /// The scene it was baked from.
    pub scene: BakedScene,
    /// The slices of the baked vertices (its settings are `settings`).
    pub bake: VmfBake,
    /// The settings (threads and progress not recorded).
    pub settings: VmfBakeSettings,
    /// How the bake ran (and which vertices, for a part).
    pub record: BakeRecord,
}

impl VmfBaked {
    /// The vertices baked: the record's range, or the whole mesh.
    pub fn vertex_range(&self) -> Range<usize> {
        match self.record.range {
            Some((a, b)) => a..b,
            None => 0..self.scene.mesh.vertex_count(),
        }
    }

    /// A human description (one line each) and the same figures as JSON: slices, views per
    /// vertex by level (what `relight bake` and `relight info` print).
    pub fn describe(&self) -> (Vec<String>, serde_json::Value) {
        let b = &self.bake;
        let mut per_level = [0usize; relight_bake::vmf::bake::MAX_VIEW_LEVEL as usize + 1];
        for &l in &b.levels {
            per_level[l as usize] += 1;
        }
        let v = b.vertex_count().max(1);
        let lines = vec![format!(
            "vmf (Laurijssen & Dutré 2009): {} slices of 6 lobes, {:.1} views per vertex (vertices per view level 0..5: {per_level:?}), {} paths per slice, {} bounce(s)",
            b.slices.len(),
            b.slices.len() as f64 / v as f64,
            self.settings.paths,
            self.settings.max_bounces,
        )];
        let json = serde_json::json!({
            "slices": b.slices.len(),
            "views_per_vertex": b.slices.len() as f64 / v as f64,
            "vertices_per_level": per_level,
        });
        (lines, json)
    }

    /// Check every invariant: the bake's ([`VmfBake::validate`]), its settings equal to the
    /// recorded ones, one row per baked vertex inside the mesh.
    ///
    /// # Errors
    /// A message naming the first violation.
    pub fn validate(&self) -> Result<(), Invalid> {
        self.bake.validate().map_err(|e| Invalid(e.0))?;
        if self.bake.settings != self.settings {
            return Err(Invalid(
                "the bake's settings are not the recorded ones".into(),
            ));
        }
        let range = self.vertex_range();
        if range.end > self.scene.mesh.vertex_count() || range.start > range.end {
            return Err(Invalid(format!(
                "vertex range {}..{} outside the mesh's {} vertices",
                range.start,
                range.end,
                self.scene.mesh.vertex_count()
            )));
        }
        if self.bake.vertex_count() != range.len() {
            return Err(Invalid(format!(
                "{} vertex rows for the {} vertices baked",
                self.bake.vertex_count(),
                range.len()
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
