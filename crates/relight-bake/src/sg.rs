//! View-dependent glossy PRT with spherical Gaussians (Green 2005, "View-dependent
//! precomputed light transport using non-linear Gaussian function approximations"; the thesis
//! text is `../shared/papers/green-2005-view-dependent-prt-gaussians.md`).
//!
//! # What is baked (thesis section 2.2.1, 3.1)
//! For every vertex `x` and each of the 92 view directions `v` of a frequency-3 geodesic
//! icosahedron ([`relight_sphere::icosphere::Icosphere`], **global frame**, as the paper), the
//! outgoing radiance is split into
//! * **direct glossy** transport `T_x,v(w) = f_glossy(v, w) cos(w) V_x(w)`, tabulated on a cube
//!   map of `direct_res` (default 6x32x32) texels `w`;
//! * **indirect glossy** transport (BRDF-importance-sampled paths leaving `x` towards `-v`,
//!   recorded in the texel of the direction in which they escape), on a coarse cube map of
//!   `indirect_res` (default 6x8x8);
//! * the **view-independent diffuse** part, projected to SH (order 5 default) from the same
//!   visibility cube map: `(1/pi) sum_w y_i(w) V_x(w) cos(w) k_x(cos w) dA(w)` with the
//!   material's light-side factor `k_x` ([`relight_scene::material::Material::diffuse_factors`]);
//!   the diffuse albedo and the view-side factor are applied at render time.
//!
//! Each cube map is the kernel of `L_o(x, v) = sum_w T_x,v(w) L(w) dA(w)`: radiance in,
//! radiance out, per steradian. Each is then fitted by `N` spherical Gaussians ([`SgLobe`]) so
//! that `L_o ~= sum_k a_k int G_k(w) L(w) dw` (eq. 2.7), which the renderer evaluates with one
//! Gaussian-prefiltered cube-map fetch per lobe.
//!
//! # Views below the horizon
//! A view `v` with `n_x . v < sin(horizon_deg)` cannot see `x`. Its lobes are fitted to the
//! transport of the view clamped to `horizon_deg` above the shading horizon (the nearest
//! visible view), so that interpolating the three nearest views near grazing angles stays
//! continuous instead of fading to black.
//!
//! # Layout of [`SgLobes::lobes`]
//! `lobes[(x * view_count + v) * lobe_count + k]`: vertex-major, then view, then lobe.

pub mod fit;
mod settings;
pub use settings::{ExpectedError, LobeSetting, DEFAULT_LOBES_EXPECTED, MAX_LOBES, MAX_REGIONS};
pub mod transport;

use relight_scene::material::Material;
use relight_sphere::sg::SgLobe;
use serde::{Deserialize, Serialize};

pub use crate::sh::ShTransfer;

/// Number of view directions: the vertices of a frequency-3 geodesic icosahedron.
pub const VIEW_FREQUENCY: usize = 3;

/// Fitted lobes of one transport component (layout in the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct SgLobes {
    /// Lobes per vertex and view, `N`.
    pub lobe_count: usize,
    /// Views per vertex (92 for frequency 3).
    pub view_count: usize,
    /// `vertex_count * view_count * lobe_count` lobes; unused lobes have zero amplitude.
    pub lobes: Vec<SgLobe>,
}

impl SgLobes {
    /// The `lobe_count` lobes of vertex `x` seen from view `v`.
    #[inline]
    pub fn get(&self, x: usize, v: usize) -> &[SgLobe] {
        let i = (x * self.view_count + v) * self.lobe_count;
        &self.lobes[i..i + self.lobe_count]
    }
}

/// Fitting statistics of a bake (for reports and the flipping analysis).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SgFitStats {
    /// Mean relative L2 error of the fits over all (vertex, view) pairs with non-zero data,
    /// per component (direct, indirect).
    pub mean_relative_error: [f64; 2],
    /// Levenberg-Marquardt iterations spent in total.
    pub iterations: u64,
    /// Lobe-correspondence failures ("flips") between neighbouring vertices after the flood
    /// fill: pairs of adjacent vertices and a view where the best lobe permutation is not the
    /// identity (thesis section 3.4).
    pub flips: u64,
    /// The same count after the relaxation sweeps.
    pub flips_after_relaxation: u64,
}

