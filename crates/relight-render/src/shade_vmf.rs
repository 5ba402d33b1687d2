//! Rendering of the `vmf` method (Laurijssen & Dutré 2009, section 6.2; the bake is
//! `relight_bake::vmf`).
//!
//! # The prefiltered chain (section 6.2)
//! "The environment map is prefiltered with several vMF profiles [...] such that the kernel's
//! kappa value is doubled between successive levels." A vMF kernel of concentration `kappa`
//! has the shape `exp(kappa (mu . w - 1))` of a spherical Gaussian of sharpness
//! `lambda = kappa`, and a level of `sg`'s Gaussian-prefiltered chain
//! (`relight_sphere::env_prefilter`) stores the kernel-weighted **average** radiance
//! `P_kappa(mu)`. So the vMF chain *is* `sg`'s chain with two levels per octave of `sigma`
//! (`lambda = 1 / sigma^2` halves per level, i.e. `kappa` doubles): [`vmf_chain`] feeds
//! [`SgLighting`], and nothing of the prefilter is written twice.
//!
//! # Lookup by kappa
//! A normalised lobe `alpha gamma(w; mu, kappa)` integrates against the lighting to
//! `alpha P_kappa(mu)` exactly (the vMF is the kernel, normalised). The fetch interpolates
//! linearly in `ln kappa` between the two levels bracketing `kappa`
//! ([`SgLighting::sample`]). A `kappa` sharper than the chain's sharpest level
//! ([`kappa_resolved`], `n^2 / 4` for a finest face of `n` texels) is fetched at that level:
//! the lobe is widened to what the chain resolves, and since the chain stores averages, its
//! energy `alpha` is kept (under a constant environment `L` every lobe gives `alpha L`,
//! whatever its `kappa`). A `kappa` below the broadest level (`1/4`) is fetched there.
//!
//! # A frame
//! 1. **Per vertex** ([`VmfRenderer::prepare`], parallel): the view `v = normalize(eye - x)`
//!    in the vertex's local frame (`Frame::from_normal` of its normal, as the bake) is
//!    located among the vertex's views ([`ViewTable`]: its own icosahedral level) and the
//!    slices of the three views are blended by eq. 6 ([`relight_bake::vmf::blend_slices`]);
//!    axes are rotated into the map frame (`Environment::env_from_world`). A vertex with a
//!    diffuse SH transfer (`relight_bake::vmf::diffuse_sh`) gets its diffuse term's radiance
//!    `c(v) sum_k t_k L_k` here (the lighting's world-frame SH, [`SgLighting::world_sh`];
//!    `c(v)` the view factor of its material's diffuse term, 1 but for the GGX plastic) and
//!    its three diffuse-term lobes are dropped (amplitude zero).
//! 2. **Per pixel** (deferred shading): the three vertices' blended lobes are blended again by
//!    eq. 6 with the fragment's barycentrics ("interpolated during rasterization", section
//!    6.2) and each lobe is one fetch: `L_o = scale sum_j alpha_j P_{kappa_j}(mu_j)`, plus
//!    the vertices' diffuse SH radiance interpolated with the same barycentrics.

use crate::raster::{self, Fragment, RasterOptions, Rendered};
use crate::shade_sg::{ChainOptions, SgLighting};
use glam::Vec3;
use rayon::prelude::*;
use relight_bake::vmf::{blend_lobes, diffuse_sh, TransferSlice, ViewTable, VmfBake};
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use relight_sphere::vmf::VmfLobe;
use relight_sphere::warp::Frame;
use std::time::Instant;

/// Lobes per vertex: 2 terms x 3 light-path classes.
pub const LOBES: usize = 6;

/// The chain of section 6.2 for a finest face of `face_size` texels: `kappa` doubles per
/// level (two levels per octave of `sigma`), from `face_size^2 / 4` down to `1/4`, each level
/// with one texel per `sigma` (module docs).
pub fn vmf_chain(face_size: usize) -> ChainOptions {
    ChainOptions {
        face_size,
        levels_per_octave: 2,
        texels_per_sigma: 1.0,
    }
}

/// The lighting of a vMF frame: `env` prefiltered into [`vmf_chain`] (`face_size` capped at
/// the map's own resolution, `shade_sg::source_face_size`) and projected to SH of the bake's
/// diffuse order (`sh_order`, at least 1; [`SgLighting::world_sh`]).
///
/// # Panics
/// If `face_size` is not a power of two.
pub fn vmf_lighting(env: &Environment, face_size: usize, sh_order: usize) -> SgLighting {
    SgLighting::with_chain(env, sh_order.max(1), &vmf_chain(face_size))
}

