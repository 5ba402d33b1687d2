//! The `cuts` method (Cheslack-Postava et al. 2008, issue 11), **first part of its seam**: the
//! baked type, its checks and its bundle tensors. The maths and the bake loop are
//! `relight_bake::cuts`.
//!
//! Not yet here (the next steps of "how to add a method"): `impl Method`, the arms of
//! [`crate::MethodKind`], [`crate::BakeKind`], [`crate::Baked`] and [`crate::FrameSettings`],
//! the frame (`relight_render::shade_cuts`), the CLI. Until then [`crate::read_any`] does not
//! read a `cuts` bundle; [`load`] does.

mod store;

pub use store::{load, store};

use crate::store::{BakeRecord, BakedScene};
use relight_bake::cuts::{CutsBake, CutsBakeSettings};
use relight_scene::error::Invalid;

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
        if b.samples.len() != n {
            return Err(format!(
                "{} light samples, the settings say {n}",
                b.samples.len()
            ));
        }
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
        // 1e-5: f32 normalisation.
        if let Some(i) = b
            .samples
            .dirs
            .iter()
            .position(|d| (d.length() - 1.0).abs() > 1e-5)
        {
            return Err(format!("light direction {i} is not unit"));
        }
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
mod tests;
