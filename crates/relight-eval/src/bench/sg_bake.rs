//! SG bake cost per vertex (section "SG bake"; formerly the ignored tests `bake_timing` of
//! `relight_bake::sg::fit` and `time_per_vertex_armadillo` of `relight_bake::sg::transport`).
//!
//! What the armadillo bake of docs/RESULTS.md (sg) does, on a small connected patch of a mesh
//! (breadth-first from a seed vertex over the triangle edges), with its material (GGX plastic,
//! alpha 0.15) and settings (defaults: 6 x 32 x 32 direct and 6 x 8 x 8 indirect cube maps, 64
//! paths, 92 views; 2 direct lobes + 1 indirect), through the public API of
//! `relight_bake::sg`:
//! 1. **Tabulation**: [`TransportContext`]`::compute` of every patch vertex on the calling
//!    thread. The context and its ray caster cover the whole mesh, so visibility and indirect
//!    paths see all of it.
//! 2. **Bake of the patch**: [`fit_mesh`] over the patch's vertices and triangles on a
//!    one-thread pool. Its flood fill tabulates each vertex again (the bake keeps no
//!    transport), so the **fit** is the bake minus the tabulation, as the former test
//!    computed it; with relaxation sweeps it includes the re-tabulation of the vertices they
//!    revisit.
//!
//! Reported per vertex: wall and CPU time (user + system of the process,
//! [`super::process_cpu_ms`], 10 ms ticks; CPU time is what a machine shared with other jobs
//! does not inflate), the fit per (vertex, view, component), the fit against the tabulation
//! of the same vertices (the baseline), and the armadillo's whole bake extrapolated from the
//! CPU time per vertex (wall time where CPU time is unavailable):
//! `14,587 x (tabulation + fit) / threads`, perfect scaling over rayon's current threads,
//! against the 10-minute target. A patch's vertices have fewer fitted neighbours than the
//! mesh's inner vertices, and flood-fill regions, which the whole bake runs in parallel, do
//! not matter on one thread.

use super::{process_cpu_ms, Section};
use crate::Result;
use glam::Vec3;
use relight_bake::sg::fit::{fit_mesh, FitConfig, MeshFit};
use relight_bake::sg::transport::{TransportContext, TransportSource, VertexTransport};
use relight_bake::sg::SgBakeSettings;
use relight_method::MethodError;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Vertices of the armadillo (`data/meshes/armadillo.obj`), what the estimate extrapolates to.
pub const ARMADILLO_VERTICES: usize = 14_587;

/// The target of the armadillo bake on 2 cores (docs/RESULTS.md, section sg), seconds.
pub const TARGET_SECONDS: f64 = 600.0;

/// The material of `examples/sg_armadillo.json`.
pub fn armadillo_material() -> Material {
    Material::GgxPlastic {
        diffuse: Vec3::new(0.35, 0.25, 0.2),
        specular: Vec3::ONE,
        alpha: 0.15,
        ior: 1.49,
    }
}

/// The bake settings of the armadillo figures: defaults with 2 direct lobes and 1 indirect.
pub fn armadillo_settings() -> SgBakeSettings {
    SgBakeSettings {
        direct_lobes: 2,
        indirect_lobes: 1,
        ..SgBakeSettings::default()
    }
}

/// Up to `n` vertices of `mesh` connected to `seed` (breadth-first over the triangle edges,
/// in that order), and the triangles with all three corners among them, indexed into that
/// list.
///
/// # Panics
/// If `seed` or a triangle index is out of range.
pub fn patch(mesh: &TriMesh, seed: usize, n: usize) -> (Vec<usize>, Vec<[u32; 3]>) {
    let nv = mesh.vertex_count();
    let mut adjacent = vec![Vec::new(); nv];
    for t in &mesh.indices {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            adjacent[a].push(b);
            adjacent[b].push(a);
        }
    }
    let mut index = vec![u32::MAX; nv];
    let mut order = vec![seed];
    index[seed] = 0;
    let mut head = 0;
    while head < order.len() && order.len() < n {
        let v = order[head];
        head += 1;
        for &w in &adjacent[v] {
            if index[w] == u32::MAX && order.len() < n {
                index[w] = order.len() as u32;
                order.push(w);
            }
        }
    }
    let triangles = mesh
        .indices
        .iter()
        .filter_map(|t| {
            let p = t.map(|v| index[v as usize]);
            p.iter().all(|&i| i != u32::MAX).then_some(p)
        })
        .collect();
    (order, triangles)
}

