//! SH bake overhead (section "SH bake"): the time of a shadowed + 1 bounce SH bake against
//! casting exactly its rays with nothing else done.

use super::Section;
use crate::Result;
use glam::Vec3;
use rayon::prelude::*;
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_bake::transport::{surface_ray, vertex_geometric_normals, VertexSamples};
use relight_scene::accel::{self, RayCaster};
use relight_scene::mesh::TriMesh;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// The section: order 4, 1024 samples (128 with `quick`) on `bake_mesh`, else
/// `<data>/data/meshes/bunny_watertight.obj`, else a procedural sphere on a plane.
///
/// # Errors
/// A mesh that cannot be read, or a bake that fails.
pub(super) fn section(
    bake_mesh: &Option<PathBuf>,
    data: &Option<PathBuf>,
    quick: bool,
) -> Result<Section> {
    let (name, mesh) =
        match super::shared_mesh(bake_mesh, data, "data/meshes/bunny_watertight.obj")? {
            Some(x) => x,
            None => {
                eprintln!("bench: no bunny_watertight.obj: using a procedural sphere on a plane");
                let mut m =
                    relight_scene::shapes::uv_sphere(Vec3::new(0.0, 0.5, 0.0), 0.5, 96, 192);
                m.append(&relight_scene::shapes::ground_plane(Vec3::ZERO, 4.0, 64), 0);
                ("procedural sphere + plane".into(), m)
            }
        };
    let samples = if quick { 128 } else { 1024 };
    let materials = vec![relight_scene::material::Material::default()];
    let mut mesh = mesh;
    mesh.material_ids.iter_mut().for_each(|m| *m = 0);
    let caster = accel::build_default(&mesh);
    let settings = ShBakeSettings {
        order: 4,
        samples,
        seed: 1,
        transfer: ShTransferKind::Interreflected,
        bounces: 1,
        ..Default::default()
    };
    let t0 = Instant::now();
    let transfer = relight_bake::sh::bake(&mesh, &materials, caster.as_ref(), &settings)
        .map_err(relight_method::MethodError::from)?;
    let bake_s = t0.elapsed().as_secs_f64();
    std::hint::black_box(&transfer);
    let cast_s = cast_bake_rays(&mesh, caster.as_ref(), samples);
    let nrays = mesh.vertex_count() as u64 * samples as u64;
    let mut sec = Section::new(
        format!(
            "SH bake: {} ({} vertices), order 4, {} samples, shadowed + 1 bounce, {}",
            name,
            mesh.vertex_count(),
            samples,
            caster.name()
        ),
        &[
            "bake (s)",
            "same rays, cast only (s)",
            "overhead",
            "rays",
            "bake Mrays/s",
        ],
    );
    sec.row(vec![
        json!(bake_s),
        json!(cast_s),
        json!(bake_s / cast_s),
        json!(nrays),
        json!(nrays as f64 / bake_s / 1e6),
    ]);
    Ok(sec)
}

/// Cast exactly the rays of a shadowed + 1 bounce bake (same directions and origins), doing
/// nothing with the answers: the pure ray-casting time the bake's overhead is measured against.
/// The bake casts each direction once, as a closest-hit ray (it keeps the front-facing hits
/// for the bounce pass instead of retracing), so that is what is timed here. Seconds.
pub fn cast_bake_rays(mesh: &TriMesh, caster: &dyn RayCaster, samples: u32) -> f64 {
    let ng = vertex_geometric_normals(mesh);
    let t0 = Instant::now();
    let hits: u64 = (0..mesh.vertex_count())
        .into_par_iter()
        .map(|v| {
            let s = VertexSamples::new(1, v, samples, mesh.normals[v]);
            (0..samples)
                .filter(|&i| {
                    let ray = surface_ray(mesh.positions[v], ng[v], s.dir(i));
                    caster.intersect(&ray).is_some()
                })
                .count() as u64
        })
        .sum();
    std::hint::black_box(hits);
    t0.elapsed().as_secs_f64()
}
