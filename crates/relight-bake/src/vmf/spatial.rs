//! Adaptive spatial refinement (paper section 4.3, Fig. 4): the bake refines the mesh where
//! the transfer changes quickly between neighbouring vertices.
//!
//! # The difference of two vertices
//! Views are defined in each vertex's local frame (parent module docs), so "the BRDF has the
//! same shape at x and y for every s_o". Their transfer is compared with each slice's lobes
//! rotated into its own vertex's local frame too, so that only the occluders and
//! interreflections make them differ, "and less [...] surface orientation". The difference is
//! the mean over the views of the finer of the two vertices' levels of the L2 distance
//! ([`slice_distance`]) between corresponding slices; the coarser vertex's missing slices are
//! interpolated (eq. 6, [`super::ViewTable::interpolate`]) ([`vertex_difference`]).
//!
//! # The loop
//! 1. Bake every vertex of the input mesh (with the adaptive angular refinement if it is on).
//! 2. A triangle's error is the largest difference between two of its vertices. The
//!    triangles with an error above `spatial_threshold` and an area above the minimum
//!    (`spatial_min_area` times the input's mean triangle area) are sorted by error. Up to
//!    `spatial_batch` of them, largest first, are split ([`AdaptiveMesh::split`]: midpoints,
//!    one level between neighbours).
//! 3. The new vertices (edge midpoints, with the normalised mean of their parents' normals
//!    and the material of their first parent) are baked, and the loop goes back to 2. It
//!    stops when no triangle is left to split.
//! 4. T-vertices are resolved ([`AdaptiveMesh::finish`]). That adds triangles but no
//!    vertices, so every vertex of the output mesh has its slices.
//!
//! New vertices lie on the input surface (midpoints of sub-triangle edges), so the ray caster
//! of the input mesh still holds; paths scatter at hits by the input mesh's vertex materials.
//! Vertex `x` of the output seeds its slices by `x`, and the order of splits is fixed (error,
//! then index), so the bake depends on the seed only.

use super::bake::{checked_vertex_materials, PointBaker, VmfBake, VmfBakeSettings};
use super::interp::slice_distance;
use super::refine::Refiner;
use super::slice::{SurfacePoint, TransferSlice};
use super::subdivide::AdaptiveMesh;
use crate::transport::{progress_bar, vertex_geometric_normals, with_threads};
use crate::BakeError;
use glam::{Mat3, Vec3};
use rayon::prelude::*;
use relight_scene::accel::RayCaster;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_sphere::warp::Frame;
use std::collections::HashMap;

/// What the spatial refinement did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpatialStats {
    /// Iterations of the loop that split triangles.
    pub iterations: u32,
    /// Triangles split (forced splits of neighbours included).
    pub split: usize,
    /// Vertices of the input mesh.
    pub input_vertices: usize,
    /// Largest error left among the triangles above the minimum area (at most the threshold
    /// when the loop stopped).
    pub max_error_left: f32,
}

/// The slice with its lobes rotated from the world frame into `frame` (normal = +Z).
pub fn local_slice(s: &TransferSlice, frame: &Frame) -> TransferSlice {
    let local_from_world = Mat3::from_cols(frame.s, frame.t, frame.n).transpose();
    TransferSlice {
        lobes: s.lobes.map(|t| t.map(|l| l.rotated(local_from_world))),
    }
}

/// The difference of two vertices (module docs): their levels and their slices in their
/// local frames ([`local_slice`]), one per view of each one's level.
///
/// # Panics
/// If a level is above the refiner's or the slices do not match the levels.
pub fn vertex_difference(
    refiner: &Refiner,
    (la, a): (u32, &[TransferSlice]),
    (lb, b): (u32, &[TransferSlice]),
) -> f32 {
    let l = la.max(lb);
    let table = refiner.table(l);
    let (ta, tb) = (refiner.table(la), refiner.table(lb));
    let at = |t: &super::ViewTable, own: u32, s: &[TransferSlice], v: usize, d: Vec3| {
        if own == l {
            s[v]
        } else {
            t.interpolate(s, d)
        }
    };
    let n = table.views().len();
    let sum: f64 = table
        .views()
        .iter()
        .enumerate()
        .map(|(v, &d)| slice_distance(&at(ta, la, a, v, d), &at(tb, lb, b, v, d)) as f64)
        .sum();
    (sum / n.max(1) as f64) as f32
}

