//! Tabulating the glossy and diffuse transport of one vertex for all views (thesis section
//! 2.2.1 and 3.1): the input of the fit ([`super::fit`]).
//!
//! # Conventions
//! * Views are the vertices of `Icosphere::new(3)` in the **global** frame, pointing from the
//!   vertex towards the viewer (`wi` of [`Material::eval`]); texels `w` point towards the
//!   light (`wo`). The BRDF frame is [`Material::shading_frame`] of the vertex's shading normal.
//! * A cube-map value is a kernel per steradian: `L_o(x, v) = sum_w T(w) L(w) dA(w)` with
//!   `dA` the exact texel solid angle ([`relight_sphere::cubemap::texel_solid_angle`]); `T`
//!   is evaluated at texel centres (thesis sec. 2.2.1: "evaluated for each texel").
//! * Direct glossy `T(w) = glossy_eval(v, w) V(w)` ([`Material::glossy_eval`], cosine
//!   included); the GGX materials go through a vectorisable rearrangement of the same formula
//!   (`kernel.rs`, tested against `glossy_eval`).
//! * Visibility `V(w)` is traced once per vertex at `direct_res` with the rays of the SH bake
//!   ([`crate::transport::surface_ray`]: origin offset along the area-weighted geometric
//!   normal). Texels below the geometric horizon or the shading horizon are not traced
//!   (`V = 0`: the surface itself blocks them, or the BRDF is zero). Surfaces are one-sided,
//!   as in Mitsuba: a ray hitting anything, front or back, is occluded.
//! * Indirect paths scatter at a hit with the material of the hit triangle's corner of
//!   largest barycentric weight (materials are per vertex; no blending per hit).
//! * Determinism: the indirect paths of view `v` of vertex `x` draw their random numbers from
//!   `Rng::new(seed, x * views + v)` only, so the result depends on the seed, never on the
//!   threads.

mod kernel;

use super::SgBakeSettings;
use crate::transport::{check_mesh_geometry, surface_ray, vertex_geometric_normals};
use crate::BakeError;
use glam::Vec3;
use kernel::GlossyKernel;
use relight_scene::accel::{Hit, Ray, RayCaster};
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_sphere::cubemap::{dir_to_texel, texel_coords, texel_dir, texel_solid_angle};
use relight_sphere::icosphere::Icosphere;
use relight_sphere::sh::{eval_sh, sh_count};
use relight_sphere::warp::{cranley_patterson, hammersley, Frame, Rng};
use std::f32::consts::FRAC_1_PI;

/// The tabulated transport of one vertex for every view (see the parent module docs for what
/// each component holds; texel order is `relight_sphere::cubemap::texel_index`).
#[derive(Clone, Debug, Default)]
pub struct VertexTransport {
    /// Per view: `true` if the view is above the clamping elevation, `false` if its data is
    /// that of the clamped view.
    pub view_visible: Vec<bool>,
    /// Per view: the direction whose transport the view holds (the view, or the clamped
    /// view; [`TransportContext::view_direction`]). Empty: the icosahedron's views.
    pub view_dirs: Vec<Vec3>,
    /// Direct glossy, `direct[view * 6 * direct_res^2 + texel]`, RGB, per steradian.
    pub direct: Vec<Vec3>,
    /// Indirect glossy, `indirect[view * 6 * indirect_res^2 + texel]` (empty when disabled).
    pub indirect: Vec<Vec3>,
    /// Diffuse SH transfer of the vertex (`order^2` floats, layout of `ShTransfer`).
    pub diffuse_sh: Vec<f32>,
}

/// Something that can tabulate the transport of any vertex: the real scene
/// ([`TransportContext`]) or a synthetic one in tests of the fit.
pub trait TransportSource: Sync {
    /// Number of vertices.
    fn vertex_count(&self) -> usize;
    /// Face size of the direct cube map.
    fn direct_res(&self) -> usize;
    /// Face size of the indirect cube map (0: no indirect component).
    fn indirect_res(&self) -> usize;
    /// Fill `out` with the transport of vertex `x` (reusing its allocations).
    fn compute(&self, x: usize, out: &mut VertexTransport);
}

