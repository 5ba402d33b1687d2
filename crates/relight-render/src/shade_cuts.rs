//! Per-pixel shading of the `cuts` method (Cheslack-Postava et al. 2008, sec. 4.2; the bake
//! is `relight_bake::cuts`).
//!
//! Deferred shading on [`raster::render_deferred`]: for every visible sample, the three
//! visibility cuts of its triangle's corners, interpolated with the sample's barycentric
//! weights, are merged in one traversal with the frame's illumination cut, and the sample's
//! material is evaluated at each merged cluster's direction
//! ([`relight_bake::cuts::merge::shade`], Eq. 5):
//! `B = sum_k |C'_k| <L O>_k (sum_j b_j <v_j>_k) f(<w>_k)`.
//!
//! The BRDF is the path tracer's: `Material::eval(wi, wo)` in the frame of the sample's
//! interpolated shading normal, `wi` towards the camera (`relight_render::pathtrace` uses the
//! same call). `eval` includes `max(0, cos theta_o)`; when the cuts already hold the cosine
//! ([`CutFunction::VisibilityCosine`], of the vertex normals) it is divided out, so the
//! cosine is counted once; with [`CutFunction::Visibility`] (binary visibility) `eval` is
//! used as it is, so the cosine follows the per-pixel normal. Materials are read at render
//! time from the scene (nothing of them is baked), with their texture and normal maps applied
//! per fragment by `relight_scene::material::maps::shading_at`, the path tracer's lookup. A
//! normal map moves the BRDF's frame; with [`CutFunction::VisibilityCosine`] the cosine
//! stays the one baked with the vertex normals (the paper's approximation), with
//! [`CutFunction::Visibility`] it follows the mapped normal as the path tracer's does.

use crate::raster::{self, Fragment, RasterOptions, Rendered};
use glam::Vec3;
use relight_bake::cuts::cut::dequantise;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::merge::{merge_cuts, shade, CutKeys};
use relight_bake::cuts::visibility::CutFunction;
use relight_bake::cuts::CutsBake;
use relight_scene::camera::Camera;
use relight_scene::material::maps::{shading_at, SceneMaps};
use relight_scene::material::microfacet;
use relight_scene::material::{Material, MaterialEval};
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use std::f32::consts::{FRAC_1_PI, PI};

/// Smallest `cos theta_o` at which the BRDF without its cosine is evaluated (directions
/// below are lifted to it; see [`CutsShader::shade_fragment`]).
const HORIZON: f32 = 1e-3;

/// The cuts renderer over one whole-mesh bake.
pub struct CutsShader<'a> {
    mesh: &'a TriMesh,
    /// The constant materials (what [`shading_at`] reads)...
    constants: Vec<Material>,
    /// ... and the same prepared for evaluation.
    materials: Vec<MaterialEval>,
    /// Their texture and normal maps ([`CutsShader::with_maps`]).
    maps: SceneMaps,
    bake: &'a CutsBake,
    function: CutFunction,
    /// Average glossy BRDFs over each cluster's spread ([`CutsShader::with_cluster_spread`]).
    spread: bool,
}

impl<'a> CutsShader<'a> {
    /// A renderer of `bake` (one cut per vertex of `mesh`) with `materials` (indexed by
    /// `mesh.material_ids`; any materials: nothing of them is baked), whose cuts approximate
    /// `function`.
    ///
    /// # Panics
    /// If the bake does not hold one cut per vertex.
    pub fn new(
        mesh: &'a TriMesh,
        materials: Vec<Material>,
        bake: &'a CutsBake,
        function: CutFunction,
    ) -> Self {
        assert_eq!(
            bake.cuts.vertex_count(),
            mesh.vertex_count(),
            "one cut per vertex"
        );
        CutsShader {
            mesh,
            materials: materials.iter().copied().map(MaterialEval::new).collect(),
            constants: materials,
            maps: SceneMaps::default(),
            bake,
            function,
            spread: false,
        }
    }

