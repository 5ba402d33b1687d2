//! A transfer slice from traced paths (paper sections 5.1-5.2, eq. 13-15).
//!
//! # Paths (section 5.1)
//! For a surface point `x` with material `m` and a view `v` (local frame, parent module
//! docs), `M` paths leave `x`:
//! * the first direction `w` is drawn from `m`'s eq. 9 lobes for `v` ([`MaterialLobes`],
//!   density `p`), from the `i`-th of `M` Hammersley points, Cranley-Patterson rotated by a
//!   shift drawn from `Rng::new(seed, stream)`;
//! * the path is traced with the ray caster: rays leave surfaces through
//!   [`crate::transport::surface_ray`]; a back face absorbs (surfaces are one-sided, as in
//!   the `sg` bake and Mitsuba); each hit scatters by the full BRDF of the material of the
//!   hit triangle's corner of largest barycentric weight, sampled with the path tracer's own
//!   [`Material::sample`] (random numbers from the same `Rng`, path after path), up to
//!   `max_bounces` scatterings after `x`;
//! * a path that escapes in direction `s` contributes the transfer estimate
//!   `throughput / (p M)` at `s`, where `throughput` is the product of the cosine-weighted
//!   BRDFs over the product of the sampling densities along the path.
//!
//! # Classes
//! A path's contribution is split, not routed at random, by the two terms of eq. 9
//! (`f = f_d + f_g`, [`super::material_lobes::split_eval`]):
//! * at `x`: into the term of `x`'s BRDF it leaves by, [`Term`] (`f_d / p` and `f_g / p`):
//!   the paper's `T_d` and `T_g` (eq. 3), both kept;
//! * by the light-path class ([`PathClass`]): **direct** if it escapes right away; else by the
//!   term of the BRDF at its **first bounce** (`f_d / pdf` to **indirect diffuse**, `f_g / pdf`
//!   to **indirect glossy**; later bounces multiply both by `f / pdf`): the paper's Fig. 6
//!   classes `E G L`, `E G D L`, `E G G L` (with its `D` / `G` at the first bounce, and any
//!   bounces after it).
//!
//! So each escaping path adds its direction `s` with its split weights to up to two (direct)
//! or four (indirect) of the 2 x 3 classes of the slice; every class's weight sum is an unbiased estimate of its transfer integral, and
//! the six sum to the estimate of the whole slice `int T(x, s, v) ds`. The paper instead
//! spawns one continuation per term at each hit (section 5.1); splitting the weight of one
//! continuation has the same expectation per class with one ray per bounce.
//!
//! # Lobes (section 5.2)
//! One vMF lobe per class from its samples in closed form ([`estimate_one_lobe`], eq. 13-15:
//! axis and concentration from the weighted mean direction, amplitude = the weight sum, the
//! paper's `alpha_j = M_j / M mean(prod beta)`), concentration at most `kappa_max`. A class
//! with no escaping sample gets a zero-amplitude lobe about the normal (`kappa = 0`), never a
//! NaN. [`SliceSamples::fit_em_nested`] fits several lobes per class instead (the paper's
//! future work).
//!
//! Determinism: a slice depends on `(scene, point, view, settings, seed, stream)` only; the
//! bake uses one stream per (vertex, view).

use super::material_lobes::{split_eval, MaterialLobes, Term};
use crate::transport::surface_ray;
use crate::BakeError;
use glam::Vec3;
use relight_scene::accel::{Hit, Ray, RayCaster};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_sphere::vmf::{
    estimate_one_lobe, fit_em_nested, inner_product, EmFit, EmOptions, KappaEstimate, VmfLobe,
    WeightedDir,
};
use relight_sphere::warp::{cranley_patterson, hammersley, Frame, Rng};

/// Largest number of paths per slice accepted by [`SliceSettings::validate`]: 2^22.
pub const MAX_PATHS: u32 = 1 << 22;

/// Largest number of bounces after the point.
pub const MAX_BOUNCES: u32 = 64;

/// The light-path class of a path (module docs; the paper's Fig. 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PathClass {
    /// Escapes to the environment right after leaving the point.
    Direct,
    /// First bounce by the diffuse term of the BRDF there.
    IndirectDiffuse,
    /// First bounce by the glossy term of the BRDF there.
    IndirectGlossy,
}