/// The transport of a patch's vertices, tabulated by the whole mesh's context.
struct Patch<'a> {
    ctx: &'a TransportContext<'a>,
    vertices: &'a [usize],
}

impl TransportSource for Patch<'_> {
    fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    fn direct_res(&self) -> usize {
        self.ctx.direct_res()
    }

    fn indirect_res(&self) -> usize {
        self.ctx.indirect_res()
    }

    fn compute(&self, x: usize, out: &mut VertexTransport) {
        self.ctx.compute(self.vertices[x], out);
    }
}

/// A time per vertex, milliseconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerVertex {
    /// Wall time.
    pub wall_ms: f64,
    /// CPU time of the process (`None` without `/proc/self/stat`).
    pub cpu_ms: Option<f64>,
}

impl PerVertex {
    /// The CPU time where measured, else the wall time.
    pub fn cpu_or_wall(&self) -> f64 {
        self.cpu_ms.unwrap_or(self.wall_ms)
    }

    /// Wall and CPU time of `f` per one of `n` vertices, and its result.
    fn time<R>(n: usize, f: impl FnOnce() -> R) -> (R, PerVertex) {
        let c0 = process_cpu_ms();
        let t0 = Instant::now();
        let r = f();
        let wall = t0.elapsed().as_secs_f64() * 1e3;
        let n = n.max(1) as f64;
        let cpu = c0.zip(process_cpu_ms()).map(|(a, b)| (b - a) / n);
        (
            r,
            PerVertex {
                wall_ms: wall / n,
                cpu_ms: cpu,
            },
        )
    }
}

/// Costs of one patch bake.
#[derive(Clone, Debug)]
pub struct SgBakeCost {
    /// Vertices of the patch.
    pub vertices: usize,
    /// Views per vertex.
    pub views: usize,
    /// Fitted components (direct, and indirect if any).
    pub components: usize,
    /// Relaxation sweeps of the fit.
    pub relax_sweeps: usize,
    /// Tabulation per vertex ([`tabulate`]).
    pub tabulation: PerVertex,
    /// Fit per vertex: the patch's bake minus its tabulation (module docs).
    pub fit: PerVertex,
    /// The patch's lobes and fit statistics.
    pub result: MeshFit,
}

impl SgBakeCost {
    /// Tabulation + fit per vertex, CPU time where both were measured, else wall time.
    pub fn total_ms(&self) -> f64 {
        match (self.tabulation.cpu_ms, self.fit.cpu_ms) {
            (Some(t), Some(f)) => t + f,
            _ => self.tabulation.wall_ms + self.fit.wall_ms,
        }
    }

    /// The fit per (vertex, view, component), CPU time where measured.
    pub fn fit_per_view_ms(&self) -> f64 {
        self.fit.cpu_or_wall() / (self.views * self.components) as f64
    }

    /// The fit over the tabulation of the same vertices (CPU times where both were measured).
    pub fn fit_over_tabulation(&self) -> f64 {
        match (self.tabulation.cpu_ms, self.fit.cpu_ms) {
            (Some(t), Some(f)) if t > 0.0 => f / t,
            _ => self.fit.wall_ms / self.tabulation.wall_ms,
        }
    }

    /// Seconds of the armadillo's whole bake on `threads` threads, extrapolated (module docs).
    pub fn armadillo_seconds(&self, threads: usize) -> f64 {
        ARMADILLO_VERTICES as f64 * self.total_ms() * 1e-3 / threads.max(1) as f64
    }
}

