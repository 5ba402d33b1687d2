//! Tests of the visibility sampling and the cuts bake: closed forms on simple scenes,
//! determinism, ranges, degenerate vertices, the cap, pilot vectors against a slow reference.

use super::*;
use crate::cuts::samples::EnvSamples;
use crate::cuts::tree::LightTree;
use crate::cuts::{bake_range, CutsBakeSettings, LightTreeKind};
use relight_scene::accel::{build, Backend};
use relight_scene::shapes::{aabb_box, ground_plane, uv_sphere};

/// Sphere of radius 1 centred 2 above an 8 x 8 ground plane, `rings x 2 rings` facets.
fn sphere_over_plane(rings: u32) -> TriMesh {
    let mut m = ground_plane(Vec3::ZERO, 8.0, 8);
    m.append(
        &uv_sphere(Vec3::new(0.0, 2.0, 0.0), 1.0, rings, 2 * rings),
        0,
    );
    m
}

fn params(sigma: f32, max_nodes: usize, threads: Option<usize>) -> CutParams {
    CutParams {
        sigma,
        max_nodes,
        threads,
        progress: false,
    }
}

#[test]
fn unoccluded_vertex_sees_the_clamped_cosine_or_one() {
    let mesh = ground_plane(Vec3::ZERO, 2.0, 2);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let s = EnvSamples::fibonacci(4096, 0).unwrap();
    for function in [CutFunction::VisibilityCosine, CutFunction::Visibility] {
        let sampler = VisibilitySampler::new(&mesh, caster.as_ref(), &s.dirs, function).unwrap();
        let mut out = vec![0.0; 4096];
        for v in 0..mesh.vertex_count() {
            sampler.sample(v, &mut out, &mut Scratch::default());
            for (&x, w) in out.iter().zip(&s.dirs) {
                let expect = match function {
                    CutFunction::VisibilityCosine => w.y.clamp(0.0, 1.0),
                    CutFunction::Visibility => (w.y > 0.0) as u8 as f32,
                };
                assert_eq!(x, expect);
            }
        }
    }
}

#[test]
fn shadow_of_a_sphere_matches_the_closed_form() {
    // A point on the plane under a sphere of radius r centred at height h: the sphere hides
    // the cone of half-angle a = asin(r / h) around +Y, so int V max(0, cos) dw =
    // pi (1 - sin^2 a) (the cap's cosine integral is pi sin^2 a) and int V [cos > 0] dw =
    // 2 pi - 2 pi (1 - cos a).
    let mesh = sphere_over_plane(48);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let s = EnvSamples::fibonacci(32768, 0).unwrap();
    let centre = (0..mesh.vertex_count())
        .find(|&v| mesh.positions[v].length() < 1e-6)
        .expect("the plane has a vertex at the origin");
    let sin_a = 0.5f64;
    let cos_a = (1.0 - sin_a * sin_a).sqrt();
    let pi = std::f64::consts::PI;
    for (function, exact) in [
        (CutFunction::VisibilityCosine, pi * (1.0 - sin_a * sin_a)),
        (CutFunction::Visibility, 2.0 * pi * cos_a),
    ] {
        let sampler = VisibilitySampler::new(&mesh, caster.as_ref(), &s.dirs, function).unwrap();
        let mut out = vec![0.0; s.len()];
        sampler.sample(centre, &mut out, &mut Scratch::default());
        let integral: f64 = out
            .iter()
            .zip(&s.solid_angles)
            .map(|(&v, &w)| v as f64 * w as f64)
            .sum();
        // The 48 x 96 tessellated sphere is inscribed (slightly smaller shadow), and the
        // samples' Voronoi cells straddle its rim: 1%.
        assert!(
            (integral - exact).abs() < 0.01 * exact,
            "{function:?}: {integral} vs {exact}"
        );
    }
}

#[test]
fn bake_is_deterministic_valid_and_honours_ranges() {
    let mesh = sphere_over_plane(16);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let settings = CutsBakeSettings {
        lights: 4096,
        seed: 3,
        ..Default::default()
    };
    let one = bake_range(
        &mesh,
        caster.as_ref(),
        &CutsBakeSettings {
            threads: Some(1),
            ..settings
        },
        0..mesh.vertex_count(),
    )
    .unwrap();
    one.validate().unwrap();
    let two = bake_range(
        &mesh,
        caster.as_ref(),
        &CutsBakeSettings {
            threads: Some(2),
            ..settings
        },
        0..mesh.vertex_count(),
    )
    .unwrap();
    assert_eq!(one, two, "the thread count changes nothing");
    let part = bake_range(&mesh, caster.as_ref(), &settings, 40..100).unwrap();
    part.validate().unwrap();
    for v in 40..100 {
        let (a, b) = (part.cuts.cut(v - 40), one.cuts.cut(v));
        assert_eq!((a.index, a.value), (b.index, b.value));
    }
    assert!(bake_range(
        &mesh,
        caster.as_ref(),
        &settings,
        0..mesh.vertex_count() + 1
    )
    .is_err());
    // Another seed rotates the samples: another bake.
    let other = bake_range(
        &mesh,
        caster.as_ref(),
        &CutsBakeSettings {
            seed: 4,
            ..settings
        },
        0..10,
    )
    .unwrap();
    assert_ne!(other.samples, one.samples);
    // With sigma 2, cuts stay far below the cap on this scene.
    assert!(one.cuts.capped.is_empty());
    assert!(one.cuts.mean_len() > 10.0 && one.cuts.mean_len() < 1000.0);
}