impl PathClass {
    /// The classes, in the order of the arrays indexed by [`PathClass::index`].
    pub const ALL: [PathClass; 3] = [
        PathClass::Direct,
        PathClass::IndirectDiffuse,
        PathClass::IndirectGlossy,
    ];

    /// Position in [`PathClass::ALL`].
    pub fn index(self) -> usize {
        match self {
            PathClass::Direct => 0,
            PathClass::IndirectDiffuse => 1,
            PathClass::IndirectGlossy => 2,
        }
    }
}

/// How a slice is sampled and estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliceSettings {
    /// Paths `M` per slice, `1..=MAX_PATHS`.
    pub paths: u32,
    /// Scatterings after the point, `0..=MAX_BOUNCES` (0: direct only; the paper uses 1).
    pub max_bounces: u32,
    /// Samples per term for fitting the eq. 9 lobes of the point's material, `1..=MAX_PATHS`.
    pub material_samples: u32,
    /// Largest concentration of a class lobe (finite, `>= 1`): a class with few samples
    /// would otherwise get a needle (one sample gives `kappa_max`).
    pub kappa_max: f32,
}

impl Default for SliceSettings {
    /// 1024 paths, one bounce (the paper's direct + single-bounce interreflections), 1024
    /// material samples, `kappa_max = 1e4` (a lobe about 0.6 degree wide, sharper than a
    /// Blinn-Phong of exponent 10^4).
    fn default() -> Self {
        SliceSettings {
            paths: 1024,
            max_bounces: 1,
            material_samples: 1024,
            kappa_max: 1.0e4,
        }
    }
}

impl SliceSettings {
    /// Check the ranges documented on each field.
    ///
    /// # Errors
    /// [`BakeError::Settings`] naming the offending setting.
    pub fn validate(&self) -> Result<(), BakeError> {
        let err = |m: String| Err(BakeError::Settings(m));
        if !(1..=MAX_PATHS).contains(&self.paths) {
            return err(format!("paths {} is not in 1..={MAX_PATHS}", self.paths));
        }
        if self.max_bounces > MAX_BOUNCES {
            return err(format!(
                "max_bounces {} is not in 0..={MAX_BOUNCES}",
                self.max_bounces
            ));
        }
        if !(1..=MAX_PATHS).contains(&self.material_samples) {
            return err(format!(
                "material_samples {} is not in 1..={MAX_PATHS}",
                self.material_samples
            ));
        }
        if !(self.kappa_max.is_finite() && self.kappa_max >= 1.0) {
            return err(format!(
                "kappa_max {} must be finite and >= 1",
                self.kappa_max
            ));
        }
        Ok(())
    }
}

/// The scene paths are traced in: a mesh, a ray caster built over it and one material per
/// vertex (a hit scatters by the material of its nearest corner).
#[derive(Clone, Copy)]
pub struct SliceScene<'a> {
    /// The mesh (positions, normals, triangles).
    pub mesh: &'a TriMesh,
    /// A ray caster over `mesh`.
    pub caster: &'a dyn RayCaster,
    /// One material per vertex of `mesh` (e.g. [`crate::sg::transport::vertex_materials`]).
    pub vertex_materials: &'a [Material],
}

/// The point a slice is computed at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Position (world).
    pub position: Vec3,
    /// Unit shading normal (world): +Z of the local frame.
    pub normal: Vec3,
    /// Unit geometric normal (world): ray offsets and the geometric horizon.
    pub geometric_normal: Vec3,
    /// The material at the point.
    pub material: Material,
}

/// The escaped path samples of one slice, per term at the point and class (module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SliceSamples {
    /// `classes[term.index()][class.index()]`: directions (world) and RGB weights (already
    /// divided by `paths`).
    pub classes: [[Vec<WeightedDir>; 3]; 2],
    /// Paths traced (`M`).
    pub paths: u32,
    /// Unit shading normal of the point (world): the axis of empty classes' lobes.
    pub normal: Vec3,
}

/// One lobe per (term at the point, class): the slice `T_{x, v}` of eq. 4 (world frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransferSlice {
    /// `lobes[term.index()][class.index()]`.
    pub lobes: [[VmfLobe; 3]; 2],
}

impl TransferSlice {
    /// The lobe of one term and class.
    pub fn lobe(&self, term: Term, class: PathClass) -> &VmfLobe {
        &self.lobes[term.index()][class.index()]
    }