/// Tabulate every vertex of `vertices` with `ctx` on the calling thread (after one warm-up
/// vertex: the buffers' first allocation is not per-vertex work); the time per vertex.
pub fn tabulate(ctx: &TransportContext, vertices: &[usize]) -> PerVertex {
    let mut buf = VertexTransport::default();
    if let Some(&v) = vertices.first() {
        ctx.compute(v, &mut buf);
    }
    let ((), t) = PerVertex::time(vertices.len(), || {
        for &v in vertices {
            ctx.compute(v, &mut buf);
        }
    });
    std::hint::black_box(&buf);
    t
}

/// Bake the patch `vertices` / `triangles` of `ctx`'s mesh (triangles indexing into
/// `vertices`, as [`patch`] returns them) with `relax_sweeps` relaxation sweeps on a
/// one-thread pool; the fit is that time minus `tabulation`, the [`tabulate`] time of the same
/// patch (module docs).
///
/// # Errors
/// The one-thread pool cannot be built.
pub fn bake_patch(
    ctx: &TransportContext,
    vertices: &[usize],
    triangles: &[[u32; 3]],
    relax_sweeps: usize,
    tabulation: PerVertex,
) -> Result<SgBakeCost> {
    let s = ctx.settings();
    let mut fit = s.fit;
    fit.relax_sweeps = relax_sweeps;
    let config = FitConfig {
        direct_lobes: s.direct_lobes,
        indirect_lobes: s.indirect_lobes,
        fit,
    };
    let source = Patch { ctx, vertices };
    let progress = relight_bake::transport::progress_bar(false, 0, "");
    let (fitted, bake) = PerVertex::time(vertices.len(), || {
        relight_bake::transport::with_threads(Some(1), || {
            fit_mesh(&source, triangles, &config, &progress)
        })
    });
    let result = fitted.map_err(MethodError::from)?;
    Ok(SgBakeCost {
        vertices: vertices.len(),
        views: ctx.views().len(),
        components: 1 + result.indirect.is_some() as usize,
        relax_sweeps,
        tabulation,
        fit: PerVertex {
            wall_ms: bake.wall_ms - tabulation.wall_ms,
            cpu_ms: bake.cpu_ms.zip(tabulation.cpu_ms).map(|(b, t)| b - t),
        },
        result,
    })
}

/// A procedural glossy scene: a sphere of radius 0.5 resting on a 4 x 4 ground plane, and
/// the seed of its patch (a vertex 30 degrees below the sphere's equator, which sees the
/// plane).
pub fn sphere_on_plane() -> (TriMesh, usize) {
    let (rings, segments) = (36, 72);
    let mut m = relight_scene::shapes::uv_sphere(Vec3::new(0.0, 0.5, 0.0), 0.5, rings, segments);
    m.append(&relight_scene::shapes::ground_plane(Vec3::ZERO, 4.0, 16), 0);
    let seed = (rings as usize * 2 / 3) * (segments as usize + 1) + segments as usize / 4;
    (m, seed)
}