/// The material of each vertex: that of the first triangle (in index order) using the
/// vertex; a vertex used by no triangle gets `materials[0]` (or the default material).
///
/// # Panics
/// If a material id or vertex index is out of range
/// ([`crate::transport::check_mesh`] reports that as an error).
pub fn vertex_materials(mesh: &TriMesh, materials: &[Material]) -> Vec<Material> {
    let fallback = materials.first().copied().unwrap_or_default();
    let mut out: Vec<Option<Material>> = vec![None; mesh.vertex_count()];
    for (tri, &m) in mesh.indices.iter().zip(&mesh.material_ids) {
        for &v in tri {
            out[v as usize].get_or_insert(materials[m as usize]);
        }
    }
    out.into_iter().map(|m| m.unwrap_or(fallback)).collect()
}

/// Why two materials cannot be blended ([`blend_materials`], [`blend_along_axis`]).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum BlendError {
    /// The blend parameter is not in `[0, 1]`.
    #[error("blend parameter {0} is not in [0, 1]")]
    Parameter(f32),
    /// The two materials are of different kinds (e.g. Lambert and GGX plastic).
    #[error("cannot blend materials of different kinds: {0:?} and {1:?}")]
    DifferentKinds(Material, Material),
    /// The blend axis is zero or not finite.
    #[error("blend axis {0} has no direction")]
    Axis(Vec3),
}

/// Blend two materials of the same kind, `t = 0` giving `a` and `t = 1` giving `b`, for
/// spatially varying BRDFs (thesis section 2.3.1, the "bird" of Fig. 2-4). Reflectances and
/// the plastic's `ior` are interpolated linearly, the Blinn-Phong exponent and the GGX
/// `alpha` geometrically (linearly in log space, so that the lobe width changes evenly).
///
/// # Errors
/// [`BlendError::DifferentKinds`], or [`BlendError::Parameter`] for `t` not in `[0, 1]`.
pub fn blend_materials(a: &Material, b: &Material, t: f32) -> Result<Material, BlendError> {
    if !(0.0..=1.0).contains(&t) {
        return Err(BlendError::Parameter(t));
    }
    let lin = |x: Vec3, y: Vec3| x.lerp(y, t);
    let log = |x: f32, y: f32| (x.ln() + (y.ln() - x.ln()) * t).exp();
    use Material as M;
    match (*a, *b) {
        (M::Lambert { albedo: x }, M::Lambert { albedo: y }) => {
            Ok(M::Lambert { albedo: lin(x, y) })
        }
        (
            M::BlinnPhong {
                diffuse: d0,
                specular: s0,
                exponent: e0,
            },
            M::BlinnPhong {
                diffuse: d1,
                specular: s1,
                exponent: e1,
            },
        ) => Ok(M::BlinnPhong {
            diffuse: lin(d0, d1),
            specular: lin(s0, s1),
            exponent: log(e0, e1),
        }),
        (
            M::GgxConductor {
                specular: s0,
                alpha: a0,
            },
            M::GgxConductor {
                specular: s1,
                alpha: a1,
            },
        ) => Ok(M::GgxConductor {
            specular: lin(s0, s1),
            alpha: log(a0, a1),
        }),
        (
            M::GgxPlastic {
                diffuse: d0,
                specular: s0,
                alpha: a0,
                ior: i0,
            },
            M::GgxPlastic {
                diffuse: d1,
                specular: s1,
                alpha: a1,
                ior: i1,
            },
        ) => Ok(M::GgxPlastic {
            diffuse: lin(d0, d1),
            specular: lin(s0, s1),
            alpha: log(a0, a1),
            ior: i0 + (i1 - i0) * t,
        }),
        _ => Err(BlendError::DifferentKinds(*a, *b)),
    }
}

/// Per-vertex materials blending from `a` to `b` along `axis` (thesis section 2.3.1): `t` is
/// the projection of the vertex position on `axis`, mapped to 0 at the lowest vertex and 1 at
/// the highest (0 everywhere for a mesh flat across the axis).
///
/// # Errors
/// [`BlendError::Axis`] for a zero or non-finite axis, or materials that [`blend_materials`]
/// rejects.
pub fn blend_along_axis(
    mesh: &TriMesh,
    a: &Material,
    b: &Material,
    axis: Vec3,
) -> Result<Vec<Material>, BlendError> {
    let axis = axis.try_normalize().ok_or(BlendError::Axis(axis))?;
    blend_materials(a, b, 0.0)?;
    let proj: Vec<f32> = mesh.positions.iter().map(|p| p.dot(axis)).collect();
    let lo = proj.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = proj.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let span = hi - lo;
    proj.iter()
        .map(|&s| {
            let t = if span > 0.0 {
                ((s - lo) / span).clamp(0.0, 1.0)
            } else {
                0.0
            };
            blend_materials(a, b, t)
        })
        .collect()
}

