//! The `cuts` method (Cheslack-Postava et al. 2008): the bake is
//! `relight_bake::cuts` (light samples, light tree, per-vertex visibility cuts), the frame
//! `relight_render::shade_cuts` (per pixel: three vertex cuts merged with the frame's
//! illumination cut and the scene's materials evaluated at run time).

mod edit;
mod frame;
pub mod local;
mod store;

pub use edit::{apply_material_edits, parse_material_edit, MaterialEdit};
pub use frame::{CutsFrame, CutsFrameSettings, EnvLightCut, MaterialOverride};
pub use store::{load, store};

use crate::store::{BakeRecord, BakedScene};
use crate::{build_caster, BakeContext, BakeInput, BakeKind, Method, MethodError};
use relight_bake::cuts::{CutsBake, CutsBakeSettings, LightSampleKind};
use relight_bundle::Bundle;
use relight_scene::error::Invalid;
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

/// The `cuts` method's bake verbs.
pub struct Cuts;

impl Method for Cuts {
    const KIND: BakeKind = BakeKind::Cuts;
    type Settings = CutsBakeSettings;
    type Baked = CutsBaked;

    fn validate(s: &CutsBakeSettings) -> Result<(), MethodError> {
        Ok(s.validate()?)
    }

    /// An upper bound: a cut of `max_cut` nodes (index, leftmost leaf, value: 10 bytes each)
    /// and its offset. Real cuts are far shorter (docs/RESULTS.md, section cuts).
    fn row_bytes(_: BakeInput, s: &CutsBakeSettings) -> u64 {
        8 + 10 * u64::from(s.max_cut)
    }

    fn settings_line(s: &CutsBakeSettings) -> String {
        format!(
            "cuts, {} lights ({:?}), {:?} light tree, sigma {}, cap {}",
            s.lights, s.samples, s.tree, s.sigma, s.max_cut
        )
    }

