//! Settings of a cuts bake ([`CutsBakeSettings`]): defaults from the paper, validation.

use super::cut::{DEFAULT_MAX_CUT, DEFAULT_SIGMA};
use super::samples::DEFAULT_SAMPLES;
use super::tree::{DEFAULT_BETA, DEFAULT_K, DEFAULT_VERTEX_CLUSTERS};
pub use super::visibility::CutFunction;
use crate::BakeError;
use serde::{Deserialize, Serialize};

/// Largest number of light samples accepted (2^20: a vertex's function is one f32 per light
/// per thread, its tree `2 N - 1` nodes).
pub const MAX_LIGHTS: u32 = 1 << 20;
/// Largest cut cap accepted (a cut of more nodes than that stops being sparse for 32K lights).
pub const MAX_CUT_CAP: u32 = 1 << 16;
/// Largest number of pilot vertex clusters accepted (the pilot matrix is lights x clusters).
pub const MAX_VERTEX_CLUSTERS: u32 = 1 << 14;

/// How the light tree is built (sec. 3.4). A closed set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum LightTreeKind {
    /// Geometric metric only (Eq. 11).
    Geometric,
    /// Mixed metric with pilot visibility vectors (Eq. 13): a second pass of rays.
    DataDriven,
}

/// What the light samples are (sec. 4.1). A closed set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum LightSampleKind {
    /// Directions of a distant environment (rendered with `--env`).
    #[default]
    Environment,
    /// Points spread by area over the surfaces, for a point or spot light moved at render
    /// time with one bounce of indirect light (sec. 4.2; [`super::surface`]).
    Surface,
}

/// Settings of a cuts bake: what a bundle records (serde) and, with the `cli` feature, the
/// options of `relight bake --method cuts`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(
    feature = "cli",
    command(next_help_heading = "Cuts bake (--method cuts)")
)]
pub struct CutsBakeSettings {
    /// Light samples (the paper's 32K, directions or surface points), `2..=MAX_LIGHTS`.
    #[cfg_attr(feature = "cli", arg(long = "cut-lights", default_value_t = DEFAULT_SAMPLES as u32))]
    pub lights: u32,
    /// Light samples: environment directions, or surface points for local lights
    /// (`relight render --point-light`). Bundles from before this setting are environment.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long = "cut-samples", id = "cut_samples", value_enum, default_value_t = LightSampleKind::Environment))]
    pub samples: LightSampleKind,
    /// `sigma` of Eq. 6: every cut node has `|C| var <= sigma^2` (the paper: 1.5-3), `>= 0`.
    #[cfg_attr(feature = "cli", arg(long = "cut-sigma", default_value_t = DEFAULT_SIGMA))]
    pub sigma: f32,
    /// The function each vertex cut approximates: visibility times the cosine, or the
    /// paper's binary visibility (the cosine then in the BRDF at render time).
    #[cfg_attr(feature = "cli", arg(long = "cut-function", value_enum, default_value_t = CutFunction::Visibility))]
    pub function: CutFunction,
    /// Cap on a visibility cut's nodes (the paper's 1000), `1..=MAX_CUT_CAP`.
    #[cfg_attr(feature = "cli", arg(long = "cut-max", default_value_t = DEFAULT_MAX_CUT as u32))]
    pub max_cut: u32,
    /// Light tree: geometric (Eq. 11) or data-driven (Eq. 13, a pilot pass of rays).
    #[cfg_attr(feature = "cli", arg(long = "cut-tree", value_enum, default_value_t = LightTreeKind::Geometric))]
    pub tree: LightTreeKind,
    /// `beta` of Eq. 13 (data-driven tree), `[0, 1]`; 1 is purely geometric.
    #[cfg_attr(feature = "cli", arg(long = "cut-beta", default_value_t = DEFAULT_BETA))]
    pub beta: f32,
    /// Vertex clusters of the pilot visibility vectors (data-driven tree),
    /// `1..=MAX_VERTEX_CLUSTERS`.
    #[cfg_attr(feature = "cli", arg(long = "cut-clusters", default_value_t = DEFAULT_VERTEX_CLUSTERS as u32))]
    pub vertex_clusters: u32,
    /// `K` of Eq. 11-12, `> 0`.
    #[cfg_attr(feature = "cli", arg(long = "cut-k", default_value_t = DEFAULT_K))]
    pub k: f32,
    /// Seed: rotates the light samples' lattice.
    #[cfg_attr(feature = "cli", arg(skip))]
    pub seed: u64,
    /// Worker threads; `None` = rayon's global pool (all cores). Not recorded.
    #[serde(skip)]
    #[cfg_attr(feature = "cli", arg(skip))]
    pub threads: Option<usize>,
    /// Show an indicatif progress bar on stderr. Not recorded.
    #[serde(skip)]
    #[cfg_attr(feature = "cli", arg(skip))]
    pub progress: bool,
}

