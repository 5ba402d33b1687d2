//! Per-pixel shading of the `cuts` method (Cheslack-Postava et al. 2008, sec. 4.2; the bake
//! is `relight_bake::cuts`).
//!
//! Deferred shading (Eq. 5): for every visible sample, the three visibility cuts of its
//! triangle's corners, interpolated with the sample's barycentric weights, are merged with
//! the frame's illumination cut (the traversal of sec. 3.2), and the sample's material is
//! evaluated at each merged cluster's direction:
//! `B = sum_k |C'_k| <L O>_k (sum_j b_j <v_j>_k) f(<w>_k)`. Three ways, one reference for
//! the next:
//! * [`CutsShader::render_per_fragment`]: the merge at every sample
//!   ([`relight_bake::cuts::merge::shade`]), the paper's algorithm as written: the slow
//!   reference;
//! * [`CutsShader::render_merged`]: the merge once per triangle and band of rows
//!   (`shade_cuts::triangle`), equal to it up to f32 rounding;
//! * [`CutsShader::render`], the default: Lambert materials from per-corner lists, every
//!   vertex's cut merged with the light cut once per light cut and the three corners' lists
//!   summed per sample (`shade_cuts::corners`: the cosine is sampled at each corner's own
//!   clusters; no further from the path tracer, tested), other materials as `render_merged`.
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

mod cache;
mod corners;
pub(crate) mod lanes;
mod triangle;

use crate::mapped::MappedMaterials;
use crate::raster::{self, Fragment, RasterOptions, Rendered};
pub use cache::DEFAULT_BUDGET as DEFAULT_MERGE_CACHE_BYTES;
use cache::{LightTables, MergedCache};
use corners::CornerLists;
use glam::Vec3;
use relight_bake::cuts::cut::CutRef;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::merge::shade;
use relight_bake::cuts::visibility::CutFunction;
use relight_bake::cuts::CutsBake;
use relight_scene::camera::Camera;
use relight_scene::material::maps::SceneMaps;
use relight_scene::material::{Material, MaterialEval};
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use std::f32::consts::FRAC_1_PI;
use std::sync::{Arc, Mutex};
use triangle::{TriangleCut, TRIANGLE_CUT};

/// Smallest `cos theta_o` at which the BRDF without its cosine is evaluated (directions
/// below are lifted to it; see [`CutsShader::shade_fragment`]).
const HORIZON: f32 = 1e-3;