/// The largest `kappa` the chain of `lighting` resolves (its sharpest level's).
pub fn kappa_resolved(lighting: &SgLighting) -> f32 {
    lighting.prefiltered().levels()[0].lambda
}

/// `int alpha gamma(w) L(w) dw` of a lobe whose axis is in the map frame: one fetch,
/// `scale alpha P_kappa(mu)`, `kappa` clamped to the chain (module docs: energy kept).
#[inline]
pub fn integrate(lighting: &SgLighting, lobe_in_map: &VmfLobe) -> Vec3 {
    lobe_in_map.amplitude * lighting.sample(lobe_in_map.axis, lobe_in_map.kappa) * lighting.scale
}

/// The per-vertex state of a frame ([`VmfRenderer::prepare`]).
#[derive(Clone, Debug, Default)]
pub struct VmfFrameLobes {
    /// `lobes[x * LOBES + k]`: view-blended lobes of vertex `x`, axes in the map frame.
    pub lobes: Vec<VmfLobe>,
    /// Per vertex, the diffuse term's radiance from its SH transfer (zero without one).
    pub diffuse: Vec<Vec3>,
}

/// Where the time of a frame goes, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VmfTimes {
    /// Per-vertex view location and blending.
    pub vertex_ms: f64,
    /// Rasterisation, per-pixel blending and fetches.
    pub pixel_ms: f64,
}

/// Renders a [`VmfBake`] of a mesh (module docs).
#[derive(Clone, Debug)]
pub struct VmfRenderer<'a> {
    mesh: &'a TriMesh,
    bake: &'a VmfBake,
    /// `tables[level]`, for the levels the bake uses.
    tables: Vec<Option<ViewTable>>,
    frames: Vec<Frame>,
    /// Each vertex's material, for the view factor of its diffuse SH transfer
    /// ([`relight_bake::vmf::diffuse_sh::view_factor`]); empty: factor 1 everywhere.
    vertex_materials: Vec<Material>,
}

