//! Diffuse SH precomputed radiance transfer (Sloan, Kautz & Snyder 2002; thesis ch. 4.2).
//!
//! ## What a transfer vector is
//!
//! Lighting is a distant environment `L(w)` (radiance arriving from world direction `w`),
//! projected to real SH of order `n` (`n^2` coefficients, conventions of `relight_sphere`):
//! `L_i = ∫ L(w) y_i(w) dw` (thesis eq. 4.2; Sloan 2002 sec. 4). A per-vertex transfer vector
//! `T_p` turns it into outgoing radiance by a dot product, `L_o(p) = sum_i T_p,i L_i`, which is
//! exactly `L_o = ∫ T(w) L(w) dw` for lighting band-limited to order `n`.
//!
//! With `H_p(w) = max(0, n_p . w)` (the clamped cosine around the vertex's unit shading
//! normal), `V_p(w)` the visibility of the environment from `p`, and `rho_p` the vertex's
//! diffuse albedo ([`crate::transport::vertex_albedo`]):
//!
//! | kind | `T_p,i` | albedo | cosine | 1/pi | channels |
//! |---|---|---|---|---|---|
//! | [`ShTransferKind::Unshadowed`] | `(1/pi) ∫ y_i H_p dw` | no | yes | yes | 1 |
//! | [`ShTransferKind::Shadowed`] | `(1/pi) ∫ y_i V_p H_p dw` | no | yes | yes | 1 |
//! | [`ShTransferKind::Interreflected`] | `sum_{k=0..=b} T^k_p,i` (below) | yes | yes | yes | 3 (RGB) |
//!
//! These are the diffuse transfers of Sloan et al. 2002, sec. 5 (unshadowed, shadowed,
//! interreflected), without the albedo for the single-channel kinds: multiply by `rho_p` at
//! render time (`L_o = rho_p sum_i T_p,i L_i`), so albedo stays editable after the bake. With
//! `L = 1` everywhere and no occlusion, `L_o = rho_p`.
//!
//! Interreflected transfer is the truncated Neumann series of the thesis (eq. 2.31,
//! `L = sum_k T^k E`, and its Figure 4.2 PRECOMPUTE-RADIOSITY; Sloan 2002 sec. 6's
//! interreflection passes), per colour channel `c`:
//! * `T^0_p = rho_p,c (1/pi) ∫ y_i V_p H_p dw` (direct, shadowed);
//! * `T^{k+1}_p = rho_p,c (1/pi) ∫ Tbar^k(q(p, w)) (1 - V_p(w)) H_p(w) dw`, where `q(p, w)`
//!   is the closest hit of the ray from `p` in direction `w` and `Tbar^k(q)` interpolates
//!   bounce `k`'s transfer of the hit triangle's vertices with the hit's barycentrics
//!   (the field-radiance operator G of thesis eq. 2.24 followed by the local reflection R of
//!   eq. 2.25). Surfaces are one-sided, as in Mitsuba: a ray hitting a triangle's back
//!   (`n_g . w >= 0`) gathers nothing, but still blocks the environment.
//!
//! ## How it is computed
//!
//! * Unshadowed transfer is exact, in closed form (Ramamoorthi & Hanrahan 2001, eq. 7,
//!   `E(n) = sum_lm A_l L_lm Y_lm(n)`, divided by pi): `T_p,lm = (A_l / pi) y_lm(n_p)` with
//!   the clamped-cosine coefficients of their eqs. 8-9 (`A_0 = pi`, `A_1 = 2 pi / 3`,
//!   `A_2 = pi / 4`, zero for odd `l > 1`; `relight_sphere::sh::clamped_cosine_zonal`).
//!   No rays, no noise.
//! * Shadowed and interreflected transfer are Monte Carlo integrals with `samples` cosine-
//!   weighted directions per vertex (pdf `H_p / pi`, so each sample weighs `1 / samples`): a
//!   Hammersley set with a per-vertex Cranley-Patterson rotation
//!   ([`crate::transport::VertexSamples`]). Rays start at the vertex, offset along its
//!   area-weighted geometric normal (Wächter & Binder 2019). Every pass of the Neumann series
//!   uses the same directions: the first pass keeps its front-facing hits (12 bytes each, up
//!   to 1 GiB in the worst case) and the others gather from them without casting rays; bigger
//!   bakes retrace the rays instead, with identical results. The result depends on the seed
//!   only, not on the threads.
//!
//! ## Layout of [`ShTransfer::data`]
//!
//! Vertex-major, coefficient-major inside, channel innermost:
//! `data[(v * n^2 + i) * channels + c]`. Relighting a frame reads it once, front to back, each
//! vertex's `n^2 * channels` floats contiguous beside its neighbours', while the light vector
//! (`n^2` RGB values, under 1.2 KB for order 10) stays in L1: one sequential stream, which is
//! what makes the per-frame cost memory-bandwidth bound (see `relight_render::shade_sh`).