/// A complete SG bake: what `relight render --method sg` needs.
#[derive(Clone, Debug)]
pub struct SgBake {
    /// Frequency of the view icosahedron (3: 92 views).
    pub view_frequency: usize,
    /// Direct glossy lobes.
    pub direct: SgLobes,
    /// Indirect glossy lobes (`None` when `indirect_lobes` was 0).
    pub indirect: Option<SgLobes>,
    /// Diffuse SH transfer: single channel, shadowed, with the light-side factor and `1/pi`,
    /// without the albedo (layout of [`ShTransfer`]).
    pub diffuse: ShTransfer,
    /// The material of each vertex (spatially varying BRDFs, thesis section 2.3.1).
    pub materials: Vec<Material>,
    /// How the fit went.
    pub stats: SgFitStats,
    /// The lobes' radial shape (the fit's [`SgFitSettings::lobe_kernel`]): every lobe of the
    /// bake is `a K(1 - mu . v; lambda)` ([`relight_sphere::sg_kernel`]).
    pub kernel: relight_sphere::sg_kernel::LobeKernel,
    /// The lobes' variable (the fit's [`SgFitSettings::lobe_domain`]): the light direction
    /// `w`, or the half vector `h(w) = normalize(w + v)` of the view the lobe is seen from.
    pub domain: SgDomain,
    /// The bake's [`SgBakeSettings::horizon_deg`]: a view below this elevation over a
    /// vertex's shading horizon holds the transport of the view clamped to it
    /// ([`transport::clamp_view`]). The frame of a half-vector bake needs the view each lobe
    /// was fitted for.
    pub horizon_deg: f32,
    /// How the fit ordered `N >= 2` lobes (the fit's [`SgFitSettings::lobe_order`]):
    /// [`LobeOrder::Nested`] and [`LobeOrder::Additive`] lobes correspond slot by slot by
    /// construction, so the frame does not re-match them
    /// (`relight_render::shade_sg::ShadeOptions::default_for`).
    pub lobe_order: LobeOrder,
}

impl SgBake {
    /// A bake of `mesh` made of given functions instead of a fit (tests and benchmarks of the
    /// frame): direct lobe `k` of vertex `x` (normal `n`) at view `v` (the views of
    /// [`VIEW_FREQUENCY`]) is `lobe(x, n, v, k)`, the diffuse transfer of order `order` is
    /// `diffuse(n)` (`order^2` values), one material everywhere, no indirect lobes.
    pub fn from_fn(
        mesh: &relight_scene::mesh::TriMesh,
        lobes: usize,
        lobe: impl Fn(usize, glam::Vec3, glam::Vec3, usize) -> SgLobe,
        order: usize,
        diffuse: impl Fn(glam::Vec3) -> Vec<f32>,
        material: Material,
    ) -> SgBake {
        let views = relight_sphere::icosphere::Icosphere::new(VIEW_FREQUENCY);
        let vc = mesh.vertex_count();
        let mut data = Vec::with_capacity(vc * views.vertices().len() * lobes);
        for (x, n) in mesh.normals.iter().enumerate() {
            for v in views.vertices() {
                data.extend((0..lobes).map(|k| lobe(x, *n, *v, k)));
            }
        }
        SgBake {
            view_frequency: VIEW_FREQUENCY,
            direct: SgLobes {
                lobe_count: lobes,
                view_count: views.vertices().len(),
                lobes: data,
            },
            indirect: None,
            diffuse: ShTransfer {
                order,
                kind: crate::sh::ShTransferKind::Shadowed,
                vertex_count: vc,
                channels: 1,
                data: mesh.normals.iter().flat_map(|n| diffuse(*n)).collect(),
            },
            materials: vec![material; vc],
            stats: SgFitStats::default(),
            kernel: Default::default(),
            domain: Default::default(),
            horizon_deg: SgBakeSettings::default().horizon_deg,
            lobe_order: LobeOrder::default(),
        }
    }
}