    /// With `on`, every material that is not purely diffuse has its BRDF averaged over each
    /// merged cluster's spread ([`LightCut::spread_average`], five evaluations where a
    /// cluster is wider than [`relight_bake::cuts::light_cut::SPREAD_MIN_ANGLE`]) instead of
    /// evaluated at the cluster's direction alone; Lambert keeps its one evaluation.
    pub fn with_cluster_spread(mut self, on: bool) -> Self {
        self.spread = on;
        self
    }

    /// With the materials' texture and normal maps (built over this shader's mesh): every
    /// fragment of a mapped material is shaded with [`shading_at`]'s material and normal,
    /// the path tracer's lookup.
    pub fn with_maps(mut self, maps: SceneMaps) -> Self {
        self.maps = maps;
        self
    }

    /// The prepared material and shading normal of fragment `f` ([`shading_at`] when its
    /// material has maps; `owned` holds the mapped material).
    #[inline]
    fn material_at<'s>(
        &'s self,
        f: &Fragment,
        owned: &'s mut Option<MaterialEval>,
    ) -> (&'s MaterialEval, Vec3) {
        let id = self.mesh.material_ids[f.tri as usize];
        if self.maps.of(id).is_none() {
            return (&self.materials[id as usize], f.shading_normal);
        }
        let (m, frame) = shading_at(
            self.mesh,
            &self.constants,
            &self.maps,
            f.tri,
            f.bary,
            f.shading_normal,
        );
        (owned.insert(MaterialEval::new(m)), frame.n)
    }

    /// Whether `material` is shaded with the cluster spread.
    #[inline]
    fn spreads(&self, material: &MaterialEval) -> bool {
        self.spread && !material.material().is_diffuse_only()
    }

    /// Outgoing radiance of fragment `f` towards the eye at `eye` under `light`. With cuts
    /// holding the cosine, a merged cluster whose mean direction is below the shading horizon
    /// still holds visible lights above it (the cut's mean says how much): its BRDF is
    /// evaluated at that direction lifted onto the horizon instead of dropping it.
    pub fn shade_fragment(&self, light: &LightCut, f: &Fragment, eye: Vec3) -> Vec3 {
        let mut owned = None;
        let (material, n) = self.material_at(f, &mut owned);
        let frame = material.material().shading_frame(n);
        let wi = frame.to_local((eye - f.position).normalize_or_zero());
        if wi.z <= 0.0 {
            return Vec3::ZERO; // one-sided materials, as the path tracer's
        }
        let [a, b, c] = self.mesh.indices[f.tri as usize];
        let cuts = [a, b, c].map(|v| self.bake.cuts.cut(v as usize));
        shade(light, cuts, f.bary, self.spreads(material), |w| {
            self.brdf(material, wi, frame.to_local(w))
        })
    }

    /// Render `camera` under `light` (the environment drawn behind the objects if
    /// `background`): [`raster::render_deferred_batched`], which hands over a triangle's
    /// fragments together, so its merged cut ([`TriangleCut`]) is built once per triangle
    /// and band of rows and summed per fragment. Equal to [`CutsShader::shade_fragment`] at
    /// every fragment up to f32 rounding (tested); that per-fragment merge is the slow
    /// reference.
    ///
    /// # Panics
    /// If `opts.supersample == 0` or the camera's image is empty.
    pub fn render(
        &self,
        light: &LightCut,
        camera: &Camera,
        background: Option<&Environment>,
        opts: &RasterOptions,
    ) -> Rendered {
        self.render_stage(light, camera, background, opts, CutsStage::Full)
    }

    /// [`CutsShader::render`] stopped after `stage` (the time split of `relight bench`):
    /// the fragments are black before [`CutsStage::Full`].
    ///
    /// # Panics
    /// As [`CutsShader::render`].
    pub fn render_stage(
        &self,
        light: &LightCut,
        camera: &Camera,
        background: Option<&Environment>,
        opts: &RasterOptions,
        stage: CutsStage,
    ) -> Rendered {
        let eye = Vec3::from_array(camera.origin);
        raster::render_deferred_batched(self.mesh, camera, background, opts, |tri, fs, out| {
            if stage == CutsStage::GBuffer {
                return;
            }
            TRIANGLE_CUT.with_borrow_mut(|t| {
                t.build(self, light, tri);
                if stage == CutsStage::Full {
                    self.shade_triangle(light, t, tri, fs, eye, out);
                }
            })
        })
    }

    /// Render with the per-fragment merge ([`CutsShader::shade_fragment`]): the slow
    /// reference of [`CutsShader::render`] (tests and `relight bench`).
    ///
    /// # Panics
    /// As [`CutsShader::render`].
    pub fn render_per_fragment(
        &self,
        light: &LightCut,
        camera: &Camera,
        background: Option<&Environment>,
        opts: &RasterOptions,
    ) -> Rendered {
        let eye = Vec3::from_array(camera.origin);
        raster::render_deferred(self.mesh, camera, background, opts, |f| {
            self.shade_fragment(light, f, eye)
        })
    }

    /// Eq. 5 at each fragment of triangle `tri` from its merged cut `t`.
    fn shade_triangle(
        &self,
        light: &LightCut,
        t: &TriangleCut,
        tri: u32,
        fs: &[Fragment],
        eye: Vec3,
        out: &mut [Vec3],
    ) {
        for (f, o) in fs.iter().zip(out.iter_mut()) {
            debug_assert_eq!(f.tri, tri);
            let mut owned = None;
            let (material, n) = self.material_at(f, &mut owned);
            let spread = self.spreads(material);
            let view = (eye - f.position).normalize_or_zero();
            if view.dot(n) <= 0.0 {
                *o = Vec3::ZERO; // one-sided materials, as the path tracer's
                continue;
            }
            let b = f.bary;
            *o = match (*material.material(), self.function) {
                // eval / cos = albedo / pi for every cluster: the sum factors per corner.
                (Material::Lambert { albedo }, CutFunction::VisibilityCosine) => {
                    albedo * FRAC_1_PI * (t.sums[0] * b[0] + t.sums[1] * b[1] + t.sums[2] * b[2])
                }
                // eval = albedo / pi max(0, n . w): no frame needed.
                (Material::Lambert { albedo }, CutFunction::Visibility) => {
                    albedo * FRAC_1_PI * t.lambert_sum(b, n)
                }
                // The GGX conductor in world space over lanes (the same definition).
                (Material::GgxConductor { specular, alpha }, CutFunction::Visibility)
                    if !spread =>
                {
                    specular * t.ggx_sum(b, n, view, alpha)
                }
                (m, _) => {
                    let frame = m.shading_frame(n);
                    let wi = frame.to_local(view);
                    let mut sum = Vec3::ZERO;
                    for k in 0..t.len() {
                        let (power, v, dir) = t.cluster(k, b);
                        if v > 0.0 {
                            let f = |w: Vec3| self.brdf(material, wi, frame.to_local(w));
                            let f = if spread {
                                light.spread_average(t.node[k], f)
                            } else {
                                f(dir)
                            };
                            sum += power * v * f;
                        }
                    }
                    sum
                }
            };
        }
    }

    /// The BRDF factor of one merged cluster in the shading frame ([`cluster_brdf`]).
    #[inline]
    fn brdf(&self, material: &MaterialEval, wi: Vec3, wo: Vec3) -> Vec3 {
        cluster_brdf(self.function, material, wi, wo)
    }
}