use crate::transport::{
    check_mesh, progress_bar, surface_ray, vertex_albedo, vertex_geometric_normals, with_threads,
    VertexSamples,
};
use crate::{check_memory, BakeError};
use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use relight_scene::accel::{Ray, RayCaster};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_sphere::sh::{clamped_cosine_zonal, eval_sh, sh_count, MAX_ORDER};
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;
use std::ops::Range;

/// Which diffuse transfer to bake (Sloan et al. 2002, sec. 5). A closed set; the number of
/// interreflection bounces is [`ShBakeSettings::bounces`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ShTransferKind {
    /// Cosine only, no visibility (closed form, exact). Single channel, albedo excluded.
    Unshadowed,
    /// Cosine and visibility of the environment. Single channel, albedo excluded.
    Shadowed,
    /// Shadowed transfer plus `bounces` diffuse interreflections (Neumann series). RGB,
    /// albedo included (colour bleeding from per-vertex albedo).
    Interreflected,
}

impl ShTransferKind {
    /// Channels of the transfer: 1 (albedo excluded) or 3 (RGB, albedo included).
    pub fn channels(&self) -> usize {
        match self {
            ShTransferKind::Unshadowed | ShTransferKind::Shadowed => 1,
            ShTransferKind::Interreflected => 3,
        }
    }

    /// The name used in settings and on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            ShTransferKind::Unshadowed => "unshadowed",
            ShTransferKind::Shadowed => "shadowed",
            ShTransferKind::Interreflected => "interreflected",
        }
    }
}

/// Settings of [`bake`]: what a bundle records of an `sh` bake (serde, field names as the
/// bundle's `settings` metadata since format 1), and, with the `cli` feature, the options of
/// `relight bake --method sh`. The SH order, bounces and seed are shared with other methods
/// on the command line, so they are not options of this struct there.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "cli", command(next_help_heading = "SH bake (--method sh)"))]
pub struct ShBakeSettings {
    /// SH order `n` (bands `0..n`, `n^2` coefficients), `1..=relight_sphere::sh::MAX_ORDER`.
    #[cfg_attr(feature = "cli", arg(skip = 5usize))]
    pub order: usize,
    /// Transfer: unshadowed, shadowed or interreflected (Sloan 2002 sec. 5).
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = ShTransferKind::Shadowed))]
    pub transfer: ShTransferKind,
    /// Interreflection bounces after the direct one (`Interreflected` only, else 0),
    /// `0..=MAX_BOUNCES`.
    #[cfg_attr(feature = "cli", arg(skip))]
    pub bounces: u32,
    /// Directions per vertex (and per Neumann pass), `>= 1`. Ignored by `unshadowed`.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1024))]
    pub samples: u32,
    /// Seed of the per-vertex sample rotations.
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

impl Default for ShBakeSettings {
    /// Order 5, shadowed, 1024 samples, seed 0, all cores, no progress bar.
    fn default() -> Self {
        ShBakeSettings {
            order: 5,
            transfer: ShTransferKind::Shadowed,
            bounces: 0,
            samples: 1024,
            seed: 0,
            threads: None,
            progress: false,
        }
    }
}

impl ShBakeSettings {
    /// Number of passes over all vertices: 0 for the closed form, 1 + bounces otherwise.
    fn ray_passes(&self) -> u64 {
        match self.transfer {
            ShTransferKind::Unshadowed => 0,
            ShTransferKind::Shadowed => 1,
            ShTransferKind::Interreflected => 1 + self.bounces as u64,
        }
    }
}