    /// Sum of the amplitudes of one class over both terms: its transfer integral (RGB).
    pub fn class_integral(&self, class: PathClass) -> Vec3 {
        Term::ALL
            .iter()
            .map(|&t| self.lobe(t, class).amplitude)
            .sum()
    }

    /// Sum of all amplitudes: the outgoing radiance under a unit constant environment.
    pub fn integral(&self) -> Vec3 {
        self.lobes.iter().flatten().map(|l| l.amplitude).sum()
    }

    /// Outgoing radiance under the environment `ambient + light(s)` (a constant plus a vMF
    /// light, world frame): `sum_j alpha_j ambient + <lobe_j, light>` (eq. 2 and 4).
    pub fn shade(&self, ambient: Vec3, light: &VmfLobe) -> Vec3 {
        self.lobes
            .iter()
            .flatten()
            .map(|l| l.amplitude * ambient + inner_product(l, light))
            .sum()
    }
}

/// Trace the paths of the slice of `point` for the unit `view` (local frame of the point):
/// the module docs' sampling, with random numbers from `Rng::new(seed, stream)`. A view at
/// or below the horizon, or a degenerate normal, gives no samples.
///
/// # Panics
/// Debug builds assert settings in range ([`SliceSettings::validate`]).
pub fn trace_slice(
    scene: &SliceScene,
    point: &SurfacePoint,
    view: Vec3,
    settings: &SliceSettings,
    seed: u64,
    stream: u64,
) -> SliceSamples {
    let lobes = match view.try_normalize() {
        Some(v) if v.z > 0.0 => MaterialLobes::fit(&point.material, v, settings.material_samples),
        _ => return trace_slice_with(scene, point, view, None, settings, seed, stream),
    };
    trace_slice_with(scene, point, view, Some(&lobes), settings, seed, stream)
}

/// [`trace_slice`] with the point material's eq. 9 lobes for `view` given (they depend on
/// the material and the view only, so a bake fits them once per material and view;
/// `None` only for a view at or below the horizon, which gives no samples).
///
/// # Panics
/// Debug builds assert settings in range and lobes for a view above the horizon.
pub fn trace_slice_with(
    scene: &SliceScene,
    point: &SurfacePoint,
    view: Vec3,
    lobes: Option<&MaterialLobes>,
    settings: &SliceSettings,
    seed: u64,
    stream: u64,
) -> SliceSamples {
    debug_assert!(settings.validate().is_ok(), "{settings:?}");
    let m = &point.material;
    let n = point.normal.try_normalize().unwrap_or(Vec3::Y);
    let mut out = SliceSamples {
        paths: settings.paths,
        normal: n,
        ..Default::default()
    };
    let (Some(ng), Some(view)) = (point.geometric_normal.try_normalize(), view.try_normalize())
    else {
        return out;
    };
    if view.z <= 0.0 || point.normal.try_normalize().is_none() {
        return out;
    }
    let frame = Frame::from_normal(n);
    let Some(lobes) = lobes else {
        debug_assert!(false, "no eq. 9 lobes for a view above the horizon");
        return out;
    };
    let inv_m = 1.0 / settings.paths as f32;
    let mut rng = Rng::new(seed, stream);
    let shift = rng.next_vec2();
    for i in 0..settings.paths {
        // First direction from the eq. 9 lobes; its weight split by the terms at x.
        let s = lobes.sample(cranley_patterson(hammersley(i, settings.paths), shift));
        if s.dir.z <= 0.0 {
            continue;
        }
        let [fd, fg] = split_eval(m, view, s.dir);
        let wx = [fd * (inv_m / s.pdf), fg * (inv_m / s.pdf)];
        if wx[0].max_element() <= 0.0 && wx[1].max_element() <= 0.0 {
            continue;
        }
        let dir = frame.to_world(s.dir);
        if dir.dot(ng) <= 0.0 {
            continue;
        }
        let mut ray = surface_ray(point.position, ng, dir);
        // Weights of the first bounce's terms, then the product of the later bounces.
        let mut wh = [Vec3::ZERO; 2];
        let mut rest = Vec3::ONE;
        let mut bounces = 0;
        loop {
            let Some(hit) = scene.caster.intersect(&ray) else {
                for (classes, &w) in out.classes.iter_mut().zip(&wx) {
                    if bounces == 0 {
                        push(&mut classes[0], ray.dir, w);
                    } else {
                        push(&mut classes[1], ray.dir, w * wh[0] * rest);
                        push(&mut classes[2], ray.dir, w * wh[1] * rest);
                    }
                }
                break;
            };
            if bounces >= settings.max_bounces {
                break;
            }
            let Some((next, split)) = scatter(scene, &hit, ray.dir, &mut rng) else {
                break;
            };
            if bounces == 0 {
                wh = split;
            } else {
                rest *= split[0] + split[1];
            }
            bounces += 1;
            ray = next;
        }
    }
    out
}