    fn streams(_: &CutsBakeSettings) -> Option<&'static str> {
        Some("the cuts merge rebases every part's cut offsets in memory (not streamed yet)")
    }

    /// Vertices are independent (the light samples depend on the seed, a data-driven tree
    /// on a pilot pass over every vertex), so a range bakes exactly those rows of the whole
    /// bake.
    fn bake(
        input: BakeInput,
        settings: &CutsBakeSettings,
        range: Range<usize>,
        ctx: &BakeContext,
    ) -> Result<CutsBaked, MethodError> {
        Cuts::validate(settings)?;
        let n = input.scene.mesh.vertex_count();
        let t0 = Instant::now();
        let caster = build_caster(&input, ctx)?;
        let run = CutsBakeSettings {
            progress: ctx.progress,
            ..*settings
        };
        let bake = relight_bake::cuts::bake_range(
            &input.scene.mesh,
            caster.as_ref(),
            &run,
            range.clone(),
        )?;
        Ok(CutsBaked {
            scene: BakedScene::of(&input),
            bake,
            settings: CutsBakeSettings {
                progress: false,
                threads: None,
                ..*settings
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

    fn store(b: &CutsBaked) -> Result<Bundle, MethodError> {
        store::store(b)
    }

    fn load(bundle: &Bundle, path: &Path) -> Result<CutsBaked, MethodError> {
        store::load(bundle, path)
    }
}

/// Everything a `cuts` bundle holds.
#[derive(Clone, Debug)]
pub struct CutsBaked {
    /// The scene it was baked from.
    pub scene: BakedScene,
    /// Light samples, light tree and the vertices' visibility cuts.
    pub bake: CutsBake,
    /// The settings (threads and progress not recorded).
    pub settings: CutsBakeSettings,
    /// How the bake ran (and which vertices, for a part).
    pub record: BakeRecord,
}

impl CutsBaked {
    /// A human description (one line each) and the same figures as JSON: lights, tree,
    /// mean cut length, capped cuts (what `relight bake` and `relight info` print).
    pub fn describe(&self) -> (Vec<String>, serde_json::Value) {
        let (s, c) = (&self.settings, &self.bake.cuts);
        let lines = vec![format!(
            "cuts (Cheslack-Postava 2008): {} lights ({:?}), {:?} light tree, sigma {}, {:?}; mean cut {:.1} nodes, {} cuts capped at {}",
            s.lights,
            s.samples,
            s.tree,
            s.sigma,
            s.function,
            c.mean_len(),
            c.capped.len(),
            s.max_cut
        )];
        let json = serde_json::json!({
            "lights": s.lights,
            "samples": s.samples,
            "mean_cut": c.mean_len(),
            "capped": c.capped.len(),
        });
        (lines, json)
    }

    /// The vertices baked: the record's range, or the whole mesh.
    pub fn vertex_range(&self) -> std::ops::Range<usize> {
        match self.record.range {
            Some((a, b)) => a..b,
            None => 0..self.scene.mesh.vertex_count(),
        }
    }

    /// Check every invariant: the tree's and the cuts' (`validate` of each), one cut per
    /// baked vertex inside the mesh, as many lights as the settings say, unit directions,
    /// finite non-negative solid angles summing to `4 pi`.
    ///
    /// # Errors
    /// A message naming the first violation.
    pub fn validate(&self) -> Result<(), Invalid> {
        self.validate_msg().map_err(Invalid)
    }

    fn validate_msg(&self) -> Result<(), String> {
        let b = &self.bake;
        b.validate()?;
        let n = self.settings.lights as usize;
        match (self.settings.samples, &b.surface) {
            (LightSampleKind::Environment, None) => {}
            (LightSampleKind::Surface, Some(s)) => {
                if s.len() != n {
                    return Err(format!("{} surface samples, the settings say {n}", s.len()));
                }
                s.validate(&self.scene.mesh)
                    .map_err(|e| format!("surface samples: {e}"))?;
                return self.validate_range();
            }
            (kind, _) => {
                return Err(format!(
                    "the settings say {kind:?} light samples, the bake holds the other kind"
                ))
            }
        }
        if b.samples.len() != n {
            return Err(format!(
                "{} light samples, the settings say {n}",
                b.samples.len()
            ));
        }
        self.validate_range()?;
        // 1e-5: f32 normalisation.
        if let Some(i) = b
            .samples
            .dirs
            .iter()
            .position(|d| (d.length() - 1.0).abs() > 1e-5)
        {
            return Err(format!("light direction {i} is not unit"));
        }
        self.validate_solid_angles()
    }

    /// One cut per baked vertex, inside the mesh.
    fn validate_range(&self) -> Result<(), String> {
        let b = &self.bake;
        let range = self.vertex_range();
        if range.end > self.scene.mesh.vertex_count() || range.start > range.end {
            return Err(format!(
                "vertex range {}..{} outside the mesh's {} vertices",
                range.start,
                range.end,
                self.scene.mesh.vertex_count()
            ));
        }
        if b.cuts.vertex_count() != range.len() {
            return Err(format!(
                "{} vertex cuts for the {} vertices baked",
                b.cuts.vertex_count(),
                range.len()
            ));
        }
        Ok(())
    }

    /// Finite non-negative solid angles summing to `4 pi`.
    fn validate_solid_angles(&self) -> Result<(), String> {
        let b = &self.bake;
        if let Some(i) = b
            .samples
            .solid_angles
            .iter()
            .position(|w| !(w.is_finite() && *w >= 0.0))
        {
            return Err(format!(
                "light {i} has a negative or non-finite solid angle"
            ));
        }
        let sum: f64 = b.samples.solid_angles.iter().map(|&w| w as f64).sum();
        let four_pi = 4.0 * std::f64::consts::PI;
        // 1e-3: f16 storage rounds each solid angle by up to 2^-11 relative.
        if (sum - four_pi).abs() > 1e-3 * four_pi {
            return Err(format!("solid angles sum to {sum}, not 4 pi"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod local_tests;
#[cfg(test)]
mod tests;