/// Bake `mesh` with the adaptive spatial refinement (module docs): the bake of the refined
/// mesh, the refined mesh and what was done. `materials`, `vertex_materials`: as
/// [`super::bake()`].
///
/// # Errors
/// As [`super::bake()`]; [`BakeError::Settings`] if `spatial_threshold` is 0 (refinement off).
pub fn bake_refined(
    mesh: &TriMesh,
    materials: &[Material],
    vertex_materials: Option<&[Material]>,
    caster: &dyn RayCaster,
    settings: &VmfBakeSettings,
) -> Result<(VmfBake, TriMesh, SpatialStats), BakeError> {
    let per_vertex = checked_vertex_materials(mesh, materials, vertex_materials, settings)?;
    if settings.spatial_threshold <= 0.0 {
        return Err(BakeError::Settings(
            "spatial_threshold is 0: the spatial refinement is off".into(),
        ));
    }
    let mut am = AdaptiveMesh::new(mesh);
    let mut ng = vertex_geometric_normals(mesh);
    let mut mats = per_vertex.clone();
    let baker = PointBaker::new(mesh, caster, &per_vertex, settings);
    let mut rows: Vec<super::bake::VertexRow> = vec![];
    let mut local: Vec<Vec<TransferSlice>> = vec![];
    let mut stats = SpatialStats {
        input_vertices: mesh.vertex_count(),
        ..Default::default()
    };
    let mean_area = if mesh.triangle_count() == 0 {
        0.0
    } else {
        am.live().map(|t| am.area(t) as f64).sum::<f64>() / mesh.triangle_count() as f64
    };
    let min_area = (mean_area * settings.spatial_min_area as f64) as f32;
    let mut pairs: HashMap<(u32, u32), f32> = HashMap::new();
    loop {
        // Bake the vertices not baked yet (all of them the first time).
        let new = rows.len()..am.vertex_count();
        let what = if stats.iterations == 0 {
            "vmf bake".to_string()
        } else {
            format!("vmf spatial {}", stats.iterations)
        };
        let progress = progress_bar(settings.progress, new.len() as u64, &what);
        let points: Vec<SurfacePoint> = new
            .clone()
            .map(|x| {
                if x >= ng.len() {
                    let [a, b] = am.parents[x].expect("a new vertex has parents");
                    let g = (ng[a as usize] + ng[b as usize])
                        .try_normalize()
                        .unwrap_or(am.normals[x]);
                    ng.push(g);
                    mats.push(mats[a as usize]);
                }
                SurfacePoint {
                    position: am.positions[x],
                    normal: am.normals[x],
                    geometric_normal: ng[x],
                    material: mats[x],
                }
            })
            .collect();
        let baked: Vec<super::bake::VertexRow> = with_threads(settings.threads, || {
            new.clone()
                .into_par_iter()
                .zip(points.par_iter())
                .map(|(x, p)| {
                    let row = baker.bake_point(x, p);
                    progress.inc(1);
                    row
                })
                .collect()
        })?;
        progress.finish_and_clear();
        for (x, (l, s, sh)) in new.zip(baked) {
            let frame = Frame::from_normal(am.normals[x]);
            local.push(s.iter().map(|s| local_slice(s, &frame)).collect());
            rows.push((l, s, sh));
        }
        // Errors of the live triangles; the ones to split.
        let mut cands: Vec<(f32, usize)> = vec![];
        stats.max_error_left = 0.0;
        for t in am.live().collect::<Vec<_>>() {
            let v = am.leaves[t].v;
            let mut err = 0.0f32;
            for k in 0..3 {
                let (a, b) = (v[k].min(v[(k + 1) % 3]), v[k].max(v[(k + 1) % 3]));
                let d = *pairs.entry((a, b)).or_insert_with(|| {
                    vertex_difference(
                        baker.refiner(),
                        (u32::from(rows[a as usize].0), &local[a as usize]),
                        (u32::from(rows[b as usize].0), &local[b as usize]),
                    )
                });
                err = err.max(d);
            }
            if am.area(t) > min_area {
                if err > settings.spatial_threshold {
                    cands.push((err, t));
                } else {
                    stats.max_error_left = stats.max_error_left.max(err);
                }
            }
        }
        if cands.is_empty() {
            break;
        }
        cands.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        for &(_, t) in cands.iter().take(settings.spatial_batch as usize) {
            if am.leaves[t].alive {
                stats.split += am.split(t).len();
            }
        }
        stats.iterations += 1;
    }
    let out = am.finish();
    debug_assert_eq!(out.vertex_count(), rows.len());
    Ok((VmfBake::from_rows(*settings, rows), out, stats))
}

#[cfg(test)]
mod tests;
