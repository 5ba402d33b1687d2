//! Precomputed visibility cuts (Cheslack-Postava, Wang, Akerlund, Pellacini 2008, "Fast,
//! realistic lighting and material design using nonlinear cut approximation"; after Akerlund,
//! Unger & Wang 2007). The only method of relight whose materials stay editable after the
//! bake: the bake stores visibility only, BRDFs are applied per pixel at render time.
//!
//! ## The pieces, one file each
//!
//! * [`samples`]: the environment as ~32K well-spread directions with the solid angle of each
//!   one's Voronoi cell, and each sample's radiance from an environment map (sec. 4.1).
//! * [`tree`]: the light tree, a complete binary tree over the samples built top-down with the
//!   geometric metric (Eq. 11) or the data-driven one from pilot visibility (Eq. 12-13), stored
//!   in post-order with each node's leftmost leaf (sec. 3.1, 3.2, 3.4).
//! * [`cut`]: cluster means and variances propagated up the tree, and a cut refined until
//!   every node satisfies `|C| var <= sigma^2` (Eq. 6), capped at 1000 nodes; the sparse
//!   quantised storage of all vertices' cuts (sec. 3.2).
//! * [`visibility`]: the per-vertex function sampled with the ray caster at every leaf, in
//!   parallel, and the pilot visibility vectors of the data-driven tree (sec. 3.4, 4.1).
//! * [`merge`]: the single linear traversal of N cuts (sec. 3.2's pseudo-code) for sums and
//!   products, e.g. three barycentric-weighted vertex cuts times a light cut (Eq. 5, sec. 4.2).
//! * [`light_cut`]: the illumination cut of a frame: error bound first, then the remaining
//!   budget by intensity (sec. 3.2, 4.2).
//! * [`surface`], [`local`]: local lighting (sec. 4.1-4.2): light samples spread by area over
//!   the surfaces, and the vertex function towards them (visibility times a clamped
//!   geometric term); a point light's direct light at the samples, re-emitted diffusely, is
//!   then the light function of one bounce of indirect light (`relight_render::shade_local`).
//!
//! ## Conventions (stated once, here)
//!
//! * Directions are world-frame unit vectors (`relight_sphere`'s conventions: +Y up); an
//!   environment light sample `i` is a direction `w_i` with the solid angle `O_i` of its
//!   Voronoi cell (`sum_i O_i = 4 pi`) and radiance `L_i` arriving from it.
//! * **Visibility function** of a vertex with unit normal `n`: by default
//!   `v_i = V(w_i) max(0, n . w_i)`, in `[0, 1]`: binary visibility times the cosine; or the
//!   paper's binary `V(w_i) [n . w_i > 0]` ([`visibility::CutFunction`]), the cosine then
//!   going with the BRDF at render time. It excludes the solid angle, the radiance and the
//!   BRDF. Vertex cuts store cluster means of `v`, quantised to 16 bits (`round(65535 v)`).
//! * **Light function**: `l_i = L_i O_i` (RGB, radiance times solid angle: the sample as a
//!   point light). Outgoing radiance is then (Eq. 1-2 with the paper's `G` in `l`)
//!   `B = sum_i l_i f_r(w_i) v_i`, and with merged clusters `C'_k` (Eq. 5)
//!   `B ~ sum_k |C'_k| <l>_k <v>_k f_r(<w>_k)` where `f_r` excludes the cosine when `v` holds
//!   it (and includes it otherwise) and `<w>_k` is the normalised mean direction of the
//!   cluster.
//! * **Tree indices**: nodes are numbered in post-order (children before parents, the root
//!   last, `2N - 1` nodes for `N` leaves); node `p` covers the post-order range
//!   `[leftleaf(p), p]`, its leftmost leaf being `leftleaf(p)`. A cut is a list of nodes in
//!   increasing index, which is left-to-right order, whose leaves tile all leaves once.
//! * **Error of a node**: `M2 = sum_{i in C} (x_i - <x>)^2 = |C| var(x)`, so Eq. 6 reads
//!   `M2 <= sigma^2`.
//!
//! ## Example: bake, light cut, one shaded point
//!
//! ```
//! use relight_bake::cuts::{bake_range, light_cut::LightCut, merge::shade};
//! use relight_bake::cuts::{samples::sample_power, CutsBakeSettings};
//! use relight_scene::{accel, scene::Environment, shapes};
//! use relight_sphere::{EnvMap, Vec3};
//! # fn main() -> Result<(), relight_bake::BakeError> {
//! // A sphere floating over a 4 x 4 plane; vertex 0 is the plane's corner (-2, 0, -2).
//! let mut mesh = shapes::ground_plane(Vec3::ZERO, 4.0, 2);
//! mesh.append(&shapes::uv_sphere(Vec3::new(0.0, 1.5, 0.0), 1.0, 8, 16), 0);
//! let caster = accel::build(&mesh, accel::Backend::Bvh).expect("our BVH always builds");
//! let settings = CutsBakeSettings { lights: 1024, ..Default::default() };
//! let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count())?;
//! bake.validate().expect("a fresh bake is valid");
//! // A white sky: each light sample's power is its solid angle.
//! let env = Environment::new(EnvMap::constant(Vec3::ONE));
//! let power = sample_power(&bake.samples, &env)?;
//! let light = LightCut::build(&bake.tree, &power, 2.0, 256)?;
//! // A white Lambertian corner (the cuts hold binary visibility, the default; the BRDF
//! // times the cosine, evaluated at each merged cluster's direction, is 1 / pi n . w, all
//! // of it a diffuse lobe: `[glossy, diffuse]`):
//! // int V cos / pi, 1 without the sphere, which hides about 5% of the cosine-weighted sky.
//! let c = bake.cuts.cut(0);
//! let b = shade(&light, [c, c, c], [1.0, 0.0, 0.0], false, |w: Vec3| {
//!     [Vec3::ZERO, Vec3::splat(w.y.max(0.0) * std::f32::consts::FRAC_1_PI)]
//! });
//! assert!(b.x > 0.9 && b.x < 0.99, "{b}");
//! # Ok(()) }
//! ```

