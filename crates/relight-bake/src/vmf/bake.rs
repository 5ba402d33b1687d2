//! The vMF bake over views (paper sections 4.2 and 6.1): for every vertex, one
//! [`TransferSlice`] per view of an icosahedral level: `view_level` for every vertex, or with
//! `angular_threshold > 0` the level the adaptive angular refinement of section 4.2 chose for
//! it between `min_view_level` and `view_level` ([`super::refine`]). The adaptive spatial
//! refinement (section 4.3) is [`super::spatial::bake_refined`].
//!
//! # Views
//! The views are the vertices of the geodesic icosahedron of subdivision level `view_level`
//! (frequency `2^level`, [`Icosphere`]; level 0 is the icosahedron, the paper refines up to
//! level 5) that lie strictly above the horizon, `z > 0`, **in the local frame** of each
//! vertex (the paper's section 4.3: the BRDF then has the same shape for a view at every
//! vertex). Views at or below the horizon see nothing of a one-sided surface and are not
//! baked (level 0 gives 4 views: the icosahedron has 4 vertices exactly on the horizon;
//! level 1 gives 17).
//!
//! # Layout and determinism
//! Slices are stored vertex after vertex ([`VmfBake`]); in a fixed-level bake that is
//! `slices[x * view_count + v]`. The slice of vertex `x` and view `v` of level `l` draws its
//! random numbers from `Rng::new(seed, slice_stream(x, l, v))` only ([`super::slice::trace_slice`],
//! [`slice_stream`]), so a bake depends on the seed, never on the threads. A vertex's point is its position, its
//! normalised shading normal, its area-weighted geometric normal
//! ([`crate::transport::vertex_geometric_normals`]) and its material
//! ([`crate::sg::transport::vertex_materials`] unless given per vertex). A part of the
//! vertices ([`bake_vertices`]) is therefore exactly that part of the whole bake (sharding).

use super::refine::{level_view, slice_stream, Refiner, LEVEL_VIEWS};
use super::slice::{
    trace_slice_with, PathClass, SliceScene, SliceSettings, SurfacePoint, TransferSlice,
};
use super::{MaterialLobes, Term};
use crate::transport::{
    check_mesh, check_mesh_geometry, progress_bar, vertex_geometric_normals, with_threads,
};
use crate::BakeError;
use glam::Vec3;
use rayon::prelude::*;
use relight_scene::accel::RayCaster;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_sphere::icosphere::Icosphere;
use relight_sphere::vmf::KappaEstimate;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

/// Largest icosahedral level of the views (the paper's maximum, section 6.1).
pub const MAX_VIEW_LEVEL: u32 = 5;