/// How far [`CutsShader::render_stage`] goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CutsStage {
    /// Rasterise the G-buffer and group its fragments by triangle only.
    GBuffer,
    /// Also merge each triangle's cuts with the light cut.
    Merge,
    /// Also shade every fragment: the frame.
    Full,
}

thread_local! {
    /// Each rendering thread's [`TriangleCut`] (reused, so a frame allocates once per thread).
    static TRIANGLE_CUT: std::cell::RefCell<TriangleCut> = Default::default();
}

/// Lanes of the per-fragment sums (independent partial sums the compiler can keep in one
/// SIMD register each); a [`TriangleCut`]'s length is padded to a multiple of it.
const LANES: usize = 8;

/// One triangle's merged cut: the union of its three vertex cuts and the light cut (the
/// traversal of sec. 3.2), with what the per-fragment sum of Eq. 5 needs of each cluster
/// `k`: `|C'_k| <L O>_k`, the three corners' visibility means and the cluster's direction,
/// as structure-of-arrays padded with zero clusters to a multiple of [`LANES`]. Clusters no
/// corner sees, or that hold no light, are dropped (they add nothing).
#[derive(Default)]
struct TriangleCut {
    /// `|C'_k| <L O>_k`, per colour channel.
    power: [Vec<f32>; 3],
    /// `<v_j>_k` of corners `j = 0, 1, 2`.
    vis: [Vec<f32>; 3],
    /// The cluster's mean direction ([`relight_bake::cuts::tree::LightTree::direction`]),
    /// per axis.
    dir: [Vec<f32>; 3],
    /// The cluster's tree node (post-order index; [`LightCut::spread_average`]).
    node: Vec<u32>,
    /// `sum_k power_k vis_k[j]` per corner (the Lambert sum without a per-cluster BRDF).
    sums: [Vec3; 3],
    /// Clusters of this triangle, padding included (the arrays may be longer).
    len: usize,
}