/// Largest number of Neumann bounces accepted (each costs a full pass of rays; the series
/// has long converged for albedos below 0.9).
pub const MAX_BOUNCES: u32 = 64;

/// Largest number of directions per vertex accepted: 2^20. Beyond it the Monte Carlo noise
/// (`~1/sqrt(samples)`) is far below what the bake's other approximations leave, and each
/// thread keeps one ray per direction (32 bytes each).
pub const MAX_SAMPLES: u32 = 1 << 20;

impl ShBakeSettings {
    /// Check the ranges documented on each field.
    ///
    /// # Errors
    /// [`BakeError::Settings`] naming the offending setting.
    pub fn validate(&self) -> Result<(), BakeError> {
        let err = |m: String| Err(BakeError::Settings(m));
        if !(1..=MAX_ORDER).contains(&self.order) {
            return err(format!("SH order {} is not in 1..={MAX_ORDER}", self.order));
        }
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return err(format!(
                "samples {} is not in 1..={MAX_SAMPLES}",
                self.samples
            ));
        }
        if self.bounces > MAX_BOUNCES {
            return err(format!(
                "{} bounces is more than {MAX_BOUNCES}",
                self.bounces
            ));
        }
        if self.threads == Some(0) {
            return err("threads must be at least 1".into());
        }
        Ok(())
    }
}

/// Baked per-vertex SH transfer (see the module docs for what it includes and its layout).
#[derive(Clone, Debug, PartialEq)]
pub struct ShTransfer {
    /// SH order `n` (`n^2` coefficients per channel).
    pub order: usize,
    /// The transfer kind baked.
    pub kind: ShTransferKind,
    /// Number of vertices.
    pub vertex_count: usize,
    /// 1 = single-channel transfer without albedo; 3 = RGB transfer with albedo.
    pub channels: usize,
    /// `data[(v * n^2 + i) * channels + c]`, length `vertex_count * n^2 * channels`.
    pub data: Vec<f32>,
}

impl ShTransfer {
    /// Coefficients per channel, `n^2`.
    pub fn coeff_count(&self) -> usize {
        sh_count(self.order)
    }

    /// Floats per vertex, `n^2 * channels`.
    pub fn stride(&self) -> usize {
        self.coeff_count() * self.channels
    }

    /// The transfer of vertex `v` (`n^2 * channels` floats, channel innermost).
    #[inline]
    pub fn vertex(&self, v: usize) -> &[f32] {
        let s = self.stride();
        &self.data[v * s..(v + 1) * s]
    }

    /// Outgoing radiance of vertex `v` under SH lighting `light` (RGB coefficients, at least
    /// `n^2`; extra coefficients are ignored). `albedo` multiplies single-channel transfer and
    /// is ignored for RGB transfer, which includes it. A plain reference implementation; the
    /// fast per-frame path is `relight_render::shade_sh::vertex_radiance`.
    ///
    /// # Panics
    /// If `light` has fewer than `n^2` coefficients.
    pub fn eval_vertex(&self, v: usize, albedo: Vec3, light: &[Vec3]) -> Vec3 {
        let n2 = self.coeff_count();
        let t = self.vertex(v);
        match self.channels {
            1 => albedo * (0..n2).map(|i| light[i] * t[i]).sum::<Vec3>(),
            _ => (0..n2)
                .map(|i| light[i] * Vec3::from_slice(&t[3 * i..3 * i + 3]))
                .sum(),
        }
    }

    /// Check every invariant: order in range, channels matching the kind, data length, finite
    /// values.
    ///
    /// # Errors
    /// The first violated invariant.
    pub fn validate(&self) -> Result<(), ShTransferError> {
        if !(1..=MAX_ORDER).contains(&self.order) {
            return Err(ShTransferError::Order(self.order));
        }
        if self.channels != self.kind.channels() {
            return Err(ShTransferError::Channels {
                kind: self.kind,
                channels: self.channels,
            });
        }
        let expected = self.vertex_count * self.stride();
        if self.data.len() != expected {
            return Err(ShTransferError::Length {
                len: self.data.len(),
                vertices: self.vertex_count,
                coeffs: self.coeff_count(),
                channels: self.channels,
            });
        }
        if let Some(k) = self.data.iter().position(|x| !x.is_finite()) {
            return Err(ShTransferError::NonFinite {
                vertex: k / self.stride(),
            });
        }
        Ok(())
    }
}

