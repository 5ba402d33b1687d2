//! Local lighting of the `cuts` method: a point or spot light moved at run time, its direct
//! light and one bounce of indirect light (Cheslack-Postava et al. 2008, sec. 4.2 "If we're
//! calculating local lighting we compute the direct lighting value first", and the local
//! indirect lighting of "At runtime we must sample lighting").
//!
//! Per light position ([`LocalShader::prepare`]):
//! 1. **sample lighting**: the light's direct irradiance `E_s` at every surface sample
//!    ([`relight_bake::cuts::surface`]), shadow-tested with one ray per sample (the paper's
//!    shadow cube map, exact here), re-emitted diffusely: the sample's exitance
//!    `l_s = rho_s E_s` with `rho_s` the diffuse albedo of its triangle's material at the
//!    sample's point, texture maps applied ([`Material::diffuse_albedo`],
//!    [`MappedMaterials::diffuse_albedo_at`]; the paper's assumption 3, "we do not handle
//!    glossy to glossy transfer paths");
//! 2. **tree and light cut**: the light tree's cluster means of `l` and the illumination cut
//!    ([`LightCut::build`], error bound then intensity), and each node's position weighted by
//!    its samples' luminance ([`weighted_positions`]).
//!
//! Per pixel ([`LocalShader::render`], deferred on [`raster::render_deferred`]), with the
//! fragment's material and shading normal after its texture and normal maps
//! ([`MappedMaterials::at`], the path tracer's lookup):
//! * **direct**: `f(wi, wo) I(w) / d^2` towards the light with one shadow ray from the
//!   fragment (the path tracer's test: `wo` above the shading and the geometric normal);
//! * **one bounce**: the three vertex cuts interpolated with barycentric weights, merged with
//!   the light cut in one traversal ([`merge_cuts`], sec. 3.2), each merged cluster `k`
//!   adding `|C'_k| <l>_k <g>_k f(wi, w_k)` with `w_k` the direction from the fragment to the
//!   cluster's weighted position, and `f` the BRDF without the cosine when the cuts hold it
//!   ([`CutFunction::VisibilityCosine`], lifted onto the horizon as in
//!   [`crate::shade_cuts`]) or with it ([`CutFunction::Visibility`]). The vertex function
//!   `g` is [`relight_bake::cuts::local`]'s, so with `l = pi L` the sum is the one-bounce
//!   estimator `sum_s f cos L_s cos_s A_s / d^2` (with its `1 / d^2` clamp).

use crate::light::{LightError, PointLight};
use crate::mapped::MappedMaterials;
use crate::raster::{self, Fragment, RasterOptions, Rendered};
use crate::shade_cuts::lanes::{lambert_points, PointGroups, LANES};
use glam::Vec3;
use rayon::prelude::*;
use relight_bake::cuts::cut::dequantise;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::local::weighted_positions;
use relight_bake::cuts::merge::{merge_cuts, CutKeys};
use relight_bake::cuts::surface::SurfaceSamples;
use relight_bake::cuts::visibility::CutFunction;
use relight_bake::cuts::{CutsBake, CutsError};
use relight_scene::accel::{offset_ray_origin, Ray, RayCaster};
use relight_scene::camera::Camera;
use relight_scene::material::maps::SceneMaps;
use relight_scene::material::{Material, MaterialEval};
use relight_scene::mesh::TriMesh;
use relight_sphere::luminance;
use std::time::Instant;

/// Which terms a frame adds (the measurement split and the tests' controls).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Terms {
    /// The light's direct light at each pixel.
    pub direct: bool,
    /// One bounce of indirect light through the cuts.
    pub indirect: bool,
}

impl Terms {
    /// Direct and one bounce.
    pub const ALL: Terms = Terms {
        direct: true,
        indirect: true,
    };
}

/// Everything a frame needs of one light position: the light, its light cut and the
/// clusters' positions (module docs, steps 1-2).
#[derive(Clone, Debug)]
pub struct LocalLighting {
    /// The light (validated).
    pub light: PointLight,
    /// The illumination cut of the samples' exitance.
    pub cut: LightCut,
    /// Every tree node's luminance-weighted sample position (post-order).
    pub positions: Vec<Vec3>,
    /// Milliseconds of step 1 (shadow rays and exitance of the samples).
    pub sample_ms: f64,
    /// Milliseconds of step 2 (tree values, light cut, positions).
    pub cut_ms: f64,
}