/// How the fit finds `N >= 2` lobes per (vertex, view) in the flood fill (the measurements
/// are in docs/RESULTS.md, section sg).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum LobeOrder {
    /// All `N` lobes refined together from the warm start (the neighbour's lobes), then
    /// permuted to match the neighbours: the paper's fit (eq. 2.2), and the default (in the
    /// light domain nested made the 2-lobe renders worse). The half-vector domain refuses it
    /// beyond one lobe (jointly fitted half-vector lobes got worse with each added lobe).
    #[default]
    Joint,
    /// Lobe `k` added on the residual of the first `k - 1` and all `k` refined, `k = 1..N`:
    /// slot 1 starts as the one-lobe fit's lobe, slot `k` is the `k`-th one found, and the
    /// fit of `N` lobes starts from the fit of `N - 1`. The joint refinement moves slot 1
    /// away from the one-lobe fit: on the small test scenes four nested half-vector lobes
    /// drift 1.1-1.4 reference noises above one lobe, while on Fig. 3-5 and the teapot under
    /// Kiara 1 Dawn two and three gain 0.4-1.0 points over additive ones.
    Nested,
    /// Lobe `k` fitted alone to the signed residual of the first `k - 1`, which stay as they
    /// were (in every sweep): slot 1 is the one-lobe fit's lobe in shape, and the `N`-lobe
    /// set is the `N - 1` set plus one, all rescaled together to the data's integral. Nested
    /// lobes' joint refinement moves slot 1 (17-27 % in amplitude on the small test sphere),
    /// which made extra lobes cost on the small test scenes; these do not move it. A
    /// residual lobe that leaves the residual no smaller is dropped (zero amplitude), and the
    /// residual is taken of the earlier lobes with their peaks bounded as they are stored.
    /// The half-vector domain's default (`settings::LobeSetting::HALF_VECTOR_GGX`): every
    /// added lobe stays within the reference's noise of one lobe on every scene measured (up
    /// to four lobes), flat on St Peter's and the Spot conductors, 0.4-0.7 points above one
    /// lobe on Fig. 3-5 and the teapot under Kiara 1 Dawn.
    Additive,
}

/// The shape each (vertex, view)'s lobes are given after the least-squares fit (the
/// measurements are in docs/RESULTS.md, section sg).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum LobeShape {
    /// The least-squares lobes (eq. 3.1), amplitudes rescaled to the data's integral
    /// ([`SgFitSettings::energy`]); a bundle without this field holds these.
    #[default]
    LeastSquares,
    /// The least-squares lobes moved to the moments of their share of the data
    /// ([`relight_sphere::sg_fit::match_moments`]: one M-step of EM): each lobe keeps its
    /// share's integral and mean direction, so the mixture's SH bands 0 and 1 are the
    /// data's for every lobe count; a GGX lobe's tails widen its Gaussian instead of
    /// brightening its core.
    Moments,
}

/// The radial shape of the fitted lobes ([`relight_sphere::sg_kernel`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SgKernel {
    /// Green 2005's spherical Gaussian `exp(lambda (mu . v - 1))` (eq. 2.1); a bundle without
    /// this field holds these.
    #[default]
    Gaussian,
    /// The heavy-tailed kernel `~ (1 + lambda (1 - mu . v) / 2)^-2` of a GGX lobe (four
    /// Gaussian terms; four prefiltered fetches per lobe at render time).
    Ggx,
}

impl SgKernel {
    /// The kernel of `relight_sphere`.
    pub fn kernel(self) -> relight_sphere::sg_kernel::LobeKernel {
        use relight_sphere::sg_kernel::LobeKernel;
        match self {
            SgKernel::Gaussian => LobeKernel::Gaussian,
            SgKernel::Ggx => LobeKernel::Ggx,
        }
    }
}