/// Settings of the vMF bake: what a `vmf` bundle records (serde) and, with the `cli` feature,
/// the options of `relight bake --method vmf`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(
    feature = "cli",
    command(next_help_heading = "vMF bake (--method vmf)")
)]
pub struct VmfBakeSettings {
    /// Icosahedral subdivision level of the views, `0..=5` (frequency `2^level`; level 1
    /// has 42 vertices on the sphere, 17 of them strictly above the horizon): every vertex's
    /// level, or with `--angular-threshold` the finest level a vertex may reach.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().view_level))]
    pub view_level: u32,
    /// Adaptive angular refinement (paper section 4.2): refine a vertex's views level by level
    /// from `--min-view-level` up to `--view-level` until the mean L2 distance (1/sr) between
    /// the next level's slices and their interpolation from the current level falls below this
    /// threshold. 0: off, every vertex at `--view-level`.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().angular_threshold))]
    pub angular_threshold: f32,
    /// The coarsest view level of the adaptive refinement, `0..=view_level`.
    #[serde(default = "default_min_view_level")]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().min_view_level))]
    pub min_view_level: u32,
    /// Adaptive spatial refinement (paper section 4.3): split triangles (1 to 4, at their
    /// edges' midpoints) while the largest mean L2 distance (1/sr) between the transfer of
    /// two of their vertices exceeds this threshold. 0: off, the scene's mesh as it is. The
    /// refined mesh is stored in the bundle and rendered; such a bake cannot be sharded.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().spatial_threshold))]
    pub spatial_threshold: f32,
    /// Smallest area of a triangle the spatial refinement splits, as a fraction of the
    /// input mesh's mean triangle area, in `(0, 1]` (1/64: at most three levels of splits
    /// of an average triangle, forced splits of neighbours aside).
    #[serde(default = "default_spatial_min_area")]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().spatial_min_area))]
    pub spatial_min_area: f32,
    /// Triangles split per iteration of the spatial refinement, those of largest error first
    /// (the paper: 200), at least 1.
    #[serde(default = "default_spatial_batch")]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().spatial_batch))]
    pub spatial_batch: u32,
    /// Paths per (vertex, view) slice.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().paths))]
    pub paths: u32,
    /// Scatterings after the vertex (0: direct only; the paper's 1; `--bounces`).
    #[cfg_attr(feature = "cli", arg(skip = 1u32))]
    pub max_bounces: u32,
    /// Samples per term for fitting the eq. 9 lobes of a vertex's material.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().material_samples))]
    pub material_samples: u32,
    /// SH order of the diffuse term's transfer, `0..=10` (0: the diffuse term as vMF lobes,
    /// as the paper; `n`: `n^2` RGB coefficients per vertex, `super::diffuse_sh`). Default
    /// 5, chosen by measurement (docs/RESULTS.md, section vmf).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().diffuse_sh_order))]
    pub diffuse_sh_order: u32,
    /// Largest concentration of a slice lobe (finite, `>= 1`).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = VmfBakeSettings::default().kappa_max))]
    pub kappa_max: f32,
    /// Seed of all random numbers (`--seed`).
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

/// The default coarsest level of the adaptive refinement: level 1 (17 views; level 0 has only
/// 4 views above the horizon).
fn default_min_view_level() -> u32 {
    1
}

/// The default smallest area of a split triangle: 1/64 of the input's mean.
fn default_spatial_min_area() -> f32 {
    1.0 / 64.0
}

/// The default number of triangles split per iteration: the paper's 200 (section 6.1).
fn default_spatial_batch() -> u32 {
    200
}

impl Default for VmfBakeSettings {
    /// Level 1 views, no adaptive refinement (coarsest level 1 when it is on), the slice defaults of [`SliceSettings::default`] (1024 paths, one
    /// bounce, 1024 material samples, `kappa_max = 1e4`), seed 0, all cores, no progress bar.
    fn default() -> Self {
        let s = SliceSettings::default();
        VmfBakeSettings {
            view_level: 1,
            angular_threshold: 0.0,
            min_view_level: default_min_view_level(),
            spatial_threshold: 0.0,
            spatial_min_area: default_spatial_min_area(),
            spatial_batch: default_spatial_batch(),
            diffuse_sh_order: 5,
            paths: s.paths,
            max_bounces: s.max_bounces,
            material_samples: s.material_samples,
            kappa_max: s.kappa_max,
            seed: 0,
            threads: None,
            progress: false,
        }
    }
}

impl VmfBakeSettings {
    /// The settings of each slice.
    pub fn slice_settings(&self) -> SliceSettings {
        SliceSettings {
            paths: self.paths,
            max_bounces: self.max_bounces,
            material_samples: self.material_samples,
            kappa_max: self.kappa_max,
        }
    }

    /// Check the ranges documented on each field (and [`SliceSettings::validate`]).
    ///
    /// # Errors
    /// [`BakeError::Settings`] naming the offending setting.
    pub fn validate(&self) -> Result<(), BakeError> {
        if self.view_level > MAX_VIEW_LEVEL {
            return Err(BakeError::Settings(format!(
                "view_level {} is not in 0..={MAX_VIEW_LEVEL}",
                self.view_level
            )));
        }
        if !(self.angular_threshold.is_finite() && self.angular_threshold >= 0.0) {
            return Err(BakeError::Settings(format!(
                "angular_threshold {} must be finite and >= 0",
                self.angular_threshold
            )));
        }
        if !(self.spatial_threshold.is_finite() && self.spatial_threshold >= 0.0) {
            return Err(BakeError::Settings(format!(
                "spatial_threshold {} must be finite and >= 0",
                self.spatial_threshold
            )));
        }
        if !(self.spatial_min_area > 0.0 && self.spatial_min_area <= 1.0) {
            return Err(BakeError::Settings(format!(
                "spatial_min_area {} is not in (0, 1]",
                self.spatial_min_area
            )));
        }
        if self.spatial_batch == 0 {
            return Err(BakeError::Settings(
                "spatial_batch must be at least 1".into(),
            ));
        }
        if self.diffuse_sh_order > super::diffuse_sh::MAX_DIFFUSE_SH_ORDER {
            return Err(BakeError::Settings(format!(
                "diffuse_sh_order {} is not in 0..={}",
                self.diffuse_sh_order,
                super::diffuse_sh::MAX_DIFFUSE_SH_ORDER
            )));
        }
        if self.angular_threshold > 0.0 && self.min_view_level > self.view_level {
            return Err(BakeError::Settings(format!(
                "min_view_level {} is above view_level {}",
                self.min_view_level, self.view_level
            )));
        }
        self.slice_settings().validate()
    }