/// Why an [`ShTransfer`] is inconsistent ([`ShTransfer::validate`]): a corrupt or hand-made
/// transfer, never a fresh bake.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum ShTransferError {
    /// The order is 0 or above [`MAX_ORDER`].
    #[error("order {0} is not in 1..={MAX_ORDER}")]
    Order(usize),
    /// The channel count does not match the kind (1 for unshadowed and shadowed, 3 for
    /// interreflected).
    #[error("{kind:?} transfer must have {} channels, has {channels}", kind.channels())]
    Channels {
        /// The transfer's kind.
        kind: ShTransferKind,
        /// Its channel count.
        channels: usize,
    },
    /// `data` is not `vertices x coeffs x channels` floats long.
    #[error(
        "data has {len} floats, expected {vertices} vertices x {coeffs} coefficients x \
         {channels} channels = {}",
        vertices * coeffs * channels
    )]
    Length {
        /// Floats held.
        len: usize,
        /// Vertex count.
        vertices: usize,
        /// Coefficients per channel, `order^2`.
        coeffs: usize,
        /// Channels.
        channels: usize,
    },
    /// A value is NaN or infinite.
    #[error("non-finite value at vertex {vertex}")]
    NonFinite {
        /// The first vertex holding one.
        vertex: usize,
    },
}

/// Bake per-vertex diffuse SH transfer of `mesh` (materials indexed by `mesh.material_ids`)
/// with rays cast by `caster`, which must have been built over the same `mesh`.
///
/// # Errors
/// Invalid settings, an inconsistent mesh, or a thread pool that cannot be started.
pub fn bake(
    mesh: &TriMesh,
    materials: &[Material],
    caster: &dyn RayCaster,
    settings: &ShBakeSettings,
) -> Result<ShTransfer, BakeError> {
    bake_range(mesh, materials, caster, settings, 0..mesh.vertex_count())
}

/// [`bake`] restricted to the vertices `range`: the transfer of those vertices only
/// (`vertex_count = range.len()`), bit-identical to the same rows of the whole bake, since
/// every vertex's directions depend on the seed and its index only. Unshadowed and shadowed
/// transfer cost `range.len()` vertices; interreflected transfer gathers bounce `k + 1` from
/// bounce `k` of *every* vertex, so its earlier passes run over the whole mesh and only the
/// last is restricted (a sharded interreflected bake saves one pass in `1 + bounces`).
///
/// # Errors
/// As [`bake`], and [`BakeError::Settings`] for a range outside the mesh.
pub fn bake_range(
    mesh: &TriMesh,
    materials: &[Material],
    caster: &dyn RayCaster,
    settings: &ShBakeSettings,
    range: Range<usize>,
) -> Result<ShTransfer, BakeError> {
    bake_with_hit_budget(mesh, materials, caster, settings, range, HIT_BUDGET_BYTES)
}

/// [`bake_range`] with an explicit memory budget for first-pass hits (tests force both
/// paths).
fn bake_with_hit_budget(
    mesh: &TriMesh,
    materials: &[Material],
    caster: &dyn RayCaster,
    settings: &ShBakeSettings,
    range: Range<usize>,
    hit_budget: usize,
) -> Result<ShTransfer, BakeError> {
    settings.validate()?;
    check_mesh(mesh, materials)?;
    if range.start > range.end || range.end > mesh.vertex_count() {
        return Err(BakeError::Settings(format!(
            "vertex range {}..{} is not inside the mesh's {} vertices",
            range.start,
            range.end,
            mesh.vertex_count()
        )));
    }
    check_memory(transfer_bytes(settings, mesh.vertex_count()))?;
    let all = 0..mesh.vertex_count();
    let (passes, pass_range) = match settings.transfer {
        ShTransferKind::Interreflected => (settings.ray_passes(), all.clone()),
        _ => (settings.ray_passes().max(1), range.clone()),
    };
    let pb = progress_bar(
        settings.progress,
        passes * pass_range.len() as u64,
        "SH bake",
    );
    let data = with_threads(settings.threads, || {
        let ctx = Ctx {
            mesh,
            caster,
            order: settings.order,
            n2: sh_count(settings.order),
            samples: settings.samples,
            seed: settings.seed,
            ng: vertex_geometric_normals(mesh),
            hit_budget,
            range: pass_range,
            pb: &pb,
        };
        match settings.transfer {
            ShTransferKind::Unshadowed => ctx.unshadowed(),
            ShTransferKind::Shadowed => ctx.shadowed(),
            ShTransferKind::Interreflected => {
                let stride = 3 * ctx.n2;
                let full = ctx.interreflected(&vertex_albedo(mesh, materials), settings.bounces);
                full[range.start * stride..range.end * stride].to_vec()
            }
        }
    })?;
    pb.finish_and_clear();
    Ok(ShTransfer {
        order: settings.order,
        kind: settings.transfer,
        vertex_count: range.len(),
        channels: settings.transfer.channels(),
        data,
    })
}