/// Tables of one cube-map resolution: texel centre directions and solid angles.
#[derive(Clone, Debug)]
struct CubeTable {
    res: usize,
    dirs: Vec<Vec3>,
    solid_angle: Vec<f32>,
}

impl CubeTable {
    fn new(res: usize) -> Self {
        let count = 6 * res * res;
        let (mut dirs, mut solid_angle) = (Vec::with_capacity(count), Vec::with_capacity(count));
        for i in 0..count {
            let (face, row, col) = texel_coords(res, i);
            dirs.push(texel_dir(res, face, row, col));
            solid_angle.push(texel_solid_angle(res, row, col) as f32);
        }
        CubeTable {
            res,
            dirs,
            solid_angle,
        }
    }

    fn len(&self) -> usize {
        self.dirs.len()
    }
}

/// An indirect glossy path in flight (see [`TransportContext::indirect`]).
#[derive(Clone, Copy, Debug)]
struct Path {
    view: u32,
    /// Surface scatterings after leaving the vertex.
    depth: u32,
    throughput: Vec3,
    rng: Rng,
}

/// The direction whose transport view `d` (unit, towards the viewer) holds at a point of
/// unit shading normal `n`, and whether it is `d` itself (`true`) or `d` clamped to the
/// elevation `asin(sin_horizon)` above the shading horizon, keeping its azimuth (parent
/// module docs, "Views below the horizon"); `(sin_horizon, cos_horizon)` is the sine and
/// cosine of [`SgBakeSettings::horizon_deg`]. The bake tabulates, and a half-vector frame
/// reads back, each view's lobes for this direction.
pub fn clamp_view(n: Vec3, d: Vec3, sin_horizon: f32, cos_horizon: f32) -> (Vec3, bool) {
    let c = d.dot(n);
    if c >= sin_horizon {
        return (d, true);
    }
    let t = (d - n * c)
        .try_normalize()
        .unwrap_or_else(|| Frame::from_normal(n).s);
    ((n * sin_horizon + t * cos_horizon).normalize(), false)
}

/// The scene-side [`TransportSource`]: tabulates the direct glossy, indirect glossy and
/// diffuse SH transport of Green 2005 (thesis sections 2.2.1, 3.1) for any vertex of a mesh.
///
/// Holds the tables shared by all vertices (texel directions and solid angles of both cube
/// maps, SH values of the direct cube map's texels, the 92 views, geometric normals);
/// [`TransportSource::compute`] does the per-vertex work, single-threaded (callers run
/// vertices in parallel).
pub struct TransportContext<'a> {
    mesh: &'a TriMesh,
    caster: &'a dyn RayCaster,
    materials: Vec<Material>,
    settings: SgBakeSettings,
    /// Area-weighted geometric normal per vertex (ray offsets, geometric horizon).
    ng: Vec<Vec3>,
    views: Vec<Vec3>,
    direct: CubeTable,
    /// `indirect_res == 0` when there is no indirect component.
    indirect: CubeTable,
    /// `sh[texel * order^2 + i] = y_i(dir of texel)` for the direct cube map.
    sh: Vec<f32>,
    sin_horizon: f32,
    cos_horizon: f32,
}

impl<'a> TransportContext<'a> {
    /// Tables for `mesh` (rays cast by `caster`, which must be built over the same mesh) and
    /// one material per vertex (see [`vertex_materials`], [`blend_along_axis`]).
    ///
    /// # Errors
    /// [`BakeError::Settings`] for out-of-range settings; [`BakeError::Scene`] for a mesh
    /// with missing normals, out-of-range indices or non-finite positions or normals, or
    /// a material count or material out of range.
    pub fn new(
        mesh: &'a TriMesh,
        vertex_materials: Vec<Material>,
        caster: &'a dyn RayCaster,
        settings: &SgBakeSettings,
    ) -> Result<Self, BakeError> {
        settings.validate()?;
        check_mesh_geometry(mesh)?;
        let scene = |m: String| BakeError::Scene(m);
        if vertex_materials.len() != mesh.vertex_count() {
            return Err(scene(format!(
                "{} vertex materials for {} vertices",
                vertex_materials.len(),
                mesh.vertex_count()
            )));
        }
        for (v, m) in vertex_materials.iter().enumerate() {
            m.validate()
                .map_err(|e| scene(format!("material of vertex {v}: {e}")))?;
        }
        let [direct_res, indirect_res] = settings.resolutions();
        let direct = CubeTable::new(direct_res);
        let indirect = CubeTable::new(indirect_res);
        let n2 = sh_count(settings.diffuse_order);
        let mut sh = vec![0.0f32; direct.len() * n2];
        for (d, y) in direct.dirs.iter().zip(sh.chunks_exact_mut(n2)) {
            eval_sh(settings.diffuse_order, *d, y);
        }
        let (sin_horizon, cos_horizon) = settings.horizon_deg.to_radians().sin_cos();
        Ok(TransportContext {
            mesh,
            caster,
            materials: vertex_materials,
            settings: *settings,
            ng: vertex_geometric_normals(mesh),
            views: Icosphere::new(super::VIEW_FREQUENCY).vertices().to_vec(),
            direct,
            indirect,
            sh,
            sin_horizon,
            cos_horizon,
        })
    }