impl<'a> VmfRenderer<'a> {
    /// A renderer of `bake` (a whole bake), made of `mesh`.
    ///
    /// # Panics
    /// If the bake does not hold one row per vertex of `mesh` (a loaded bundle is checked by
    /// its reader first).
    pub fn new(mesh: &'a TriMesh, bake: &'a VmfBake) -> VmfRenderer<'a> {
        assert_eq!(bake.vertex_count(), mesh.vertex_count(), "rows of the bake");
        let mut tables: Vec<Option<ViewTable>> =
            vec![None; relight_bake::vmf::bake::MAX_VIEW_LEVEL as usize + 1];
        for &l in &bake.levels {
            let t = &mut tables[l as usize];
            if t.is_none() {
                *t = Some(ViewTable::new(u32::from(l)));
            }
        }
        let frames = mesh
            .normals
            .iter()
            // The bake's frame: `relight_bake::vmf::slice::trace_slice`.
            .map(|n| Frame::from_normal(n.try_normalize().unwrap_or(Vec3::Y)))
            .collect();
        VmfRenderer {
            mesh,
            bake,
            tables,
            frames,
            vertex_materials: Vec::new(),
        }
    }

    /// The renderer with each vertex's material (the bake's: the first triangle's, as
    /// `relight_bake::sg::transport::vertex_materials`), whose view factor scales the
    /// diffuse SH transfer (the GGX plastic's Fresnel transmission towards the viewer).
    ///
    /// # Panics
    /// If `materials` does not hold one material per vertex.
    pub fn with_vertex_materials(mut self, materials: Vec<Material>) -> Self {
        assert_eq!(
            materials.len(),
            self.mesh.vertex_count(),
            "one material per vertex"
        );
        self.vertex_materials = materials;
        self
    }

    /// The slice of vertex `x` for the world view direction `v` (unit, towards the viewer),
    /// eq. 6 over the vertex's views; lobes in the world frame.
    pub fn view_slice(&self, x: usize, v: Vec3) -> TransferSlice {
        let table = self.tables[self.bake.levels[x] as usize]
            .as_ref()
            .expect("a table per level used");
        table.interpolate(self.bake.vertex_slices(x), self.frames[x].to_local(v))
    }

    /// The per-vertex pass for an eye at `eye` (world), axes rotated into the map frame of
    /// `lighting`.
    pub fn prepare(&self, lighting: &SgLighting, eye: Vec3) -> VmfFrameLobes {
        let r = lighting.env_from_world;
        let n = self.mesh.vertex_count();
        let mut lobes = vec![VmfLobe::new(Vec3::Z, 0.0, Vec3::ZERO); n * LOBES];
        let mut diffuse = vec![Vec3::ZERO; n];
        let light_sh = lighting.world_sh();
        lobes
            .par_chunks_mut(LOBES * 256)
            .zip(diffuse.par_chunks_mut(256))
            .enumerate()
            .for_each(|(c, (out, dout))| {
                for (i, (o, d)) in out.chunks_mut(LOBES).zip(dout).enumerate() {
                    let x = c * 256 + i;
                    let p = self.mesh.positions[x];
                    let v = (eye - p).try_normalize().unwrap_or(self.frames[x].n);
                    let s = self.view_slice(x, v);
                    let sh = self.bake.diffuse_sh_row(x);
                    for (k, (o, l)) in o.iter_mut().zip(s.lobes.iter().flatten()).enumerate() {
                        *o = VmfLobe {
                            axis: r * l.axis,
                            ..*l
                        };
                        if sh.is_some() && k < LOBES / 2 {
                            o.amplitude = Vec3::ZERO; // the diffuse term: SH instead
                        }
                    }
                    if let Some(t) = sh {
                        let c = self
                            .vertex_materials
                            .get(x)
                            .map_or(1.0, |m| diffuse_sh::view_factor(m, v.dot(self.frames[x].n)));
                        *d = diffuse_sh::radiance(t, light_sh) * c;
                    }
                }
            });
        VmfFrameLobes { lobes, diffuse }
    }

    /// Radiance of a fragment: eq. 6 over its triangle's vertex lobes, one fetch per lobe.
    #[inline]
    fn shade(
        &self,
        frame: &VmfFrameLobes,
        f: &Fragment,
        integrate: impl Fn(&VmfLobe) -> Vec3,
    ) -> Vec3 {
        let id = self.mesh.indices[f.tri as usize].map(|i| i as usize);
        let b = f.bary;
        let diffuse =
            frame.diffuse[id[0]] * b[0] + frame.diffuse[id[1]] * b[1] + frame.diffuse[id[2]] * b[2];
        diffuse
            + (0..LOBES)
                .map(|k| {
                    let l = blend_lobes(id.map(|x| &frame.lobes[x * LOBES + k]), f.bary);
                    if l.amplitude == Vec3::ZERO {
                        Vec3::ZERO
                    } else {
                        integrate(&l)
                    }
                })
                .sum::<Vec3>()
    }

    /// One frame: [`VmfRenderer::prepare`], then deferred per-pixel shading with prefiltered
    /// fetches ([`integrate`]).
    pub fn render(
        &self,
        lighting: &SgLighting,
        camera: &Camera,
        background: Option<&Environment>,
        opts: &RasterOptions,
    ) -> (Rendered, VmfTimes) {
        let t0 = Instant::now();
        let frame = self.prepare(lighting, Vec3::from(camera.origin));
        let t1 = Instant::now();
        let img = raster::render_deferred(self.mesh, camera, background, opts, |f| {
            self.shade(&frame, f, |l| integrate(lighting, l))
        });
        let times = VmfTimes {
            vertex_ms: (t1 - t0).as_secs_f64() * 1e3,
            pixel_ms: t1.elapsed().as_secs_f64() * 1e3,
        };
        (img, times)
    }

    /// The slow reference of [`VmfRenderer::render`]: the same blended lobes, each integrated
    /// numerically against every texel of `env.map` (through its SG form,
    /// `relight_sphere::sg::integrate_with_env`), times `env.scale`. For tests on small
    /// images and maps: it isolates the error of the prefiltered chain.
    pub fn render_reference(
        &self,
        lighting: &SgLighting,
        env: &Environment,
        camera: &Camera,
        opts: &RasterOptions,
    ) -> Rendered {
        let frame = self.prepare(lighting, Vec3::from(camera.origin));
        raster::render_deferred(self.mesh, camera, None, opts, |f| {
            self.shade(&frame, f, |l| {
                relight_sphere::sg::integrate_with_env(&[l.to_sg()], &env.map) * env.scale
            })
        })
    }
}

#[cfg(test)]
mod tests;