/// The local-lighting renderer over one whole-mesh bake of surface samples.
pub struct LocalShader<'a> {
    mesh: &'a TriMesh,
    materials: MappedMaterials,
    bake: &'a CutsBake,
    surface: &'a SurfaceSamples,
    caster: &'a dyn RayCaster,
    function: CutFunction,
}

impl<'a> LocalShader<'a> {
    /// A renderer of `bake` (surface samples, one cut per vertex of `mesh`) with `materials`
    /// (indexed by `mesh.material_ids`) and `caster` built over `mesh` for shadow rays.
    ///
    /// # Errors
    /// [`CutsError::Input`] for a bake of environment directions or of another vertex count.
    pub fn new(
        mesh: &'a TriMesh,
        materials: Vec<Material>,
        bake: &'a CutsBake,
        function: CutFunction,
        caster: &'a dyn RayCaster,
    ) -> Result<Self, CutsError> {
        let Some(surface) = bake.surface.as_ref() else {
            return Err(CutsError::Input(
                "this cuts bake holds environment directions, not surface samples: it is lit \
                 by an environment, not a point light (bake with --cut-samples surface)"
                    .into(),
            ));
        };
        if bake.cuts.vertex_count() != mesh.vertex_count() {
            return Err(CutsError::Input(format!(
                "{} vertex cuts for {} vertices",
                bake.cuts.vertex_count(),
                mesh.vertex_count()
            )));
        }
        Ok(LocalShader {
            mesh,
            materials: MappedMaterials::new(materials),
            bake,
            surface,
            caster,
            function,
        })
    }

    /// With the materials' texture and normal maps (built over this shader's mesh): each
    /// fragment is shaded with its mapped material and normal, and each surface sample
    /// re-emits with the diffuse albedo at its point ([`MappedMaterials`], the path tracer's
    /// lookup).
    pub fn with_maps(self, maps: SceneMaps) -> Self {
        LocalShader {
            materials: self.materials.with_maps(maps),
            ..self
        }
    }

    /// Check `light` ([`PointLight::validated`]) and that it is not inside a closed object
    /// ([`crate::light::check_not_inside`]).
    ///
    /// # Errors
    /// The [`LightError`].
    pub fn check_light(&self, light: PointLight) -> Result<PointLight, LightError> {
        let light = light.validated()?;
        crate::light::check_not_inside(&light, self.mesh, self.caster)?;
        Ok(light)
    }

    /// Exitance `l_s = rho_s E_s` of every surface sample under `light` (step 1), in
    /// parallel.
    pub fn sample_exitance(&self, light: &PointLight) -> Vec<Vec3> {
        let s = self.surface;
        (0..s.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|i| {
                let (x, n) = (s.positions[i], s.normals[i]);
                let Some((e, w, d)) = light.irradiance(x, n) else {
                    return Vec3::ZERO;
                };
                let rho = self
                    .materials
                    .diffuse_albedo_at(self.mesh, s.triangles[i], x);
                if rho == Vec3::ZERO {
                    return Vec3::ZERO;
                }
                let shadow = Ray::new(offset_ray_origin(x, n, w), w, 0.0, d);
                if self.caster.occluded(&shadow) {
                    Vec3::ZERO
                } else {
                    rho * e
                }
            })
            .collect()
    }