    /// The view directions (global frame, unit), 92 for frequency 3.
    pub fn views(&self) -> &[Vec3] {
        &self.views
    }

    /// The material of each vertex.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// The settings the context was built with.
    pub fn settings(&self) -> &SgBakeSettings {
        &self.settings
    }

    /// Unit shading normal of vertex `x`, `None` if degenerate.
    fn normal(&self, x: usize) -> Option<Vec3> {
        self.mesh.normals[x].try_normalize()
    }

    /// The direction whose transport view `v` of vertex `x` holds, and whether it is the
    /// view itself (`true`) or the view clamped to `horizon_deg` above the shading horizon,
    /// keeping its azimuth (parent module docs). A degenerate normal gives `(view, false)`.
    pub fn view_direction(&self, x: usize, v: usize) -> (Vec3, bool) {
        match self.normal(x) {
            Some(n) => self.clamp_view(n, self.views[v]),
            None => (self.views[v], false),
        }
    }

    fn clamp_view(&self, n: Vec3, d: Vec3) -> (Vec3, bool) {
        clamp_view(n, d, self.sin_horizon, self.cos_horizon)
    }

    /// Visibility of the direct cube map from vertex `x`: the unoccluded texels above both
    /// horizons, with their directions in the shading frame.
    fn visible_texels(&self, x: usize, frame: &Frame) -> Vec<(u32, Vec3)> {
        self.visible_texels_at(self.mesh.positions[x], self.ng[x], frame)
    }

    /// [`Self::visible_texels`] of any surface point `p` with geometric normal `ng`.
    fn visible_texels_at(&self, p: Vec3, ng: Vec3, frame: &Frame) -> Vec<(u32, Vec3)> {
        let n = frame.n;
        let texels: Vec<u32> = (0..self.direct.dirs.len() as u32)
            .filter(|&i| {
                let w = self.direct.dirs[i as usize];
                w.dot(n) > 0.0 && w.dot(ng) > 0.0
            })
            .collect();
        let mut occluded = vec![false; texels.len()];
        if self.settings.visibility {
            let rays: Vec<_> = texels
                .iter()
                .map(|&i| surface_ray(p, ng, self.direct.dirs[i as usize]))
                .collect();
            self.caster.occluded_many(&rays, &mut occluded);
        }
        texels
            .iter()
            .zip(&occluded)
            .filter(|(_, &o)| !o)
            .map(|(&i, _)| (i, frame.to_local(self.direct.dirs[i as usize])))
            .collect()
    }

    /// The direct glossy transport of one view `view` (world, unit, towards the viewer) at
    /// any surface point `p` with shading normal `n`, geometric normal `ng` and material `m`,
    /// into `out` (`6 direct_res^2` texels): what [`TransportSource::compute`] tabulates for a
    /// vertex and one of the 92 views, for an arbitrary point and view (the view clamped to
    /// `horizon_deg` as there). Used by the error budget of the evaluation (the per-pixel and
    /// exact-view rows, `relight_eval::sg::budget`). A degenerate normal gives zeros.
    ///
    /// # Panics
    /// If `out.len() != 6 direct_res^2`.
    pub fn direct_at(
        &self,
        p: Vec3,
        n: Vec3,
        ng: Vec3,
        m: &Material,
        view: Vec3,
        out: &mut [Vec3],
    ) {
        assert_eq!(out.len(), self.direct.len(), "one direct cube map");
        let (Some(n), Some(ng)) = (n.try_normalize(), ng.try_normalize()) else {
            out.fill(Vec3::ZERO);
            return;
        };
        if m.is_diffuse_only() {
            out.fill(Vec3::ZERO);
            return;
        }
        let frame = m.shading_frame(n);
        let visible = self.visible_texels_at(p, ng, &frame);
        let mut kernel = GlossyKernel::new(m, &visible, self.direct.len());
        let (d, _) = self.clamp_view(n, view);
        kernel.eval_view(frame.to_local(d), out);
    }