/// The cuts renderer over one whole-mesh bake.
pub struct CutsShader<'a> {
    mesh: &'a TriMesh,
    /// The materials and their texture and normal maps ([`CutsShader::with_maps`]).
    materials: MappedMaterials,
    bake: &'a CutsBake,
    function: CutFunction,
    /// Average glossy BRDFs over each cluster's spread ([`CutsShader::with_cluster_spread`]).
    spread: bool,
    /// The corner lists and light-cut tables of the last light cut rendered
    /// ([`CutsShader::prepare`]).
    lit: Mutex<Option<Arc<Lit>>>,
    /// The triangles' visibility unions, kept across frames and light cuts
    /// ([`CutsShader::with_merge_cache`]; `None` when off).
    merged: Option<MergedCache>,
    /// Whether a material is Lambert (shaded from the corner lists).
    has_lambert: bool,
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
            has_lambert: materials
                .iter()
                .any(|m| matches!(m, Material::Lambert { .. })),
            materials: MappedMaterials::new(materials),
            bake,
            function,
            spread: false,
            lit: Mutex::new(None),
            merged: MergedCache::new(mesh, cache::DEFAULT_BUDGET),
        }
    }

    /// With `on`, every material that is not purely diffuse has its glossy lobe averaged over
    /// each merged cluster's spread ([`LightCut::spread_lobes`], five evaluations where a
    /// cluster is wider than [`relight_bake::cuts::light_cut::SPREAD_MIN_ANGLE`]) instead of
    /// evaluated at the cluster's direction alone; diffuse lobes (a plastic's base, Lambert)
    /// keep their one evaluation.
    pub fn with_cluster_spread(mut self, on: bool) -> Self {
        self.spread = on;
        self
    }

    /// Keep at most `bytes` of triangles' visibility unions across frames and light cuts
    /// (default [`DEFAULT_MERGE_CACHE_BYTES`]; 0: none, every frame merges every visible
    /// triangle). Module docs of `shade_cuts::cache`: the frames are the same bits either way.
    pub fn with_merge_cache(mut self, bytes: usize) -> Self {
        self.merged = MergedCache::new(self.mesh, bytes);
        self
    }

    /// With the materials' texture and normal maps (built over this shader's mesh): every
    /// fragment of a mapped material is shaded with [`relight_scene::material::maps::shading_at`]'s material and normal,
    /// the path tracer's lookup.
    pub fn with_maps(self, maps: SceneMaps) -> Self {
        CutsShader {
            materials: self.materials.with_maps(maps),
            ..self
        }
    }

    /// The prepared material and shading normal of fragment `f` ([`MappedMaterials::at`] when its
    /// material has maps; `owned` holds the mapped material).
    #[inline]
    fn material_at<'s>(
        &'s self,
        f: &Fragment,
        owned: &'s mut Option<MaterialEval>,
    ) -> (&'s MaterialEval, Vec3) {
        self.materials.at(self.mesh, f, owned)
    }

    /// The visibility cuts of triangle `tri`'s three corners.
    #[inline]
    fn vertex_cuts(&self, tri: u32) -> [CutRef<'_>; 3] {
        self.mesh.indices[tri as usize].map(|v| self.bake.cuts.cut(v as usize))
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
        let cuts = self.vertex_cuts(f.tri);
        shade(light, cuts, f.bary, self.spreads(material), |w| {
            self.lobes(material, wi, frame.to_local(w))
        })
    }

    /// Render `camera` under `light` (the environment drawn behind the objects if
    /// `background`), the default frame, over [`raster::render_deferred_batched`] (a
    /// triangle's fragments handed over together):
    /// * triangles of a **Lambert** material from the corner lists: every vertex's cut merged
    ///   once with `light` ([`CutsShader::prepare`], cached until the light cut changes) and,
    ///   per fragment, the three corners' lists summed with the barycentric weights (Eq. 5
    ///   summed by corner, module docs of `shade_cuts::corners`). Equal to the triangle merge
    ///   over cuts holding the cosine (tested); over binary visibility the cosine is sampled
    ///   at each corner's own clusters, no further from the path tracer (tested);
    /// * other materials as [`CutsShader::render_merged`] (for glossy lobes the corners'
    ///   coarser clusters measured further from the path tracer), each triangle's merged cut
    ///   from its kept visibility union and the light cut's tables (`shade_cuts::cache`: the
    ///   same bits; only triangles drawn for the first time are merged).
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
    /// the fragments are black before [`CutsStage::Full`]. If `light` is not the cached one,
    /// the corner lists and the light cut's tables are built first ([`CutsShader::prepare`];
    /// the triangles' visibility unions are kept).
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
        let lit = self.prepared(light);
        let merged = self.merged.as_ref().zip(lit.tables.as_ref());
        if let (Some((m, _)), CutsStage::Full) = (merged, stage) {
            m.begin_frame();
        }
        let eye = Vec3::from_array(camera.origin);
        raster::render_deferred_batched(self.mesh, camera, background, opts, |tri, fs, out| {
            if stage == CutsStage::GBuffer {
                return;
            }
            let constant = self
                .materials
                .of_triangle(self.mesh, tri as usize)
                .material();
            match (&lit.lists, merged) {
                (Some(lists), _) if matches!(constant, Material::Lambert { .. }) => {
                    self.shade_corners(light, lists, tri, fs, eye, out)
                }
                (_, Some((merged, tables))) => TRIANGLE_CUT.with_borrow_mut(|t| {
                    let spread = self.glossy_spread(constant);
                    merged.fill(t, self, (light, tables), tri, spread);
                    self.shade_triangle(light, t, tri, fs, eye, out);
                }),
                _ => self.merge_and_shade(light, constant, tri, fs, eye, out),
            }
        })
    }

    /// Prepare the frames of `light` now (what [`CutsShader::render`] does on its first
    /// frame under a new light cut: once per environment and rotation, independent of the
    /// camera and the materials): with a Lambert material, merge every vertex's cut with
    /// `light` (the traversal of sec. 3.2 over two cuts) and keep the lists; build the light
    /// cut's tables for the kept visibility unions of the triangles (`shade_cuts::cache`).
    /// Returns the corner lists' figures, `None` (no lists) when no material is Lambert.
    pub fn prepare(&self, light: &LightCut) -> Option<CornerStats> {
        let lit = self.prepared(light);
        lit.lists.as_ref().map(|lists| CornerStats {
            mean_len: lists.mean_len(),
            bytes: lists.bytes(),
        })
    }

    /// Bytes of the triangles' visibility unions kept ([`CutsShader::with_merge_cache`]).
    pub fn merge_cache_bytes(&self) -> usize {
        self.merged.as_ref().map_or(0, |m| m.bytes())
    }

    /// What the frames of `light` keep, built if the cache holds another light cut (or
    /// none). The comparison is exact (every node, value and direction).
    fn prepared(&self, light: &LightCut) -> Arc<Lit> {
        let mut cache = self.lit.lock().unwrap_or_else(|e| e.into_inner());
        match &*cache {
            Some(lit) if lit.light == *light => lit.clone(),
            _ => {
                // The previous lists' arrays are reused unless a frame still holds them (then
                // they are dropped with it, never kept beside the new ones by the cache).
                let reuse = cache
                    .take()
                    .and_then(|old| Arc::try_unwrap(old).ok())
                    .and_then(|old| old.lists);
                let lit = Arc::new(Lit {
                    lists: self
                        .has_lambert
                        .then(|| CornerLists::build(&self.bake.cuts, light, reuse)),
                    tables: self
                        .merged
                        .is_some()
                        .then(|| LightTables::new(&self.bake.tree, light))
                        .flatten(),
                    light: light.clone(),
                });
                *cache = Some(lit.clone());
                lit
            }
        }
    }

    /// Whether triangles of material `constant` are merged for the cluster spread.
    #[inline]
    fn glossy_spread(&self, constant: &Material) -> bool {
        self.spread && !constant.is_diffuse_only()
    }

    /// The previous default frame: [`raster::render_deferred_batched`], which hands over a
    /// triangle's fragments together, so its merged cut (the three vertex cuts and the light
    /// cut, `shade_cuts::triangle`) is built once per triangle and band of rows and summed
    /// per fragment. Equal to [`CutsShader::shade_fragment`] at every fragment up to f32
    /// rounding (tested).
    ///
    /// # Panics
    /// As [`CutsShader::render`].
    pub fn render_merged(
        &self,
        light: &LightCut,
        camera: &Camera,
        background: Option<&Environment>,
        opts: &RasterOptions,
    ) -> Rendered {
        let eye = Vec3::from_array(camera.origin);
        raster::render_deferred_batched(self.mesh, camera, background, opts, |tri, fs, out| {
            let constant = self
                .materials
                .of_triangle(self.mesh, tri as usize)
                .material();
            self.merge_and_shade(light, constant, tri, fs, eye, out)
        })
    }

    /// Triangle `tri`'s cuts merged with `light` (for the cluster spread if its material
    /// `constant` is glossy and the spread is on) and its fragments shaded from them.
    fn merge_and_shade(
        &self,
        light: &LightCut,
        constant: &Material,
        tri: u32,
        fs: &[Fragment],
        eye: Vec3,
        out: &mut [Vec3],
    ) {
        TRIANGLE_CUT.with_borrow_mut(|t| {
            t.build(self, light, tri, self.glossy_spread(constant));
            self.shade_triangle(light, t, tri, fs, eye, out);
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

    /// Eq. 5 summed by corner at each fragment of triangle `tri`, whose material is Lambert,
    /// from the corner lists `lists` of `light` (module docs of `shade_cuts::corners`):
    /// `albedo / pi sum_j b_j sum_k P_jk max(0, n . w_jk)` (binary visibility), or
    /// `albedo / pi sum_j b_j sum_k P_jk` with the cosine in the cuts. A fragment whose maps
    /// made its material another model is shaded by the per-fragment merge.
    fn shade_corners(
        &self,
        light: &LightCut,
        lists: &CornerLists,
        tri: u32,
        fs: &[Fragment],
        eye: Vec3,
        out: &mut [Vec3],
    ) {
        let corners = self.mesh.indices[tri as usize];
        self.shade_fragments(tri, fs, eye, out, |f, material, n, _| {
            let b = f.bary;
            let by_corner = |sum: &dyn Fn(u32) -> Vec3| -> Vec3 {
                sum(corners[0]) * b[0] + sum(corners[1]) * b[1] + sum(corners[2]) * b[2]
            };
            match (*material.material(), self.function) {
                // eval / cos = albedo / pi for every cluster: the sum factors per corner.
                (Material::Lambert { albedo }, CutFunction::VisibilityCosine) => {
                    albedo * FRAC_1_PI * by_corner(&|v| lists.sum(v))
                }
                // eval = albedo / pi max(0, n . w): no frame needed.
                (Material::Lambert { albedo }, CutFunction::Visibility) => {
                    albedo * FRAC_1_PI * by_corner(&|v| lists.lambert(v, n))
                }
                _ => self.shade_fragment(light, f, eye),
            }
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
        // The Lambert sums per corner, once per triangle when a fragment needs them.
        let sums = std::cell::OnceCell::new();
        self.shade_fragments(tri, fs, eye, out, |f, material, n, view| {
            let b = f.bary;
            match (*material.material(), self.function) {
                // eval / cos = albedo / pi for every cluster: the sum factors per corner
                // (the sums are those of whole clusters, spread or not).
                (Material::Lambert { albedo }, CutFunction::VisibilityCosine) => {
                    let s = sums.get_or_init(|| t.corner_sums());
                    albedo * FRAC_1_PI * (s[0] * b[0] + s[1] * b[1] + s[2] * b[2])
                }
                // A fragment whose maps changed whether it spreads (rare): the reference.
                _ if self.spreads(material) != t.spread => self.shade_fragment(light, f, eye),
                // eval = albedo / pi max(0, n . w): no frame needed.
                (Material::Lambert { albedo }, CutFunction::Visibility) => {
                    albedo * FRAC_1_PI * t.lambert_sum(b, n)
                }
                // The GGX conductor in world space over lanes (the same definition; with
                // the spread, each cluster's five-point rule in the lanes).
                (Material::GgxConductor { specular, alpha }, CutFunction::Visibility) => {
                    specular * t.ggx_sum(b, n, view, alpha)
                }
                // The GGX plastic likewise (its specular and diffuse terms).
                (
                    Material::GgxPlastic {
                        diffuse,
                        specular,
                        alpha,
                        ior,
                    },
                    CutFunction::Visibility,
                ) => {
                    let tables = material.plastic_tables().expect("a plastic's tables");
                    t.plastic_sum(b, n, view, (diffuse, specular, alpha, ior), tables)
                }
                (m, _) => {
                    let frame = m.shading_frame(n);
                    let wi = frame.to_local(view);
                    let mut sum = Vec3::ZERO;
                    for k in 0..t.len() {
                        let (power, v, dir, node) = t.cluster(k, b);
                        if v > 0.0 {
                            let f = |w: Vec3| self.lobes(material, wi, frame.to_local(w));
                            let f = if t.spread {
                                light.spread_lobes(node, f)
                            } else {
                                let [glossy, diffuse] = f(dir);
                                glossy + diffuse
                            };
                            sum += power * v * f;
                        }
                    }
                    sum
                }
            }
        })
    }

    /// `shade(f, material, n, view)` into `out` for each fragment `f` of triangle `tri`, with
    /// its prepared material and shading normal ([`CutsShader::material_at`]) and the unit
    /// direction to `eye`; black where `view . n <= 0` (one-sided materials, as the path
    /// tracer's).
    fn shade_fragments(
        &self,
        tri: u32,
        fs: &[Fragment],
        eye: Vec3,
        out: &mut [Vec3],
        shade: impl Fn(&Fragment, &MaterialEval, Vec3, Vec3) -> Vec3,
    ) {
        for (f, o) in fs.iter().zip(out.iter_mut()) {
            debug_assert_eq!(f.tri, tri);
            let mut owned = None;
            let (material, n) = self.material_at(f, &mut owned);
            let view = (eye - f.position).normalize_or_zero();
            *o = if view.dot(n) <= 0.0 {
                Vec3::ZERO
            } else {
                shade(f, material, n, view)
            };
        }
    }

    /// The BRDF factor of one merged cluster in the shading frame as its `[glossy, diffuse]`
    /// lobes ([`cluster_lobes`]).
    #[inline]
    fn lobes(&self, material: &MaterialEval, wi: Vec3, wo: Vec3) -> [Vec3; 2] {
        cluster_lobes(self.function, material, wi, wo)
    }
}

/// How far [`CutsShader::render_stage`] goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CutsStage {
    /// Rasterise the G-buffer and group its fragments by triangle only.
    GBuffer,
    /// Also shade every fragment: the frame.
    Full,
}

/// The corner lists of one light cut ([`CutsShader::prepare`]: each vertex's cut merged with
/// it, sec. 3.2, for Eq. 5 summed by corner).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CornerStats {
    /// Mean clusters per vertex (a vertex's cut merged with the light cut, clusters it does
    /// not see dropped).
    pub mean_len: f64,
    /// Bytes of the lists.
    pub bytes: usize,
}

/// What the frames of one light cut keep: the corner lists (with a Lambert material) and the
/// tables for the triangles' visibility unions (unless the cache is off), with the light cut
/// they were built for.
struct Lit {
    light: LightCut,
    lists: Option<CornerLists>,
    tables: Option<LightTables>,
}

#[cfg(test)]
mod ward_tests;

#[cfg(test)]
mod corner_tests;

#[cfg(test)]
mod cache_tests;

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
    let [glossy, diffuse] = cluster_lobes(function, material, wi, wo);
    glossy + diffuse
}

/// [`cluster_brdf`] as the material's `[glossy, diffuse]` lobes (`MaterialEval::lobes`), for
/// [`LightCut::spread_lobes`].
#[inline]
pub(crate) fn cluster_lobes(
    function: CutFunction,
    material: &MaterialEval,
    wi: Vec3,
    wo: Vec3,
) -> [Vec3; 2] {
    match function {
        CutFunction::VisibilityCosine => {
            let wo = if wo.z >= HORIZON {
                wo
            } else {
                Vec3::new(wo.x, wo.y, HORIZON).normalize()
            };
            material.lobes(wi, wo).map(|l| l / wo.z)
        }
        CutFunction::Visibility => material.lobes(wi, wo),
    }
}