impl TriangleCut {
    /// Clusters, padding included.
    fn len(&self) -> usize {
        self.len
    }

    /// Merge triangle `tri`'s cuts with `light` into `self` (its arrays reused: they only
    /// grow, and are written by index; a merged cut is at most as long as its four cuts
    /// together).
    fn build(&mut self, shader: &CutsShader<'_>, light: &LightCut, tri: u32) {
        self.sums = [Vec3::ZERO; 3];
        let [a, b, c] = shader.mesh.indices[tri as usize];
        let cuts = [
            shader.bake.cuts.cut(a as usize),
            shader.bake.cuts.cut(b as usize),
            shader.bake.cuts.cut(c as usize),
        ];
        let bound = (light.len() + cuts.iter().map(|c| c.index.len()).sum::<usize>())
            .next_multiple_of(LANES);
        if self.power[0].len() < bound {
            for a in [&mut self.power, &mut self.vis, &mut self.dir] {
                a.iter_mut().for_each(|x| x.resize(bound, 0.0));
            }
        }
        let keys = [
            CutKeys::from(light),
            cuts[0].into(),
            cuts[1].into(),
            cuts[2].into(),
        ];
        let mut n = 0;
        let mut sums = [Vec3::ZERO; 3];
        merge_cuts(keys, |node, pos| {
            let q = [
                cuts[0].value[pos[1]],
                cuts[1].value[pos[2]],
                cuts[2].value[pos[3]],
            ];
            let power = light.value[pos[0]] * node.leaves() as f32;
            if q == [0; 3] || power == Vec3::ZERO {
                return;
            }
            let dir = light.direction(node.index);
            if self.node.len() < bound {
                self.node.resize(bound, 0);
            }
            self.node[n] = node.index;
            for j in 0..3 {
                let v = dequantise(q[j]);
                sums[j] += power * v;
                self.vis[j][n] = v;
                self.power[j][n] = power[j];
                self.dir[j][n] = dir[j];
            }
            n += 1;
        });
        self.sums = sums;
        self.len = n.next_multiple_of(LANES);
        // Zero clusters pad the last lane group.
        for a in [&mut self.power, &mut self.vis, &mut self.dir] {
            a.iter_mut().for_each(|x| x[n..self.len].fill(0.0));
        }
    }

    /// Cluster `k`'s power, visibility interpolated with `b`, and direction.
    #[inline]
    fn cluster(&self, k: usize, b: [f32; 3]) -> (Vec3, f32, Vec3) {
        let at = |a: &[Vec<f32>; 3]| Vec3::new(a[0][k], a[1][k], a[2][k]);
        let v = b[0] * self.vis[0][k] + b[1] * self.vis[1][k] + b[2] * self.vis[2][k];
        (at(&self.power), v, at(&self.dir))
    }