    /// Texel directions (world, unit) and exact solid angles of the direct cube map.
    pub fn direct_texels(&self) -> (&[Vec3], &[f32]) {
        (&self.direct.dirs, &self.direct.solid_angle)
    }

    /// The direction view `view` of vertex `x` is tabulated for (the exact direction, or the
    /// direction clamped `horizon_deg` above the shading horizon).
    pub fn clamped_view(&self, x: usize, view: Vec3) -> Vec3 {
        match self.normal(x) {
            Some(n) => self.clamp_view(n, view).0,
            None => view,
        }
    }

    /// The area-weighted geometric normal of vertex `x` (ray offsets, geometric horizon).
    pub fn geometric_normal(&self, x: usize) -> Vec3 {
        self.ng[x]
    }

    /// Diffuse SH transfer: `(1/pi) sum_w y_i(w) V(w) cos(w) k(cos w) dA(w)` over the visible
    /// texels (`k` = light-side factor of [`Material::diffuse_factors`]).
    fn diffuse(&self, m: &Material, visible: &[(u32, Vec3)], out: &mut [f32]) {
        let n2 = out.len();
        for &(i, wo) in visible {
            let i = i as usize;
            let (_, k) = m.diffuse_factors(1.0, wo.z);
            let w = FRAC_1_PI * wo.z * k * self.direct.solid_angle[i];
            for (o, &y) in out.iter_mut().zip(&self.sh[i * n2..(i + 1) * n2]) {
                *o += y * w;
            }
        }
    }

    /// The stream of the random numbers of view `v` of vertex `x`.
    fn stream(&self, x: usize, v: usize) -> u64 {
        (x * self.views.len() + v) as u64
    }

    /// Indirect glossy transport of every view (`wis[v]` in the shading frame) into `out`
    /// (`views x 6 indirect_res^2`, zeroed), by BRDF-importance-sampled path tracing (thesis
    /// sec. 2.2.1). Paths start with a sample of the glossy part at `x` (Hammersley points,
    /// Cranley-Patterson rotated per view); a path escaping right away is direct transport
    /// and skipped. Each hit on a front face scatters by the full BRDF of the hit triangle's
    /// nearest corner, up to `max_depth` scatterings; back faces and directions below a
    /// surface absorb. A path escaping in direction `w` adds `throughput / (paths dA)` to the
    /// texel of `w`, so `sum_w T dA L` is the Monte Carlo estimate of `L_o`. No Russian
    /// roulette (`max_depth` is small). All paths of a vertex advance together, one
    /// `intersect_many` per bounce.
    fn indirect(&self, x: usize, frame: &Frame, wis: &[Vec3], out: &mut [Vec3]) {
        let m = &self.materials[x];
        let (p, ng) = (self.mesh.positions[x], self.ng[x]);
        let paths = self.settings.indirect_paths;
        let texels = self.indirect.len();
        let inv_paths = 1.0 / paths as f32;
        let mut state: Vec<Path> = Vec::new();
        let mut rays: Vec<Ray> = Vec::new();
        for (v, &wi) in wis.iter().enumerate() {
            let mut rng = Rng::new(self.settings.seed, self.stream(x, v));
            let shift = rng.next_vec2();
            for i in 0..paths {
                let u = cranley_patterson(hammersley(i, paths), shift);
                let Some(s) = m.sample_glossy(wi, u) else {
                    continue;
                };
                let dir = frame.to_world(s.wo);
                if dir.dot(ng) <= 0.0 {
                    continue;
                }
                let seed = (rng.next_u32() as u64) << 32 | rng.next_u32() as u64;
                state.push(Path {
                    view: v as u32,
                    depth: 0,
                    throughput: s.weight,
                    rng: Rng::new(seed, self.stream(x, v)),
                });
                rays.push(surface_ray(p, ng, dir));
            }
        }
        let mut hits: Vec<Option<Hit>> = Vec::new();
        while !rays.is_empty() {
            hits.clear();
            hits.resize(rays.len(), None);
            self.caster.intersect_many(&rays, &mut hits);
            let (mut next_state, mut next_rays) = (Vec::new(), Vec::new());
            for ((path, ray), hit) in state.iter().zip(&rays).zip(&hits) {
                let Some(hit) = hit else {
                    if path.depth > 0 {
                        let t = dir_to_texel(self.indirect.res, ray.dir);
                        out[path.view as usize * texels + t] +=
                            path.throughput * (inv_paths / self.indirect.solid_angle[t]);
                    }
                    continue;
                };
                if path.depth >= self.settings.max_depth {
                    continue;
                }
                let mut path = *path;
                if let Some(next) = self.scatter(hit, ray.dir, &mut path) {
                    path.depth += 1;
                    next_state.push(path);
                    next_rays.push(next);
                }
            }
            state = next_state;
            rays = next_rays;
        }
    }