/// The variable of the fitted lobes ([`relight_sphere::half_vector`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SgDomain {
    /// `a K(1 - mu . w)` in the light direction `w` (Green 2005); a bundle without this
    /// field holds these.
    #[default]
    Light,
    /// `a K(1 - mu . h(w))` in the half vector `h(w) = normalize(w + v)` of the view `v`: a
    /// GGX lobe's own variable, so that one lobe follows the reflection's stretch along the
    /// plane of incidence at grazing views. Rendered with five prefiltered lookups per
    /// Gaussian term (`relight_sphere::half_vector`); more than one lobe per component only
    /// [`LobeOrder::Additive`] or [`LobeOrder::Nested`] (jointly fitted ones were measured
    /// worse with each added lobe).
    HalfVector,
}

/// Where the flood fill starts the fit of a (vertex, view) in its first sweep.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum FitStart {
    /// From the lobes of the neighbour the vertex was reached from (the same view), a greedy
    /// fit only if that ends poorly (Green 2005, sec. 2.2.2's flood fill).
    #[default]
    Neighbour,
    /// From the greedy fit of the view's own data (`sg_fit::fit`), permuted to match the
    /// neighbours, then refined with the coherence terms.
    Greedy,
}

/// Settings of the fit (thesis section 2.2.2, eq. 2.2-2.6).
///
/// The three weights are relative to each (vertex, view)'s data energy `sum dA |T|^2` (the
/// solver multiplies them by it, [`fit`] docs), so a dim vertex is not all prior and a bright
/// one not all data; 0 disables a term. Recorded in `sg` bundles (serde) and, with the `cli`
/// feature, the fit options of `relight bake --method sg`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct SgFitSettings {
    /// Levenberg-Marquardt iterations per (vertex, view) refinement.
    #[cfg_attr(feature = "cli", arg(long = "fit-iterations", default_value_t = SgFitSettings::default().max_iterations))]
    pub max_iterations: usize,
    /// Weight `beta` of the mean-alignment term across neighbouring views (eq. 2.4).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgFitSettings::default().mean_weight))]
    pub mean_weight: f64,
    /// Weight `gamma` of the width-alignment term across neighbouring views (eq. 2.5).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgFitSettings::default().width_weight))]
    pub width_weight: f64,
    /// Weight `delta` of the spatial arrangement term across processed neighbours (eq. 2.6).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgFitSettings::default().spatial_weight))]
    pub spatial_weight: f64,
    /// Relaxation sweeps after the flood fill (the paper's suggested future work, sec. 3.4).
    /// Default 0: on the armadillo one sweep removes 18 % of the flips for about a quarter
    /// more bake time.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgFitSettings::default().relax_sweeps))]
    pub relax_sweeps: usize,
    /// Weight of the energy term of the fit (`relight_sphere::sg_fit` docs), relative: an
    /// energy error of `e` (a fraction of the view's integral) costs as much as a relative
    /// L2 error of `sqrt(energy_weight) e`. 0 disables it (bundles written before it
    /// existed).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgFitSettings::default().energy_weight))]
    pub energy_weight: f64,
    /// Where the first sweep starts each view's fit ([`FitStart`]).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = SgFitSettings::default().fit_start))]
    pub fit_start: FitStart,
    /// How `N >= 2` lobes are fitted ([`LobeOrder`]). Bundles written before this setting
    /// existed were fitted [`LobeOrder::Joint`]. Without any lobe option (kernel, domain,
    /// order, shape) `relight bake` and `relight eval` choose the kernel, domain and order by
    /// the scene's materials ([`LobeSetting::for_materials`]: a GGX conductor gets ggx,
    /// half-vector, additive; other scenes gaussian, light, joint).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, value_enum, hide_default_value = true, default_value_t = SgFitSettings::default().lobe_order))]
    pub lobe_order: LobeOrder,
    /// The lobes' shape after the fit ([`LobeShape`]). Bundles written before this setting
    /// existed were fitted [`LobeShape::LeastSquares`].
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = SgFitSettings::default().lobe_shape))]
    pub lobe_shape: LobeShape,
    /// The lobes' radial shape ([`SgKernel`]). Bundles written before this setting existed
    /// were fitted with Gaussians. Default: by the scene's materials (see --lobe-order).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, value_enum, hide_default_value = true, default_value_t = SgFitSettings::default().lobe_kernel))]
    pub lobe_kernel: SgKernel,
    /// The lobes' variable ([`SgDomain`]). Bundles written before this setting existed were
    /// fitted in the light direction. Default: by the scene's materials (see --lobe-order).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, value_enum, hide_default_value = true, default_value_t = SgFitSettings::default().lobe_domain))]
    pub lobe_domain: SgDomain,
    /// Independent flood-fill regions (the unit of parallel work); 0 = automatic.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgFitSettings::default().regions))]
    pub regions: usize,
    /// Rescale each fitted (vertex, view)'s amplitudes so that the lobes' integral equals the
    /// data's (our addition, default on; `fit::vertex` docs): a constant environment is then
    /// rendered exactly.
    #[cfg_attr(
        feature = "cli",
        arg(
            long = "no-energy",
            action = clap::ArgAction::SetFalse,
            help = "Keep the least-squares amplitudes instead of rescaling each fit to the data's integral"
        )
    )]
    pub energy: bool,
}