impl Default for CutsBakeSettings {
    /// The paper's: 32K lights, sigma 2, binary visibility, cap 1000, geometric tree (data-driven: beta 0.5,
    /// 1024 clusters), K 30, seed 0, all cores, no progress bar.
    fn default() -> Self {
        CutsBakeSettings {
            lights: DEFAULT_SAMPLES as u32,
            samples: LightSampleKind::Environment,
            sigma: DEFAULT_SIGMA,
            function: CutFunction::Visibility,
            max_cut: DEFAULT_MAX_CUT as u32,
            tree: LightTreeKind::Geometric,
            beta: DEFAULT_BETA,
            vertex_clusters: DEFAULT_VERTEX_CLUSTERS as u32,
            k: DEFAULT_K,
            seed: 0,
            threads: None,
            progress: false,
        }
    }
}

impl CutsBakeSettings {
    /// Check the ranges documented on each field.
    ///
    /// # Errors
    /// [`BakeError::Settings`] naming the offending setting.
    pub fn validate(&self) -> Result<(), BakeError> {
        let err = |m: String| Err(BakeError::Settings(m));
        if !(2..=MAX_LIGHTS).contains(&self.lights) {
            return err(format!("lights {} is not in 2..={MAX_LIGHTS}", self.lights));
        }
        if !(self.sigma.is_finite() && self.sigma >= 0.0) {
            return err(format!("sigma {} must be finite and >= 0", self.sigma));
        }
        if !(1..=MAX_CUT_CAP).contains(&self.max_cut) {
            return err(format!(
                "max_cut {} is not in 1..={MAX_CUT_CAP}",
                self.max_cut
            ));
        }
        if !(0.0..=1.0).contains(&self.beta) {
            return err(format!("beta {} is not in [0, 1]", self.beta));
        }
        if !(1..=MAX_VERTEX_CLUSTERS).contains(&self.vertex_clusters) {
            return err(format!(
                "vertex_clusters {} is not in 1..={MAX_VERTEX_CLUSTERS}",
                self.vertex_clusters
            ));
        }
        if !(self.k.is_finite() && self.k > 0.0) {
            return err(format!("K {} must be finite and > 0", self.k));
        }
        if self.threads == Some(0) {
            return err("threads must be at least 1".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_ranges_refused() {
        let d = CutsBakeSettings::default();
        d.validate().unwrap();
        let bad = [
            CutsBakeSettings { lights: 1, ..d },
            CutsBakeSettings { sigma: -1.0, ..d },
            CutsBakeSettings {
                sigma: f32::NAN,
                ..d
            },
            CutsBakeSettings { max_cut: 0, ..d },
            CutsBakeSettings { beta: 1.5, ..d },
            CutsBakeSettings {
                beta: f32::NAN,
                ..d
            },
            CutsBakeSettings {
                vertex_clusters: 0,
                ..d
            },
            CutsBakeSettings { k: 0.0, ..d },
            CutsBakeSettings {
                threads: Some(0),
                ..d
            },
        ];
        for s in bad {
            assert!(matches!(s.validate(), Err(BakeError::Settings(_))), "{s:?}");
        }
    }
}