    /// The views of `view_level` (local frame, unit, `z > 0`; module docs).
    ///
    /// # Panics
    /// Debug builds assert a valid level.
    pub fn views(&self) -> Vec<Vec3> {
        views_of_level(self.view_level)
    }

    /// The lowest and highest view level a vertex of this bake may have: both
    /// `view_level` for a fixed-level bake, `min_view_level..=view_level` with adaptive
    /// refinement.
    pub fn level_range(&self) -> (u32, u32) {
        if self.angular_threshold > 0.0 {
            (self.min_view_level, self.view_level)
        } else {
            (self.view_level, self.view_level)
        }
    }
}

/// The views of icosahedral level `level` (local frame, unit, `z > 0`, in [`Icosphere`]
/// vertex order; module docs).
///
/// # Panics
/// Debug builds assert `level <= MAX_VIEW_LEVEL`.
pub fn views_of_level(level: u32) -> Vec<Vec3> {
    debug_assert!(level <= MAX_VIEW_LEVEL);
    Icosphere::new(1 << level)
        .vertices()
        .iter()
        .copied()
        .filter(|v| v.z > 0.0)
        .collect()
}

/// Number of views of icosahedral level `level` ([`views_of_level`]), for every level up
/// to [`MAX_VIEW_LEVEL`] (index = level).
pub fn view_counts() -> [usize; MAX_VIEW_LEVEL as usize + 1] {
    std::array::from_fn(|l| views_of_level(l as u32).len())
}

/// A vMF bake of some vertices (all of a mesh, or a part of a sharded bake): each vertex has
/// its own icosahedral level of views (section 4.2; the fixed-level bake gives every vertex
/// `settings.view_level`) and one transfer slice per view of that level, in the order of
/// [`views_of_level`]. Rows are stored flat: the slices of the `i`-th vertex of the bake are
/// `slices[offsets[i]..offsets[i + 1]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct VmfBake {
    /// The settings it was baked with.
    pub settings: VmfBakeSettings,
    /// The icosahedral level of each vertex's views, `<= settings.view_level`.
    pub levels: Vec<u8>,
    /// `levels.len() + 1` offsets into `slices`, from 0, non-decreasing.
    pub offsets: Vec<usize>,
    /// The slices, vertex after vertex.
    pub slices: Vec<TransferSlice>,
    /// The diffuse term's SH transfer, `order^2` RGB coefficients per vertex
    /// (`settings.diffuse_sh_order`; empty when 0): [`super::diffuse_sh`].
    pub diffuse_sh: Vec<Vec3>,
}

/// An invariant of a [`VmfBake`] that does not hold ([`VmfBake::validate`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("invalid vMF bake: {0}")]
pub struct InvalidVmfBake(pub String);