/// Settings of the SG bake ([`SgBake`]): what an `sg` bundle records (serde) and, with the
/// `cli` feature, the options of `relight bake --method sg`. The SH order of the diffuse
/// part, the indirect bounces and the seed are shared with other methods on the command line
/// (`--sh-order`, `--bounces`, `--seed`), so they are not options of this struct there.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "cli", command(next_help_heading = "SG bake (--method sg)"))]
pub struct SgBakeSettings {
    /// Face size of the direct-glossy cube map per view (default 32: 6x32x32 texels).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgBakeSettings::default().direct_res))]
    pub direct_res: usize,
    /// Face size of the indirect-glossy cube map per view (default 8: 6x8x8).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgBakeSettings::default().indirect_res))]
    pub indirect_res: usize,
    /// Paths per (vertex, view) for the indirect glossy component.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgBakeSettings::default().indirect_paths))]
    pub indirect_paths: u32,
    /// Maximum bounces of an indirect path after leaving the vertex (`--bounces`).
    #[cfg_attr(feature = "cli", arg(skip = 3u32))]
    pub max_depth: u32,
    /// SH order of the diffuse part (default 5; `--sh-order`).
    #[cfg_attr(feature = "cli", arg(skip = 5usize))]
    pub diffuse_order: usize,
    /// Views below this elevation (degrees) over the shading horizon are clamped to it.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgBakeSettings::default().horizon_deg, allow_hyphen_values = true))]
    pub horizon_deg: f32,
    /// Trace visibility (default). `false` bakes every texel above the horizons as visible:
    /// the transport of prefiltered environment mapping, which ignores shadowing (the
    /// baseline of the paper's Fig. 3-5), in the same representation.
    #[serde(default = "yes")]
    #[cfg_attr(
        feature = "cli",
        arg(
            long = "no-visibility",
            action = clap::ArgAction::SetFalse,
            help = "Ignore visibility: bake the transport of prefiltered environment mapping (no shadowing), the baseline of Green 2005's Fig. 3-5"
        )
    )]
    pub visibility: bool,
    /// Gaussians for the direct glossy component, `1..=10`.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgBakeSettings::default().direct_lobes))]
    pub direct_lobes: usize,
    /// Gaussians for the indirect glossy component, `0..=10` (0: no indirect component).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = SgBakeSettings::default().indirect_lobes))]
    pub indirect_lobes: usize,
    /// Fit settings.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub fit: SgFitSettings,
    /// Seed of all random numbers (the bake is deterministic for a seed, any thread count;
    /// `--seed`).
    #[cfg_attr(feature = "cli", arg(skip))]
    pub seed: u64,
    /// Worker threads; `None` = all cores. Not recorded.
    #[serde(skip)]
    #[cfg_attr(feature = "cli", arg(skip))]
    pub threads: Option<usize>,
    /// Show a progress bar on stderr. Not recorded.
    #[serde(skip)]
    #[cfg_attr(feature = "cli", arg(skip))]
    pub progress: bool,
}

fn yes() -> bool {
    true
}