pub mod cut;
pub mod light_cut;
pub mod local;
pub mod merge;
pub mod nearest;
pub mod samples;
pub mod settings;
pub mod surface;
pub mod tree;
pub mod visibility;

pub use settings::{CutsBakeSettings, LightSampleKind, LightTreeKind};

use crate::BakeError;
use cut::VertexCuts;
use relight_scene::accel::RayCaster;
use relight_scene::mesh::TriMesh;
use samples::EnvSamples;
use std::ops::Range;
use surface::SurfaceSamples;
use tree::LightTree;
use visibility::{CutParams, LightTargets, VisibilitySampler};

/// A cuts bake: the light samples, the light tree over them and every vertex's visibility
/// cut. Lighting, BRDFs and materials are applied at render time.
#[derive(Clone, Debug, PartialEq)]
pub struct CutsBake {
    /// The environment light samples (directions and solid angles); empty for a bake of
    /// surface samples.
    pub samples: EnvSamples,
    /// The surface light samples of local lighting ([`LightSampleKind::Surface`]); `None`
    /// for an environment bake.
    pub surface: Option<SurfaceSamples>,
    /// The light tree over the samples.
    pub tree: LightTree,
    /// The visibility cuts of the baked vertices.
    pub cuts: VertexCuts,
}

impl CutsBake {
    /// Check the tree's and the cuts' invariants.
    ///
    /// # Errors
    /// A description of the first broken invariant.
    pub fn validate(&self) -> Result<(), String> {
        self.tree.validate().map_err(|e| e.to_string())?;
        if let Some(s) = &self.surface {
            if !self.samples.is_empty() || s.len() != self.tree.light_count() {
                return Err(format!(
                    "{} surface samples and {} directions for a tree of {} lights",
                    s.len(),
                    self.samples.len(),
                    self.tree.light_count()
                ));
            }
            return self.cuts.validate(&self.tree).map_err(|e| e.to_string());
        }
        if self.samples.dirs.len() != self.tree.light_count()
            || self.samples.solid_angles.len() != self.samples.dirs.len()
        {
            return Err(format!(
                "{} samples, {} solid angles, tree of {} lights",
                self.samples.dirs.len(),
                self.samples.solid_angles.len(),
                self.tree.light_count()
            ));
        }
        self.cuts.validate(&self.tree).map_err(|e| e.to_string())
    }
}

/// Bake the visibility cuts of the vertices `range` of `mesh` (with `caster` built over it):
/// light samples, light tree (geometric, or data-driven from a pilot pass over all vertices),
/// cuts. Deterministic for the settings' seed, whatever the threads.
///
/// # Errors
/// Invalid settings, an inconsistent mesh, a range outside the mesh, a thread-pool failure.
pub fn bake_range(
    mesh: &TriMesh,
    caster: &dyn RayCaster,
    settings: &CutsBakeSettings,
    range: Range<usize>,
) -> Result<CutsBake, BakeError> {
    settings.validate()?;
    let n = settings.lights as usize;
    let (samples, surface) = match settings.samples {
        LightSampleKind::Environment => (EnvSamples::fibonacci(n, settings.seed)?, None),
        LightSampleKind::Surface => (
            EnvSamples::default(),
            Some(SurfaceSamples::spread(mesh, n, settings.seed)?),
        ),
    };
    // Environment lights are points on the unit sphere facing the scene (normal -w).
    let (targets, positions, normals) = match &surface {
        None => (
            LightTargets::Directions(&samples.dirs),
            samples.dirs.clone(),
            samples.dirs.iter().map(|&d| -d).collect(),
        ),
        Some(s) => (
            LightTargets::Points(s),
            s.positions.clone(),
            s.normals.clone(),
        ),
    };
    let sampler = VisibilitySampler::with_targets(mesh, caster, targets, settings.function)?;
    let tree = match settings.tree {
        LightTreeKind::Geometric => LightTree::geometric(&positions, &normals, settings.k)?,
        LightTreeKind::DataDriven => {
            let pilot = sampler.pilot_vectors(
                settings.vertex_clusters as usize,
                settings.k,
                settings.threads,
                settings.progress,
            )?;
            LightTree::data_driven(&positions, &normals, &pilot, settings.k, settings.beta)?
        }
    };
    let params = CutParams {
        sigma: settings.sigma,
        max_nodes: settings.max_cut as usize,
        threads: settings.threads,
        progress: settings.progress,
    };
    let cuts = sampler.cuts(&tree, range, &params)?;
    Ok(CutsBake {
        samples,
        surface,
        tree,
        cuts,
    })
}

/// Why a cuts computation refused its input: a user-facing error (bad environment, too few
/// lights, settings out of range), never a numeric precondition.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CutsError {
    /// A light tree needs at least two lights.
    #[error("a light tree needs at least 2 lights, got {count}")]
    TooFewLights {
        /// Lights given.
        count: usize,
    },
    /// The environment has a texel or scale that is NaN, infinite or negative.
    #[error("invalid environment: {0}")]
    Environment(String),
    /// An input's size or value is out of range (the message names it).
    #[error("invalid cuts input: {0}")]
    Input(String),
}