    /// `sum_k power_k (b . vis_k) max(0, n . dir_k)`: Eq. 5 for a Lambert BRDF without its
    /// `albedo / pi`, over [`LANES`] partial sums.
    fn lambert_sum(&self, b: [f32; 3], n: Vec3) -> Vec3 {
        fn chunks(a: &[Vec<f32>; 3]) -> [&[[f32; LANES]]; 3] {
            a.each_ref().map(|x| x.as_chunks::<LANES>().0)
        }
        let groups = self.len / LANES;
        let (p, v, d) = (chunks(&self.power), chunks(&self.vis), chunks(&self.dir));
        let mut acc = [[0.0f32; LANES]; 3];
        for i in 0..groups {
            for l in 0..LANES {
                let c = (n.x * d[0][i][l] + n.y * d[1][i][l] + n.z * d[2][i][l]).max(0.0);
                let w = (b[0] * v[0][i][l] + b[1] * v[1][i][l] + b[2] * v[2][i][l]) * c;
                for ch in 0..3 {
                    acc[ch][l] += p[ch][i][l] * w;
                }
            }
        }
        Vec3::from_array(acc.map(|a| a.iter().sum()))
    }

    /// `sum_k power_k (b . vis_k) f(v, dir_k)` for the GGX conductor of `Material::eval`
    /// without its specular colour, `f = D(h) G1(v, h) G1(w, h) / (4 n.v)` (height-separable
    /// Smith masking, `relight_scene::material::microfacet`), evaluated in world space over
    /// [`LANES`] partial sums: `n . h`, `tan^2` of `w` from `n . w`, and `G1(v, h)`, which
    /// depends on the fragment only, hoisted. `n . v > 0` (the caller's one-sided test).
    fn ggx_sum(&self, b: [f32; 3], n: Vec3, v: Vec3, alpha: f32) -> Vec3 {
        let a2 = {
            let a = alpha.max(microfacet::MIN_ALPHA);
            a * a
        };
        let ci = n.dot(v);
        let g1 = |c: f32| {
            let tan2 = a2 * (1.0 - c * c) / (c * c);
            2.0 / (1.0 + (1.0 + tan2.max(0.0)).sqrt())
        };
        // D = 1 / (pi a^2 s^2) with s = (1 - (n.h)^2) / a^2 + (n.h)^2.
        let k = g1(ci) / (4.0 * ci) / (PI * a2);
        fn chunks(a: &[Vec<f32>; 3]) -> [&[[f32; LANES]]; 3] {
            a.each_ref().map(|x| x.as_chunks::<LANES>().0)
        }
        let (p, vis, d) = (chunks(&self.power), chunks(&self.vis), chunks(&self.dir));
        let mut acc = [[0.0f32; LANES]; 3];
        for i in 0..self.len / LANES {
            for l in 0..LANES {
                let w = Vec3::new(d[0][i][l], d[1][i][l], d[2][i][l]);
                let co = n.dot(w);
                let h = v + w;
                let hn = n.dot(h) / h.length();
                let s = (1.0 - hn * hn) / a2 + hn * hn;
                let x = (b[0] * vis[0][i][l] + b[1] * vis[1][i][l] + b[2] * vis[2][i][l]) * g1(co)
                    / (s * s);
                let x = if co > 0.0 && hn > 0.0 { x } else { 0.0 };
                for ch in 0..3 {
                    acc[ch][l] += p[ch][i][l] * x;
                }
            }
        }
        Vec3::from_array(acc.map(|a| a.iter().sum())) * k
    }
}

#[cfg(test)]
mod ward_tests;

#[cfg(test)]
pub(crate) mod texture_tests;

#[cfg(test)]
mod tests;

/// The BRDF factor of one merged cluster towards `wo` in the shading frame, for cuts holding
/// `function` (see [`CutsShader::shade_fragment`]): the BRDF with its cosine over visibility
/// cuts, without it (the cosine is in the cuts) over visibility-cosine cuts, `wo` then lifted
/// to [`HORIZON`] where it dips below it. Shared with the local-light frame
/// (`crate::shade_local`).
#[inline]
pub(crate) fn cluster_brdf(
    function: CutFunction,
    material: &MaterialEval,
    wi: Vec3,
    wo: Vec3,
) -> Vec3 {
    match function {
        CutFunction::VisibilityCosine => {
            let wo = if wo.z >= HORIZON {
                wo
            } else {
                Vec3::new(wo.x, wo.y, HORIZON).normalize()
            };
            material.eval(wi, wo) / wo.z
        }
        CutFunction::Visibility => material.eval(wi, wo),
    }
}