/// Bake the SG transport of a mesh: tabulate ([`transport`]) and fit ([`fit`]) every vertex
/// and view, plus the diffuse SH part.
///
/// `materials` is the scene's per-triangle material list (indexed by `mesh.material_ids`);
/// each vertex takes the material of its triangles ([`transport::vertex_materials`]) unless
/// `vertex_materials` overrides it (spatially varying BRDFs, thesis section 2.3.1).
///
/// # Errors
/// [`crate::BakeError::Settings`] for out-of-range settings, [`crate::BakeError::Scene`] for
/// an inconsistent mesh.
pub fn bake(
    mesh: &relight_scene::mesh::TriMesh,
    materials: &[Material],
    vertex_materials: Option<&[Material]>,
    caster: &dyn relight_scene::accel::RayCaster,
    settings: &SgBakeSettings,
) -> Result<SgBake, crate::BakeError> {
    let (ctx, vm) = context(mesh, materials, vertex_materials, caster, settings)?;
    let progress =
        crate::transport::progress_bar(settings.progress, mesh.vertex_count() as u64, "sg bake");
    let fitted = crate::transport::with_threads(settings.threads, || {
        fit::fit_mesh(&ctx, &mesh.indices, &fit_config(settings), &progress)
    })?;
    progress.finish_and_clear();
    Ok(assemble(settings, mesh.vertex_count(), fitted, vm))
}

/// The flood-fill regions of `mesh` under `settings` ([`fit::RegionPlan`]): the unit that a
/// sharded bake splits.
pub fn region_plan(
    mesh: &relight_scene::mesh::TriMesh,
    settings: &SgBakeSettings,
) -> fit::RegionPlan {
    fit::RegionPlan::new(mesh.vertex_count(), &mesh.indices, &settings.fit)
}

/// Part of an SG bake: the fits of the vertices of some flood-fill regions, before the regions
/// are aligned ([`fit::PartFit`]), with those vertices' materials (same order).
#[derive(Clone, Debug, PartialEq)]
pub struct SgPart {
    /// The fits, rows in ascending vertex order.
    pub fit: fit::PartFit,
    /// The material of each vertex of `fit.vertices`.
    pub materials: Vec<Material>,
}

/// Bake the regions `regions` of `plan` (which must be [`region_plan`] of the same mesh and
/// settings): what one part of a sharded bake runs. [`finish_parts`] turns the parts into the
/// bake [`bake`] would have made, bit for bit.
///
/// # Errors
/// As [`bake`], and [`crate::BakeError::Settings`] when relaxation is asked (it refits
/// vertices across region borders after the fill, so it needs the whole mesh) or the
/// regions are out of range.
pub fn bake_regions(
    mesh: &relight_scene::mesh::TriMesh,
    materials: &[Material],
    vertex_materials: Option<&[Material]>,
    caster: &dyn relight_scene::accel::RayCaster,
    settings: &SgBakeSettings,
    plan: &fit::RegionPlan,
    regions: std::ops::Range<usize>,
) -> Result<SgPart, crate::BakeError> {
    if settings.fit.relax_sweeps > 0 {
        return Err(crate::BakeError::Settings(format!(
            "an sg bake with {} relaxation sweeps cannot be split: relaxation refits vertices across region borders after the whole fill (use --relax-sweeps 0)",
            settings.fit.relax_sweeps
        )));
    }
    if regions.start > regions.end || regions.end > plan.region_count() {
        return Err(crate::BakeError::Settings(format!(
            "regions {regions:?} are not inside the mesh's {} flood-fill regions",
            plan.region_count()
        )));
    }
    let (ctx, vm) = context(mesh, materials, vertex_materials, caster, settings)?;
    let vertices = plan.vertices(regions.clone());
    let progress =
        crate::transport::progress_bar(settings.progress, vertices.len() as u64, "sg bake (part)");
    let fit = crate::transport::with_threads(settings.threads, || {
        fit::fit_regions(&ctx, plan, &fit_config(settings), regions, &progress)
    })?;
    progress.finish_and_clear();
    debug_assert_eq!(fit.vertices, vertices);
    let materials = fit.vertices.iter().map(|&x| vm[x as usize]).collect();
    Ok(SgPart { fit, materials })
}