impl VmfBake {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.levels.len()
    }

    /// The slices of the `x`-th vertex of the bake, in the order of
    /// `views_of_level(levels[x])`.
    ///
    /// # Panics
    /// If `x` is out of range.
    pub fn vertex_slices(&self, x: usize) -> &[TransferSlice] {
        &self.slices[self.offsets[x]..self.offsets[x + 1]]
    }

    /// The slice of vertex `x` and view `v` (of its level).
    ///
    /// # Panics
    /// If `x` or `v` is out of range.
    pub fn slice(&self, x: usize, v: usize) -> &TransferSlice {
        let s = self.vertex_slices(x);
        assert!(v < s.len(), "view {v} of {}", s.len());
        &s[v]
    }

    /// Append the vertices of `other` (a later part of the same bake) after these.
    pub fn append(&mut self, other: VmfBake) {
        let base = self.slices.len();
        self.levels.extend_from_slice(&other.levels);
        self.offsets
            .extend(other.offsets.iter().skip(1).map(|&o| o + base));
        self.slices.extend(other.slices);
        self.diffuse_sh.extend(other.diffuse_sh);
    }

    /// Check every invariant: valid settings, one level per vertex within the settings'
    /// (all equal to `view_level` unless the bake is adaptive), offsets from 0 that give each
    /// vertex as many slices as its level has views, every lobe with a unit axis, a finite
    /// `kappa` in `[0, kappa_max]` and a finite non-negative amplitude.
    ///
    /// # Errors
    /// The first invariant that fails.
    pub fn validate(&self) -> Result<(), InvalidVmfBake> {
        let err = |m: String| Err(InvalidVmfBake(m));
        if let Err(e) = self.settings.validate() {
            return err(e.to_string());
        }
        if self.offsets.len() != self.levels.len() + 1 || self.offsets[0] != 0 {
            return err(format!(
                "{} offsets for {} vertices (need one more, from 0)",
                self.offsets.len(),
                self.levels.len()
            ));
        }
        if self.offsets[self.levels.len()] != self.slices.len() {
            return err(format!(
                "offsets end at {} but there are {} slices",
                self.offsets[self.levels.len()],
                self.slices.len()
            ));
        }
        let counts = view_counts();
        let (lo, hi) = self.settings.level_range();
        for (x, &l) in self.levels.iter().enumerate() {
            if !(lo..=hi).contains(&u32::from(l)) {
                return err(format!("vertex {x}: view level {l} is not in {lo}..={hi}"));
            }
            let (a, b) = (self.offsets[x], self.offsets[x + 1]);
            if b < a || b - a != counts[l as usize] {
                return err(format!(
                    "vertex {x}: {} slices for the {} views of level {l}",
                    b.wrapping_sub(a) as isize,
                    counts[l as usize]
                ));
            }
        }
        let sh = self.diffuse_sh_len() * usize::from(self.settings.diffuse_sh_order > 0);
        if self.diffuse_sh.len() != sh * self.levels.len() {
            return err(format!(
                "{} diffuse SH coefficients for {} vertices of {sh}",
                self.diffuse_sh.len(),
                self.levels.len()
            ));
        }
        if let Some(c) = self.diffuse_sh.iter().find(|c| !c.is_finite()) {
            return err(format!("diffuse SH coefficient {c}"));
        }
        for (i, s) in self.slices.iter().enumerate() {
            for t in Term::ALL {
                for c in PathClass::ALL {
                    let l = s.lobe(t, c);
                    if (l.axis.length() - 1.0).abs() > 1e-4 {
                        return err(format!("slice {i} {t:?} {c:?}: axis {}", l.axis));
                    }
                    if !(l.kappa >= 0.0 && l.kappa <= self.settings.kappa_max) {
                        return err(format!("slice {i} {t:?} {c:?}: kappa {}", l.kappa));
                    }
                    if !l.amplitude.is_finite() || l.amplitude.min_element() < 0.0 {
                        return err(format!("slice {i} {t:?} {c:?}: amplitude {}", l.amplitude));
                    }
                }
            }
        }
        Ok(())
    }
}

/// Bake the slices of every vertex of `mesh` for the views of `settings.view_level`, on all
/// cores (or `settings.threads`), with a progress bar if `settings.progress`.
///
/// `materials` is the scene's per-triangle material list (indexed by `mesh.material_ids`);
/// each vertex takes the material of its first triangle unless `vertex_materials` gives one
/// per vertex. Paths scatter with the same per-vertex materials.
///
/// # Errors
/// [`BakeError::Settings`] for out-of-range settings; [`BakeError::Scene`] for an
/// inconsistent mesh or a material out of range; [`BakeError::Memory`] if the slices would
/// not fit in memory; [`BakeError::Threads`].
pub fn bake(
    mesh: &TriMesh,
    materials: &[Material],
    vertex_materials: Option<&[Material]>,
    caster: &dyn RayCaster,
    settings: &VmfBakeSettings,
) -> Result<VmfBake, BakeError> {
    bake_vertices(
        mesh,
        materials,
        vertex_materials,
        caster,
        settings,
        0..mesh.vertex_count(),
    )
}