/// Vertices per parallel work item (and per progress-bar tick).
const CHUNK: usize = 32;

/// What every pass needs.
struct Ctx<'a> {
    mesh: &'a TriMesh,
    caster: &'a dyn RayCaster,
    order: usize,
    n2: usize,
    samples: u32,
    seed: u64,
    /// Per-vertex geometric normals (ray offsets).
    ng: Vec<Vec3>,
    /// Bytes allowed for keeping first-pass hits (see [`Ctx::interreflected`]).
    hit_budget: usize,
    /// The vertices of every pass (the whole mesh for interreflected transfer).
    range: Range<usize>,
    pb: &'a ProgressBar,
}

impl Ctx<'_> {
    /// Unit shading normal of `v`, `None` if degenerate.
    fn normal(&self, v: usize) -> Option<Vec3> {
        let n = self.mesh.normals[v].normalize_or_zero();
        (n != Vec3::ZERO).then_some(n)
    }

    /// Run `f(v, out, scratch)` for every vertex `v` of the pass range, `out` being its
    /// `stride` floats of a new zeroed array (row `v - range.start`).
    fn per_vertex<S: Send>(
        &self,
        stride: usize,
        init: impl Fn() -> S + Sync + Send,
        f: impl Fn(usize, &mut [f32], &mut S) + Sync + Send,
    ) -> Vec<f32> {
        let mut data = vec![0.0f32; self.range.len() * stride];
        let first = self.range.start;
        data.par_chunks_mut(stride * CHUNK)
            .enumerate()
            .for_each_init(init, |s, (ci, chunk)| {
                for (k, out) in chunk.chunks_exact_mut(stride).enumerate() {
                    f(first + ci * CHUNK + k, out, s);
                }
                self.pb.inc((chunk.len() / stride) as u64);
            });
        data
    }

    /// Closed form of R&H 2001: `T_lm = (A_l / pi) y_lm(n)`.
    fn unshadowed(&self) -> Vec<f32> {
        let a_over_pi: Vec<f32> = (0..self.order)
            .map(|l| clamped_cosine_zonal(l) / PI)
            .collect();
        self.per_vertex(
            self.n2,
            || (),
            |v, out, _| {
                let Some(n) = self.normal(v) else { return };
                eval_sh(self.order, n, out);
                for l in 0..self.order {
                    for x in &mut out[l * l..(l + 1) * (l + 1)] {
                        *x *= a_over_pi[l];
                    }
                }
            },
        )
    }

    /// The rays of vertex `v` (all its sample directions), written to `rays`.
    fn vertex_rays(&self, v: usize, n: Vec3, rays: &mut Vec<Ray>) -> VertexSamples {
        let dirs = VertexSamples::new(self.seed, v, self.samples, n);
        let p = self.mesh.positions[v];
        rays.clear();
        rays.extend((0..self.samples).map(|i| surface_ray(p, self.ng[v], dirs.dir(i))));
        dirs
    }

    /// Single-channel shadowed transfer: `(1/N) sum_k V(w_k) y_i(w_k)` over cosine-weighted
    /// directions (Sloan 2002 sec. 5, shadowed diffuse transfer).
    fn shadowed(&self) -> Vec<f32> {
        let init = || (Vec::new(), Vec::new(), vec![0.0f32; self.n2]);
        self.per_vertex(self.n2, init, |v, out, (rays, occluded, y)| {
            let Some(n) = self.normal(v) else { return };
            self.vertex_rays(v, n, rays);
            occluded.clear();
            occluded.resize(rays.len(), false);
            self.caster.occluded_many(rays, occluded);
            for (ray, &blocked) in rays.iter().zip(occluded.iter()) {
                if !blocked {
                    eval_sh(self.order, ray.dir, y);
                    out.iter_mut().zip(y.iter()).for_each(|(o, &yi)| *o += yi);
                }
            }
            let w = 1.0 / self.samples as f32;
            out.iter_mut().for_each(|o| *o *= w);
        })
    }

    /// RGB interreflected transfer: shadowed times albedo, then `bounces` Neumann passes.
    ///
    /// When the first pass's front-facing hits fit in `hit_budget` bytes (worst case: every
    /// ray hits), it records them and the Neumann passes gather from that list without
    /// casting rays; otherwise every pass retraces the same directions. Both give the same
    /// bits.
    fn interreflected(&self, albedo: &[Vec3], bounces: u32) -> Vec<f32> {
        let stride = 3 * self.n2;
        let worst = self.mesh.vertex_count() as u128
            * self.samples as u128
            * std::mem::size_of::<FrontHit>() as u128;
        // Bounce 0: direct, shadowed, with the receiver's albedo.
        let (mono, hits) = if bounces > 0 && worst <= self.hit_budget as u128 {
            let (mono, hits) = self.shadowed_with_hits();
            (mono, Some(hits))
        } else {
            (self.shadowed(), None)
        };
        let mut prev = vec![0.0f32; self.mesh.vertex_count() * stride];
        for (v, (out, t)) in prev
            .chunks_exact_mut(stride)
            .zip(mono.chunks_exact(self.n2))
            .enumerate()
        {
            for (o3, &ti) in out.chunks_exact_mut(3).zip(t) {
                o3.copy_from_slice(&(albedo[v] * ti).to_array());
            }
        }
        let mut total = prev.clone();
        for _ in 0..bounces {
            let next = match &hits {
                Some(hits) => self.gather_stored(&prev, albedo, hits),
                None => self.gather_traced(&prev, albedo),
            };
            total.iter_mut().zip(&next).for_each(|(t, &x)| *t += x);
            prev = next;
        }
        total
    }

    /// As [`Ctx::shadowed`] (same directions, same sums), with closest-hit rays, also
    /// returning each vertex's front-facing hits in sample order.
    fn shadowed_with_hits(&self) -> (Vec<f32>, Vec<Vec<FrontHit>>) {
        let init = || (Vec::new(), vec![0.0f32; self.n2]);
        let per_vertex: Vec<(Vec<f32>, Vec<FrontHit>)> = (0..self.mesh.vertex_count())
            .into_par_iter()
            .with_min_len(CHUNK)
            .map_init(init, |(rays, y), v| {
                let (mut t, mut hits) = (vec![0.0f32; self.n2], Vec::new());
                if let Some(n) = self.normal(v) {
                    self.vertex_rays(v, n, rays);
                    for ray in rays.iter() {
                        match self.caster.intersect(ray) {
                            None => {
                                eval_sh(self.order, ray.dir, y);
                                t.iter_mut().zip(y.iter()).for_each(|(o, &yi)| *o += yi);
                            }
                            Some(h) if self.front_facing(h.tri, ray.dir) => {
                                hits.push(FrontHit {
                                    tri: h.tri,
                                    u: h.u,
                                    v: h.v,
                                });
                            }
                            Some(_) => {}
                        }
                    }
                    let w = 1.0 / self.samples as f32;
                    t.iter_mut().for_each(|o| *o *= w);
                    hits.shrink_to_fit();
                }
                self.pb.inc(1);
                (t, hits)
            })
            .collect();
        let mut mono = Vec::with_capacity(self.mesh.vertex_count() * self.n2);
        let mut hits = Vec::with_capacity(self.mesh.vertex_count());
        for (t, h) in per_vertex {
            mono.extend_from_slice(&t);
            hits.push(h);
        }
        (mono, hits)
    }

    /// Whether a ray in direction `dir` hits triangle `tri` from its front. Surfaces are
    /// one-sided: the back of a triangle sends nothing.
    #[inline]
    fn front_facing(&self, tri: u32, dir: Vec3) -> bool {
        self.mesh.geometric_normal(tri as usize).dot(dir) < 0.0
    }

    /// Add bounce `k`'s transfer at barycentrics `(u, v)` of `tri` (`Tbar^k(q)`) to `acc`.
    #[inline]
    fn accumulate(&self, prev: &[f32], tri: u32, u: f32, v: f32, acc: &mut [f32]) {
        let stride = acc.len();
        let [a, b, c] = self.mesh.indices[tri as usize].map(|i| i as usize * stride);
        let (wa, wb, wc) = (1.0 - u - v, u, v);
        let (ta, tb, tc) = (
            &prev[a..a + stride],
            &prev[b..b + stride],
            &prev[c..c + stride],
        );
        for k in 0..stride {
            acc[k] += wa * ta[k] + wb * tb[k] + wc * tc[k];
        }
    }

    /// `out = rho (1/N) acc` per channel.
    #[inline]
    fn finish_gather(&self, acc: &[f32], rho: Vec3, out: &mut [f32]) {
        let w = rho / self.samples as f32;
        for (o3, a3) in out.chunks_exact_mut(3).zip(acc.chunks_exact(3)) {
            o3[0] = a3[0] * w.x;
            o3[1] = a3[1] * w.y;
            o3[2] = a3[2] * w.z;
        }
    }

    /// One Neumann pass, `T^{k+1}_p = rho_p (1/N) sum_k [front hit] Tbar^k(hit)`, from the
    /// hits kept by [`Ctx::shadowed_with_hits`].
    fn gather_stored(&self, prev: &[f32], albedo: &[Vec3], hits: &[Vec<FrontHit>]) -> Vec<f32> {
        let stride = 3 * self.n2;
        self.per_vertex(
            stride,
            || vec![0.0f32; stride],
            |v, out, acc| {
                if albedo[v] == Vec3::ZERO || self.normal(v).is_none() {
                    return; // reflects nothing
                }
                acc.fill(0.0);
                for h in &hits[v] {
                    self.accumulate(prev, h.tri, h.u, h.v, acc);
                }
                self.finish_gather(acc, albedo[v], out);
            },
        )
    }

    /// One Neumann pass as [`Ctx::gather_stored`], retracing the first pass's rays.
    fn gather_traced(&self, prev: &[f32], albedo: &[Vec3]) -> Vec<f32> {
        let stride = 3 * self.n2;
        let init = || (Vec::new(), vec![0.0f32; stride]);
        self.per_vertex(stride, init, |v, out, (rays, acc)| {
            let Some(n) = self.normal(v) else { return };
            if albedo[v] == Vec3::ZERO {
                return; // reflects nothing: skip its rays
            }
            self.vertex_rays(v, n, rays);
            acc.fill(0.0);
            for ray in rays.iter() {
                match self.caster.intersect(ray) {
                    Some(h) if self.front_facing(h.tri, ray.dir) => {
                        self.accumulate(prev, h.tri, h.u, h.v, acc);
                    }
                    _ => {}
                }
            }
            self.finish_gather(acc, albedo[v], out);
        })
    }
}

/// Bytes of the transfer of `vertices` vertices under `settings` (what one pass allocates;
/// interreflected transfer holds three such arrays at once).
pub fn transfer_bytes(settings: &ShBakeSettings, vertices: usize) -> u128 {
    let per_vertex = sh_count(settings.order.min(MAX_ORDER)) * settings.transfer.channels() * 4;
    let arrays = match settings.transfer {
        ShTransferKind::Interreflected => 3,
        _ => 1,
    };
    vertices as u128 * per_vertex as u128 * arrays
}

/// A front-facing hit of one of a vertex's rays, kept between Neumann passes (12 bytes).
#[derive(Clone, Copy, Debug)]
struct FrontHit {
    tri: u32,
    u: f32,
    v: f32,
}

/// Memory the interreflected bake may spend on keeping first-pass hits (worst case, every
/// ray a hit) instead of retracing rays in every Neumann pass.
const HIT_BUDGET_BYTES: usize = 1 << 30;

#[cfg(test)]
mod tests;