/// The whole bake from parts that together hold every vertex of `mesh` once (each from
/// [`bake_regions`] with the same `settings`): regions aligned, flips counted, statistics
/// computed, exactly as [`bake`] does after its fill.
///
/// # Errors
/// [`crate::BakeError::Settings`] naming what does not fit: a vertex in two parts or in
/// none, parts of different layouts, or relaxation asked.
pub fn finish_parts(
    mesh: &relight_scene::mesh::TriMesh,
    settings: &SgBakeSettings,
    parts: Vec<SgPart>,
) -> Result<SgBake, crate::BakeError> {
    let bad = |m: String| crate::BakeError::Settings(format!("sg parts: {m}"));
    if settings.fit.relax_sweeps > 0 {
        return Err(bad("relaxation needs the whole mesh".into()));
    }
    let nv = mesh.vertex_count();
    let mut materials: Vec<(u32, Material)> = parts
        .iter()
        .flat_map(|p| {
            p.fit
                .vertices
                .iter()
                .copied()
                .zip(p.materials.iter().copied())
        })
        .collect();
    materials.sort_unstable_by_key(|m| m.0);
    let whole = fit::PartFit::join(parts.into_iter().map(|p| p.fit).collect()).map_err(bad)?;
    if whole.vertices.len() != nv
        || whole
            .vertices
            .iter()
            .enumerate()
            .any(|(i, &x)| x as usize != i)
    {
        return Err(bad(format!(
            "they hold {} distinct vertices, not the mesh's {nv}",
            whole.vertices.len()
        )));
    }
    let plan = region_plan(mesh, settings);
    let fitted = fit::finish::<transport::TransportContext>(
        &plan,
        &fit_config(settings),
        settings.resolutions(),
        whole,
        None,
        &indicatif::ProgressBar::hidden(),
    );
    let vm = materials.into_iter().map(|m| m.1).collect();
    Ok(assemble(settings, nv, fitted, vm))
}

/// The transport of a bake and the material of each vertex.
fn context<'a>(
    mesh: &'a relight_scene::mesh::TriMesh,
    materials: &[Material],
    vertex_materials: Option<&[Material]>,
    caster: &'a dyn relight_scene::accel::RayCaster,
    settings: &SgBakeSettings,
) -> Result<(transport::TransportContext<'a>, Vec<Material>), crate::BakeError> {
    settings.validate()?;
    let vm = match vertex_materials {
        Some(v) => v.to_vec(),
        None => {
            crate::transport::check_mesh(mesh, materials)?;
            transport::vertex_materials(mesh, materials)
        }
    };
    let ctx = transport::TransportContext::new(mesh, vm.clone(), caster, settings)?;
    Ok((ctx, vm))
}

fn fit_config(settings: &SgBakeSettings) -> fit::FitConfig {
    fit::FitConfig {
        direct_lobes: settings.direct_lobes,
        indirect_lobes: settings.indirect_lobes,
        fit: settings.fit,
    }
}

/// The bake from the fit of all `nv` vertices.
fn assemble(
    settings: &SgBakeSettings,
    nv: usize,
    fitted: fit::MeshFit,
    vm: Vec<Material>,
) -> SgBake {
    let order = (fitted.diffuse_stride as f64).sqrt().round() as usize;
    debug_assert!(nv == 0 || order * order == fitted.diffuse_stride);
    SgBake {
        view_frequency: VIEW_FREQUENCY,
        direct: fitted.direct,
        indirect: fitted.indirect,
        diffuse: ShTransfer {
            order: if nv == 0 {
                settings.diffuse_order
            } else {
                order
            },
            kind: crate::sh::ShTransferKind::Shadowed,
            vertex_count: nv,
            channels: 1,
            data: fitted.diffuse_sh,
        },
        materials: vm,
        stats: fitted.stats,
        kernel: settings.fit.lobe_kernel.kernel(),
        domain: settings.fit.lobe_domain,
        horizon_deg: settings.horizon_deg,
        lobe_order: settings.fit.lobe_order,
    }
}