    /// Steps 1-2 of the module docs for `light` (checked with [`LocalShader::check_light`]),
    /// with an illumination cut of at most `budget` nodes and error bound `sigma`.
    ///
    /// # Errors
    /// A bad light ([`LightError`], as a message) or light cut settings.
    pub fn prepare(
        &self,
        light: PointLight,
        sigma: f32,
        budget: usize,
    ) -> Result<LocalLighting, String> {
        let light = self.check_light(light).map_err(|e| e.to_string())?;
        let t0 = Instant::now();
        let exitance = self.sample_exitance(&light);
        let sample_ms = t0.elapsed().as_secs_f64() * 1e3;
        let t1 = Instant::now();
        let cut = LightCut::build(&self.bake.tree, &exitance, sigma, budget)
            .map_err(|e| e.to_string())?;
        let y: Vec<f64> = exitance.iter().map(|&l| luminance(l) as f64).collect();
        let positions = weighted_positions(&self.bake.tree, &y);
        Ok(LocalLighting {
            light,
            cut,
            positions,
            sample_ms,
            cut_ms: t1.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// Outgoing radiance of fragment `f` towards `eye` (module docs), the `terms` asked.
    pub fn shade_fragment(&self, l: &LocalLighting, f: &Fragment, eye: Vec3, terms: Terms) -> Vec3 {
        let mut owned = None;
        let (material, n) = self.materials.at(self.mesh, f, &mut owned);
        let frame = material.material().shading_frame(n);
        let view = (eye - f.position).normalize_or_zero();
        let wi = frame.to_local(view);
        if wi.z <= 0.0 || view.dot(f.geometric_normal) <= 0.0 {
            return Vec3::ZERO; // one-sided materials, as the path tracer's
        }
        let mut sum = Vec3::ZERO;
        if terms.direct {
            let ng = f.geometric_normal;
            if let Some((e, w, d)) = l.light.irradiance(f.position, ng) {
                let wo = frame.to_local(w);
                if wo.z > 0.0 {
                    let fr = material.eval(wi, wo);
                    let shadow = Ray::new(offset_ray_origin(f.position, ng, w), w, 0.0, d);
                    if fr.max_element() > 0.0 && !self.caster.occluded(&shadow) {
                        sum += fr * (e / ng.dot(w));
                    }
                }
            }
        }
        if terms.indirect {
            let [a, b, c] = self.mesh.indices[f.tri as usize];
            let cuts = [a, b, c].map(|v| self.bake.cuts.cut(v as usize));
            let keys = [
                CutKeys::from(&l.cut),
                cuts[0].into(),
                cuts[1].into(),
                cuts[2].into(),
            ];
            let bary = f.bary;
            merge_cuts(keys, |node, pos| {
                let g = bary[0] * dequantise(cuts[0].value[pos[1]])
                    + bary[1] * dequantise(cuts[1].value[pos[2]])
                    + bary[2] * dequantise(cuts[2].value[pos[3]]);
                let power = l.cut.value[pos[0]];
                if g > 0.0 && power != Vec3::ZERO {
                    let w = (l.positions[node.index as usize] - f.position).normalize_or_zero();
                    let fr = self.brdf(material, wi, frame.to_local(w));
                    sum += power * (node.leaves() as f32 * g) * fr;
                }
            });
        }
        sum
    }

    /// The BRDF factor of one cluster in the shading frame (module docs;
    /// [`crate::shade_cuts::cluster_brdf`]).
    #[inline]
    fn brdf(&self, material: &MaterialEval, wi: Vec3, wo: Vec3) -> Vec3 {
        crate::shade_cuts::cluster_brdf(self.function, material, wi, wo)
    }

    /// Render `camera` under the prepared light (`terms` of it), the background black:
    /// [`raster::render_deferred_batched`], each triangle's cuts merged with the light cut
    /// once per band of rows (`TriangleMerge`) and summed per fragment. Equal to
    /// [`LocalShader::render_per_fragment`] up to f32 rounding (tested).
    ///
    /// # Panics
    /// If `opts.supersample == 0` or the camera's image is empty.
    pub fn render(
        &self,
        l: &LocalLighting,
        camera: &Camera,
        opts: &RasterOptions,
        terms: Terms,
    ) -> Rendered {
        let eye = Vec3::from_array(camera.origin);
        raster::render_deferred_batched(self.mesh, camera, None, opts, |tri, fs, out| {
            let direct_only = Terms {
                indirect: false,
                ..terms
            };
            for (f, o) in fs.iter().zip(out.iter_mut()) {
                *o = self.shade_fragment(l, f, eye, direct_only);
            }
            if terms.indirect {
                TRIANGLE_MERGE.with_borrow_mut(|t| {
                    t.build(self, l, tri);
                    for (f, o) in fs.iter().zip(out.iter_mut()) {
                        *o += t.shade(self, f, eye);
                    }
                });
            }
        })
    }

    /// Render with the per-fragment merge ([`LocalShader::shade_fragment`]): the slow
    /// reference of [`LocalShader::render`].
    ///
    /// # Panics
    /// As [`LocalShader::render`].
    pub fn render_per_fragment(
        &self,
        l: &LocalLighting,
        camera: &Camera,
        opts: &RasterOptions,
        terms: Terms,
    ) -> Rendered {
        let eye = Vec3::from_array(camera.origin);
        raster::render_deferred(self.mesh, camera, None, opts, |f| {
            self.shade_fragment(l, f, eye, terms)
        })
    }
}

thread_local! {
    /// Each rendering thread's [`TriangleMerge`] (reused across triangles).
    static TRIANGLE_MERGE: std::cell::RefCell<TriangleMerge> = Default::default();
}

/// One triangle's merged cut (its three vertex cuts and the light cut, sec. 3.2) with what
/// each cluster `k` adds at a fragment: `|C'_k| <l>_k`, the corners' `<g_j>_k` and the
/// cluster's position, as structure-of-arrays padded with zero clusters to a multiple of
/// [`LANES`] (the Lambert sum runs over lanes, `crate::shade_cuts::lanes`). Clusters no
/// corner sees or that hold no light are dropped.
#[derive(Default)]
struct TriangleMerge {
    power: [Vec<f32>; 3],
    g: [Vec<f32>; 3],
    position: [Vec<f32>; 3],
}

impl TriangleMerge {
    /// Merge triangle `tri`'s vertex cuts with `l`'s light cut into `self`.
    fn build(&mut self, shader: &LocalShader<'_>, l: &LocalLighting, tri: u32) {
        for a in [&mut self.power, &mut self.g, &mut self.position] {
            a.iter_mut().for_each(Vec::clear);
        }
        let [a, b, c] = shader.mesh.indices[tri as usize];
        let cuts = [a, b, c].map(|v| shader.bake.cuts.cut(v as usize));
        let keys = [
            CutKeys::from(&l.cut),
            cuts[0].into(),
            cuts[1].into(),
            cuts[2].into(),
        ];
        merge_cuts(keys, |node, pos| {
            let q = [
                cuts[0].value[pos[1]],
                cuts[1].value[pos[2]],
                cuts[2].value[pos[3]],
            ];
            let power = l.cut.value[pos[0]] * node.leaves() as f32;
            if q == [0; 3] || power == Vec3::ZERO {
                return;
            }
            let p = l.positions[node.index as usize];
            for j in 0..3 {
                self.power[j].push(power[j]);
                self.g[j].push(dequantise(q[j]));
                self.position[j].push(p[j]);
            }
        });
        // Zero clusters pad the last lane group (they add 0).
        let padded = self.power[0].len().next_multiple_of(LANES);
        for a in [&mut self.power, &mut self.g, &mut self.position] {
            a.iter_mut().for_each(|x| x.resize(padded, 0.0));
        }
    }

    /// The clusters as lane groups.
    fn groups(&self) -> PointGroups<'_> {
        fn chunks(a: &[Vec<f32>; 3]) -> [&[[f32; LANES]]; 3] {
            [0, 1, 2].map(|c| a[c].as_chunks::<LANES>().0)
        }
        PointGroups {
            power: chunks(&self.power),
            vis: chunks(&self.g),
            pos: chunks(&self.position),
        }
    }

    /// The one-bounce term at fragment `f` (as [`LocalShader::shade_fragment`]'s).
    fn shade(&self, shader: &LocalShader<'_>, f: &Fragment, eye: Vec3) -> Vec3 {
        let mut owned = None;
        let (material, n) = shader.materials.at(shader.mesh, f, &mut owned);
        let view = (eye - f.position).normalize_or_zero();
        if view.dot(n) <= 0.0 || view.dot(f.geometric_normal) <= 0.0 {
            return Vec3::ZERO;
        }
        let b = f.bary;
        let mut sum = Vec3::ZERO;
        match (*material.material(), shader.function) {
            // eval = albedo / pi max(0, n . w): no frame needed.
            (Material::Lambert { albedo }, CutFunction::Visibility) => {
                lambert_points(&self.groups(), b, n, f.position)
                    * albedo
                    * std::f32::consts::FRAC_1_PI
            }
            _ => {
                let frame = material.material().shading_frame(n);
                let wi = frame.to_local(view);
                if wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                let at = |a: &[Vec<f32>; 3], k: usize| Vec3::new(a[0][k], a[1][k], a[2][k]);
                for k in 0..self.power[0].len() {
                    let g = at(&self.g, k);
                    let v = b[0] * g.x + b[1] * g.y + b[2] * g.z;
                    if v > 0.0 {
                        let w = (at(&self.position, k) - f.position).normalize_or_zero();
                        let fr = shader.brdf(material, wi, frame.to_local(w));
                        sum += at(&self.power, k) * v * fr;
                    }
                }
                sum
            }
        }
    }
}

#[cfg(test)]
mod tests;