#[test]
fn a_vertex_that_sees_nothing_has_one_zero_node() {
    // A plane vertex inside a closed box, and a vertex with a zero normal.
    let mut mesh = ground_plane(Vec3::ZERO, 4.0, 4);
    mesh.append(&aabb_box(Vec3::splat(-0.5), Vec3::splat(0.5), 1), 0);
    let inside = (0..mesh.vertex_count())
        .find(|&v| mesh.positions[v].length() < 1e-6)
        .unwrap();
    let corner = (0..mesh.vertex_count())
        .find(|&v| mesh.positions[v].x < -1.9)
        .unwrap();
    mesh.normals[corner] = Vec3::ZERO;
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let s = EnvSamples::fibonacci(2048, 0).unwrap();
    let tree = LightTree::environment(&s.dirs).unwrap();
    let sampler = VisibilitySampler::new(
        &mesh,
        caster.as_ref(),
        &s.dirs,
        CutFunction::VisibilityCosine,
    )
    .unwrap();
    let cuts = sampler
        .cuts(&tree, 0..mesh.vertex_count(), &params(2.0, 1000, None))
        .unwrap();
    cuts.validate(&tree).unwrap();
    for v in [inside, corner] {
        let c = cuts.cut(v);
        assert_eq!(
            (c.index, c.value),
            (&[tree.root()][..], &[0u16][..]),
            "vertex {v}"
        );
    }
}

#[test]
fn capped_cuts_are_reported() {
    let mesh = sphere_over_plane(16);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let s = EnvSamples::fibonacci(2048, 0).unwrap();
    let tree = LightTree::environment(&s.dirs).unwrap();
    let sampler = VisibilitySampler::new(
        &mesh,
        caster.as_ref(),
        &s.dirs,
        CutFunction::VisibilityCosine,
    )
    .unwrap();
    let cuts = sampler.cuts(&tree, 0..50, &params(0.05, 20, None)).unwrap();
    cuts.validate(&tree).unwrap();
    // Every vertex of the plane sees a cosine varying over the sky: sigma 0.05 needs more
    // than 20 nodes.
    assert_eq!(cuts.capped.len(), 50);
    for v in 0..50 {
        assert_eq!(cuts.cut(v).index.len(), 20);
    }
    assert!(sampler.cuts(&tree, 0..5, &params(1.0, 0, None)).is_err());
    let small = LightTree::environment(&s.dirs[..100]).unwrap();
    assert!(sampler.cuts(&small, 0..5, &params(1.0, 10, None)).is_err());
}

#[test]
fn pilot_vectors_match_the_slow_mean_and_drive_a_valid_tree() {
    let mesh = sphere_over_plane(16);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let s = EnvSamples::fibonacci(512, 0).unwrap();
    let sampler = VisibilitySampler::new(
        &mesh,
        caster.as_ref(),
        &s.dirs,
        CutFunction::VisibilityCosine,
    )
    .unwrap();
    let m = 16;
    let pilot = sampler.pilot_vectors(m, 30.0, None, false).unwrap();
    assert_eq!((pilot.lights, pilot.clusters), (512, m));
    let groups = sampler.vertex_groups(m, 30.0);
    let mut all: Vec<u32> = groups.concat();
    all.sort_unstable();
    assert_eq!(all, (0..mesh.vertex_count() as u32).collect::<Vec<_>>());
    let mut values = vec![0.0; 512];
    let mut scratch = Scratch::default();
    for (j, g) in groups.iter().enumerate() {
        let mut mean = vec![0.0f64; 512];
        for &v in g {
            sampler.sample(v as usize, &mut values, &mut scratch);
            mean.iter_mut()
                .zip(&values)
                .for_each(|(a, &x)| *a += x as f64);
        }
        for (i, &sum) in mean.iter().enumerate() {
            let expect = sum / g.len() as f64;
            assert!((pilot.data[i * m + j] as f64 - expect).abs() < 1e-6);
        }
    }
    // The pilot data changes the tree (beta 0.5 mixes it with the geometric metric).
    let normals: Vec<Vec3> = s.dirs.iter().map(|&d| -d).collect();
    let t = LightTree::data_driven(&s.dirs, &normals, &pilot, 30.0, 0.5).unwrap();
    t.validate().unwrap();
    assert_ne!(t, LightTree::geometric(&s.dirs, &normals, 30.0).unwrap());
}

#[test]
fn data_driven_bake_is_valid() {
    let mesh = sphere_over_plane(16);
    let caster = build(&mesh, Backend::Bvh).unwrap();
    let settings = CutsBakeSettings {
        lights: 2048,
        tree: LightTreeKind::DataDriven,
        vertex_clusters: 64,
        ..Default::default()
    };
    let b = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count()).unwrap();
    b.validate().unwrap();
}