/// Add a sample unless its weight is zero (or negative, which cannot happen).
fn push(class: &mut Vec<WeightedDir>, dir: Vec3, weight: Vec3) {
    if weight.max_element() > 0.0 {
        class.push(WeightedDir {
            dir: dir.normalize(),
            weight,
        });
    }
}

/// Scatter at `hit` (arriving along `dir`): the next ray and the throughput factor split by
/// the terms of the BRDF there, `[f_d / pdf, f_g / pdf]`; `None` if absorbed.
fn scatter(scene: &SliceScene, hit: &Hit, dir: Vec3, rng: &mut Rng) -> Option<(Ray, [Vec3; 2])> {
    let mesh = scene.mesh;
    let tri = hit.tri as usize;
    let ng = mesh.geometric_normal(tri);
    // One-sided: a back face (or a degenerate triangle) absorbs.
    if ng.dot(dir) >= 0.0 {
        return None;
    }
    let ns = mesh.shading_normal(tri, hit.u, hit.v).try_normalize()?;
    let corners = mesh.indices[tri];
    let bary = [1.0 - hit.u - hit.v, hit.u, hit.v];
    let k = (0..3).fold(0, |k, j| if bary[j] > bary[k] { j } else { k });
    let m = &scene.vertex_materials[corners[k] as usize];
    let frame = Frame::from_normal(ns);
    let wi = frame.to_local(-dir);
    let s = m.sample(wi, rng.next_vec2(), rng.next_f32())?;
    let next = frame.to_world(s.wo);
    if next.dot(ng) <= 0.0 {
        return None;
    }
    let [fd, fg] = split_eval(m, wi, s.wo);
    let point = mesh.point(tri, hit.u, hit.v);
    Some((surface_ray(point, ng, next), [fd / s.pdf, fg / s.pdf]))
}

impl SliceSamples {
    /// The samples of one term and class.
    pub fn class(&self, term: Term, class: PathClass) -> &[WeightedDir] {
        &self.classes[term.index()][class.index()]
    }

    /// One lobe per class in closed form (eq. 13-15, module docs), concentrations at most
    /// `kappa_max`; zero-amplitude lobes for empty classes.
    ///
    /// # Panics
    /// Debug builds assert `kappa_max > 0`.
    pub fn estimate(&self, estimate: KappaEstimate, kappa_max: f32) -> TransferSlice {
        let empty = VmfLobe::new(self.normal, 0.0, Vec3::ZERO);
        let lobes = self.classes.each_ref().map(|term| {
            term.each_ref()
                .map(|c| estimate_one_lobe(c, estimate, kappa_max).unwrap_or(empty))
        });
        TransferSlice { lobes }
    }

    /// Nested EM fits of 1..=`max_lobes` lobes per class ([`fit_em_nested`]); an empty list
    /// for an empty class.
    pub fn fit_em_nested(&self, max_lobes: usize, opts: &EmOptions) -> [[Vec<EmFit>; 3]; 2] {
        self.classes
            .each_ref()
            .map(|term| term.each_ref().map(|c| fit_em_nested(c, max_lobes, opts)))
    }
}

/// [`trace_slice`] then [`SliceSamples::estimate`] with the paper's eq. 13
/// ([`KappaEstimate::Banerjee`]) and `settings.kappa_max`.
///
/// # Panics
/// Debug builds assert settings in range ([`SliceSettings::validate`]).
pub fn transfer_slice(
    scene: &SliceScene,
    point: &SurfacePoint,
    view: Vec3,
    settings: &SliceSettings,
    seed: u64,
    stream: u64,
) -> TransferSlice {
    trace_slice(scene, point, view, settings, seed, stream)
        .estimate(KappaEstimate::Banerjee, settings.kappa_max)
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod diffuse_tests;