/// The section: a patch of 48 vertices (6 with `quick`) of [`sphere_on_plane`] and, with a
/// data folder, of the armadillo (seeded at its middle vertex), 0 and 1 relaxation sweeps
/// (0 with `quick`).
///
/// # Errors
/// The armadillo cannot be read, or a bake fails.
pub(super) fn section(data: &Option<PathBuf>, quick: bool) -> Result<Section> {
    let (n, sweeps): (usize, &[usize]) = if quick { (6, &[0]) } else { (48, &[0, 1]) };
    let threads = rayon::current_num_threads();
    let settings = armadillo_settings();
    let mut meshes = vec![{
        let (m, seed) = sphere_on_plane();
        ("procedural sphere on a plane".to_string(), m, seed)
    }];
    if let Some(p) = data
        .as_ref()
        .map(|d| d.join("data/meshes/armadillo.obj"))
        .filter(|p| p.is_file())
    {
        let m = super::load_mesh(&p)?;
        let seed = m.vertex_count() / 2;
        meshes.push((p.display().to_string(), m, seed));
    }
    let mut sec = Section::new(
        format!(
            "SG bake: cost per vertex on a {n}-vertex patch, GGX plastic, \
             6 x {d} x {d} direct + 6 x {i} x {i} indirect ({p} paths), \
             {dl} direct + {il} indirect lobes, one thread; \
             the armadillo ({ARMADILLO_VERTICES} vertices) extrapolated to {threads} threads",
            d = settings.direct_res,
            i = settings.indirect_res,
            p = settings.indirect_paths,
            dl = settings.direct_lobes,
            il = settings.indirect_lobes,
        ),
        &[
            "mesh",
            "relaxation sweeps",
            "tabulation (ms/vertex)",
            "tabulation CPU (ms/vertex)",
            "fit (ms/vertex)",
            "fit CPU (ms/vertex)",
            "fit CPU per (vertex, view, component) (ms)",
            "fit / tabulation",
            "armadillo bake, estimated (s)",
            "estimate / 10 min target",
            "mean fit error (direct)",
        ],
    );
    for (name, mesh, seed) in &meshes {
        let caster = relight_scene::accel::build_default(mesh);
        let materials = vec![armadillo_material(); mesh.vertex_count()];
        let ctx = TransportContext::new(mesh, materials, caster.as_ref(), &settings)
            .map_err(MethodError::from)?;
        let (vertices, triangles) = patch(mesh, *seed, n);
        let tabulation = tabulate(&ctx, &vertices);
        for &relax in sweeps {
            let c = bake_patch(&ctx, &vertices, &triangles, relax, tabulation)?;
            let est = c.armadillo_seconds(threads);
            sec.row(vec![
                json!(name),
                json!(relax),
                json!(c.tabulation.wall_ms),
                json!(c.tabulation.cpu_ms),
                json!(c.fit.wall_ms),
                json!(c.fit.cpu_ms),
                json!(c.fit_per_view_ms()),
                json!(c.fit_over_tabulation()),
                json!(est),
                json!(est / TARGET_SECONDS),
                json!(c.result.stats.mean_relative_error[0]),
            ]);
        }
    }
    Ok(sec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patch_is_connected_and_reindexed() {
        let (mesh, seed) = sphere_on_plane();
        let (v, t) = patch(&mesh, seed, 20);
        assert_eq!(v.len(), 20);
        assert_eq!(v[0], seed);
        let mut sorted = v.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 20, "no vertex twice");
        assert!(!t.is_empty());
        for tri in &t {
            assert!(tri.iter().all(|&i| (i as usize) < 20), "{tri:?}");
            // The same triangle exists in the mesh, through the patch's vertex list.
            let back = tri.map(|i| v[i as usize] as u32);
            assert!(mesh.indices.contains(&back), "{back:?}");
        }
        // The seed is on the sphere, 30 degrees below its equator.
        let d = (mesh.positions[seed] - Vec3::new(0.0, 0.5, 0.0)).normalize();
        assert!((d.y + 0.5).abs() < 1e-4, "{d}");
    }

    #[test]
    fn a_small_patch_bakes_and_reports_positive_costs() {
        let (mesh, seed) = sphere_on_plane();
        // Small cube maps and few paths: a test of the plumbing, not a measurement.
        let settings = SgBakeSettings {
            direct_res: 8,
            indirect_res: 4,
            indirect_paths: 4,
            ..armadillo_settings()
        };
        let caster = relight_scene::accel::build_default(&mesh);
        let ctx = TransportContext::new(
            &mesh,
            vec![armadillo_material(); mesh.vertex_count()],
            caster.as_ref(),
            &settings,
        )
        .unwrap();
        let (v, t) = patch(&mesh, seed, 4);
        let tab = tabulate(&ctx, &v);
        assert!(tab.wall_ms > 0.0, "{tab:?}");
        let c = bake_patch(&ctx, &v, &t, 0, tab).unwrap();
        assert_eq!((c.vertices, c.views, c.components), (4, 92, 2));
        assert_eq!(c.result.direct.lobes.len(), 4 * 92 * 2);
        assert!(c.total_ms() > 0.0 && c.armadillo_seconds(2) > 0.0, "{c:?}");
        assert!(c
            .result
            .direct
            .lobes
            .iter()
            .all(|g| g.axis.is_finite() && g.sharpness.is_finite() && g.amplitude.is_finite()));
    }
}