/// The bake of the vertices `vertices` only, as [`bake`] computes them: each vertex is seeded
/// by its index in the whole mesh, so the parts of a sharded bake concatenate
/// ([`VmfBake::append`]) to the whole bake exactly.
///
/// # Errors
/// As [`bake`], and [`BakeError::Settings`] for a range outside the mesh.
pub fn bake_vertices(
    mesh: &TriMesh,
    materials: &[Material],
    vertex_materials: Option<&[Material]>,
    caster: &dyn RayCaster,
    settings: &VmfBakeSettings,
    vertices: Range<usize>,
) -> Result<VmfBake, BakeError> {
    let per_vertex = checked_vertex_materials(mesh, materials, vertex_materials, settings)?;
    if vertices.start > vertices.end || vertices.end > mesh.vertex_count() {
        return Err(BakeError::Settings(format!(
            "vertex range {vertices:?} is not within 0..{}",
            mesh.vertex_count()
        )));
    }
    let (_, hi) = settings.level_range();
    let nv = view_counts()[hi as usize];
    crate::check_memory(
        vertices.len() as u128 * nv as u128 * std::mem::size_of::<TransferSlice>() as u128,
    )?;
    let ng = vertex_geometric_normals(mesh);
    let baker = PointBaker::new(mesh, caster, &per_vertex, settings);
    let progress = progress_bar(settings.progress, vertices.len() as u64, "vmf bake");
    let rows: Vec<VertexRow> = with_threads(settings.threads, || {
        vertices
            .into_par_iter()
            .map(|x| {
                let point = SurfacePoint {
                    position: mesh.positions[x],
                    normal: mesh.normals[x].normalize_or_zero(),
                    geometric_normal: ng[x],
                    material: per_vertex[x],
                };
                let row = baker.bake_point(x, &point);
                progress.inc(1);
                if x % 16 == 0 {
                    baker.report(&progress);
                }
                row
            })
            .collect()
    })?;
    progress.finish_and_clear();
    Ok(VmfBake::from_rows(*settings, rows))
}

/// The per-vertex materials of a bake (given, or those of each vertex's first triangle),
/// after checking the settings, the mesh and every material.
pub(crate) fn checked_vertex_materials(
    mesh: &TriMesh,
    materials: &[Material],
    vertex_materials: Option<&[Material]>,
    settings: &VmfBakeSettings,
) -> Result<Vec<Material>, BakeError> {
    settings.validate()?;
    let per_vertex = match vertex_materials {
        Some(m) => {
            check_mesh_geometry(mesh)?;
            if m.len() != mesh.vertex_count() {
                return Err(BakeError::Scene(format!(
                    "{} vertex materials for {} vertices",
                    m.len(),
                    mesh.vertex_count()
                )));
            }
            m.to_vec()
        }
        None => {
            check_mesh(mesh, materials)?;
            crate::sg::transport::vertex_materials(mesh, materials)
        }
    };
    for (v, m) in per_vertex.iter().enumerate() {
        m.validate()
            .map_err(|e| BakeError::Scene(format!("material of vertex {v}: {e}")))?;
    }
    Ok(per_vertex)
}

impl VmfBake {
    /// A bake of `settings` from per-vertex rows (level, slices).
    pub(crate) fn from_rows(settings: VmfBakeSettings, rows: Vec<VertexRow>) -> Self {
        let levels = rows.iter().map(|(l, _, _)| *l).collect();
        let offsets = std::iter::once(0)
            .chain(rows.iter().scan(0, |o, (_, s, _)| {
                *o += s.len();
                Some(*o)
            }))
            .collect();
        let diffuse_sh = rows
            .iter()
            .flat_map(|(_, _, t)| t.iter().copied())
            .collect();
        VmfBake {
            settings,
            levels,
            offsets,
            slices: rows.into_iter().flat_map(|(_, s, _)| s).collect(),
            diffuse_sh,
        }
    }
}

/// What a vertex bakes to: its view level, its slices, its diffuse SH row (empty when off).
pub(crate) type VertexRow = (u8, Vec<TransferSlice>, Vec<Vec3>);