    /// Scatter `path` at `hit` (arriving along `dir`): the next ray, or `None` if absorbed.
    fn scatter(&self, hit: &Hit, dir: Vec3, path: &mut Path) -> Option<Ray> {
        let tri = hit.tri as usize;
        let ng = self.mesh.geometric_normal(tri);
        // One-sided: a back face (or a degenerate triangle) absorbs.
        if ng.dot(dir) >= 0.0 {
            return None;
        }
        let ns = self
            .mesh
            .shading_normal(tri, hit.u, hit.v)
            .try_normalize()?;
        let corners = self.mesh.indices[tri];
        let bary = [1.0 - hit.u - hit.v, hit.u, hit.v];
        let k = (0..3).fold(0, |k, j| if bary[j] > bary[k] { j } else { k });
        let m = &self.materials[corners[k] as usize];
        let frame = m.shading_frame(ns);
        let wi = frame.to_local(-dir);
        let s = m.sample(wi, path.rng.next_vec2(), path.rng.next_f32())?;
        let next = frame.to_world(s.wo);
        if next.dot(ng) <= 0.0 {
            return None;
        }
        path.throughput *= s.weight;
        let point = self.mesh.point(tri, hit.u, hit.v);
        Some(surface_ray(point, ng, next))
    }
}

impl TransportSource for TransportContext<'_> {
    fn vertex_count(&self) -> usize {
        self.mesh.vertex_count()
    }

    fn direct_res(&self) -> usize {
        self.direct.res
    }

    fn indirect_res(&self) -> usize {
        self.indirect.res
    }

    /// The three components of vertex `x` (parent module docs). A vertex with a degenerate
    /// normal gets all-zero transport and every view flagged as clamped.
    fn compute(&self, x: usize, out: &mut VertexTransport) {
        let nv = self.views.len();
        let (td, ti) = (self.direct.len(), self.indirect.len());
        out.view_visible.clear();
        out.view_visible.resize(nv, false);
        out.view_dirs.clear();
        out.view_dirs
            .extend((0..nv).map(|v| self.view_direction(x, v).0));
        // The direct cube maps are overwritten texel by texel below (zeroing 6.8 MB first
        // would cost as much as the kernel); resized only when the shape changes.
        if out.direct.len() != nv * td {
            out.direct.clear();
            out.direct.resize(nv * td, Vec3::ZERO);
        }
        out.indirect.clear();
        out.indirect.resize(nv * ti, Vec3::ZERO);
        out.diffuse_sh.clear();
        out.diffuse_sh
            .resize(sh_count(self.settings.diffuse_order), 0.0);
        let Some(n) = self.normal(x) else {
            out.direct.fill(Vec3::ZERO);
            return;
        };
        let m = &self.materials[x];
        let frame = m.shading_frame(n);
        // Visibility cube map, then the diffuse SH part from it.
        let visible = self.visible_texels(x, &frame);
        self.diffuse(m, &visible, &mut out.diffuse_sh);
        if m.is_diffuse_only() {
            out.direct.fill(Vec3::ZERO);
            // No glossy lobe: no direct or indirect glossy transport (views still flagged).
            for (v, vis) in out.view_visible.iter_mut().enumerate() {
                *vis = self.clamp_view(n, self.views[v]).1;
            }
            return;
        }
        // Direct glossy, view by view (clamped below the horizon).
        let mut kernel = GlossyKernel::new(m, &visible, td);
        let mut wis = Vec::with_capacity(nv);
        for (v, cube) in out.direct.chunks_exact_mut(td).enumerate() {
            let (d, vis) = self.clamp_view(n, self.views[v]);
            out.view_visible[v] = vis;
            let wi = frame.to_local(d);
            wis.push(wi);
            kernel.eval_view(wi, cube);
        }
        if ti > 0 {
            self.indirect(x, &frame, &wis, &mut out.indirect);
        }
    }
}

#[cfg(test)]
mod tests;