/// What baking one point needs, shared by all points of a bake: the scene, the view tables,
/// the eq. 9 lobes fitted once per (material, level, view), and the refinement counts shown
/// by the progress bar.
pub(crate) struct PointBaker<'a> {
    scene: SliceScene<'a>,
    refiner: Refiner,
    palette: Vec<Material>,
    lobe_cache: Vec<OnceLock<MaterialLobes>>,
    settings: VmfBakeSettings,
    /// Vertices that reached each level by refining.
    refined: Vec<AtomicU64>,
}

impl<'a> PointBaker<'a> {
    /// The baker of points whose materials are among `per_vertex` (paths scatter by them).
    pub(crate) fn new(
        mesh: &'a TriMesh,
        caster: &'a dyn RayCaster,
        per_vertex: &'a [Material],
        settings: &VmfBakeSettings,
    ) -> Self {
        let (_, hi) = settings.level_range();
        let mut palette: Vec<Material> = vec![];
        for m in per_vertex {
            if !palette.contains(m) {
                palette.push(*m);
            }
        }
        PointBaker {
            scene: SliceScene {
                mesh,
                caster,
                vertex_materials: per_vertex,
            },
            refiner: Refiner::new(hi),
            lobe_cache: (0..palette.len() * LEVEL_VIEWS)
                .map(|_| OnceLock::new())
                .collect(),
            palette,
            settings: *settings,
            refined: (0..=hi).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    /// The refiner (view tables).
    pub(crate) fn refiner(&self) -> &Refiner {
        &self.refiner
    }

    /// The level and slices of vertex `x` (its index seeds its streams) at `point`, whose
    /// material must be one of the baker's.
    pub(crate) fn bake_point(&self, x: usize, point: &SurfacePoint) -> VertexRow {
        let settings = &self.settings;
        let (lo, hi) = settings.level_range();
        let slice_settings = settings.slice_settings();
        let material = self
            .palette
            .iter()
            .position(|p| *p == point.material)
            .expect("a material of the bake");
        // The diffuse SH transfer: the mean projection over every slice computed.
        let order = settings.diffuse_sh_order as usize;
        let sh_on = order > 0 && super::diffuse_sh::separable_diffuse(&point.material);
        let mut sh = vec![
            Vec3::ZERO;
            if order > 0 {
                relight_sphere::sh::sh_count(order)
            } else {
                0
            }
        ];
        let mut norm = 0.0f32;
        let r = self.refiner.refine(
            lo,
            hi,
            settings.angular_threshold,
            |level, v, view| {
                let stream = slice_stream(x, level, v);
                // The eq. 9 lobes of this material and view, fitted once per bake.
                let slot = material * LEVEL_VIEWS + level_view(level, v);
                let lobes = self.lobe_cache[slot].get_or_init(|| {
                    // (normalised as `trace_slice` does, so both give the same bits)
                    MaterialLobes::fit(&point.material, view.normalize(), settings.material_samples)
                });
                let lobes = (view.z > 0.0).then_some(lobes);
                let samples = trace_slice_with(
                    &self.scene,
                    point,
                    view,
                    lobes,
                    &slice_settings,
                    settings.seed,
                    stream,
                );
                if sh_on {
                    let c = super::diffuse_sh::view_factor(&point.material, view.normalize().z);
                    super::diffuse_sh::accumulate(&samples, order, c, &mut sh);
                    norm += c * c;
                }
                samples.estimate(KappaEstimate::Banerjee, settings.kappa_max)
            },
            |level| {
                self.refined[level as usize].fetch_add(1, Ordering::Relaxed);
            },
        );
        // The least-squares fit over the slices (`diffuse_sh` module docs).
        let inv = if norm > 0.0 { 1.0 / norm } else { 0.0 };
        sh.iter_mut().for_each(|c| *c *= inv);
        (r.level as u8, r.slices, sh)
    }

    /// Show the refinement counts so far in `progress`'s message.
    pub(crate) fn report(&self, progress: &indicatif::ProgressBar) {
        let (lo, hi) = self.settings.level_range();
        if lo < hi {
            let counts: Vec<String> = (lo + 1..=hi)
                .map(|l| format!("L{l}:{}", self.refined[l as usize].load(Ordering::Relaxed)))
                .collect();
            progress.set_message(format!("vmf refined {}", counts.join(" ")));
        }
    }
}

#[cfg(test)]
mod tests;
