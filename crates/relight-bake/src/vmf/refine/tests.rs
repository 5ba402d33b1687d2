use super::*;
use crate::vmf::bake::{bake, view_counts, VmfBakeSettings};
use relight_scene::accel::build_default;
use relight_scene::material::Material;
use relight_scene::shapes::ground_plane;
use relight_sphere::vmf::VmfLobe;

#[test]
fn streams_of_levels_follow_each_other() {
    let counts = view_counts();
    let mut base = 0u64;
    for l in 0..=MAX_VIEW_LEVEL as usize {
        assert_eq!(LEVEL_STREAM_BASE[l], base, "level {l}");
        base += counts[l] as u64;
    }
    assert_eq!(base as usize, LEVEL_VIEWS);
    assert!(base <= STREAMS_PER_VERTEX);
    assert_eq!(slice_stream(1, 0, 0), STREAMS_PER_VERTEX);
}

#[test]
fn every_view_of_a_level_is_a_view_of_the_next() {
    let r = Refiner::new(4);
    let counts = view_counts();
    for l in 1..=4usize {
        let p = &r.parent[l];
        let shared: Vec<usize> = p.iter().flatten().copied().collect();
        assert_eq!(shared.len(), counts[l - 1], "level {l}");
        let mut sorted = shared.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), shared.len(), "level {l}: a coarse view twice");
        for (v, q) in p.iter().enumerate() {
            if let Some(q) = q {
                let (a, b) = (
                    r.table(l as u32).views()[v],
                    r.table(l as u32 - 1).views()[*q],
                );
                assert!(a.dot(b) > 1.0 - 1e-6);
            }
        }
    }
}

/// A slice of one lobe about the mirror direction of the local view `v` (kappa `k`).
fn mirror(v: Vec3, k: f32) -> TransferSlice {
    let empty = VmfLobe::new(Vec3::Z, 0.0, Vec3::ZERO);
    let mut lobes = [[empty; 3]; 2];
    lobes[1][0] = VmfLobe::new(Vec3::new(-v.x, -v.y, v.z), k, Vec3::splat(0.5));
    TransferSlice { lobes }
}

/// The stopping rule of the module docs, checked on a refinement's distances.
fn check_rule(r: &VertexRefinement, lo: u32, hi: u32, threshold: f32) {
    let tests = r.distances.len() as u32;
    assert_eq!(r.slices.len(), view_counts()[r.level as usize]);
    if r.level < hi {
        // Stopped by a passed test: every earlier test failed.
        assert!(*r.distances.last().unwrap() < threshold, "{r:?}");
        assert_eq!(r.level, lo + tests - 1);
    } else {
        assert_eq!(r.level, lo + tests);
    }
    for &d in &r.distances[..r.distances.len().saturating_sub(1)] {
        assert!(d >= threshold, "{:?}", r.distances);
    }
    if r.level == hi && tests > 0 {
        assert!(*r.distances.last().unwrap() >= threshold);
    }
}

#[test]
fn view_independent_slices_stop_at_the_coarsest_level_and_glossy_ones_refine() {
    let r = Refiner::new(4);
    let (lo, hi, t) = (1, 4, 0.05);
    let mut calls = 0;
    let flat = r.refine(
        lo,
        hi,
        t,
        |_, _, _| {
            calls += 1;
            mirror(Vec3::Z, 2.0)
        },
        |_| {},
    );
    assert_eq!(flat.level, lo);
    assert_eq!(flat.distances.len(), 1);
    assert!(flat.distances[0] < 1e-6);
    // Level 1's views, then the new views of level 2 (the shared ones reused).
    assert_eq!(calls, view_counts()[2]);
    check_rule(&flat, lo, hi, t);
    let mut seen = vec![];
    let mut last = lo;
    for k in [20.0, 200.0, 2000.0] {
        let g = r.refine(lo, hi, t, |_, _, v| mirror(v, k), |l| seen.push(l));
        check_rule(&g, lo, hi, t);
        // Sharper highlights need more views.
        assert!(
            g.level > lo && g.level >= last,
            "kappa {k}: {:?}",
            g.distances
        );
        last = g.level;
    }
    assert_eq!(last, hi);
    assert!(seen.windows(2).all(|w| w[0] + 1 == w[1] || w[1] == lo + 1));
}

/// A 2x2 plane of one material under the open sky; its centre vertex (4) refined.
fn centre_level(m: Material, threshold: f32) -> (u8, usize) {
    let mut mesh = ground_plane(Vec3::ZERO, 4.0, 2);
    mesh.material_ids = vec![0; mesh.indices.len()];
    let caster = build_default(&mesh);
    let s = VmfBakeSettings {
        view_level: 3,
        min_view_level: 1,
        angular_threshold: threshold,
        paths: 1024,
        material_samples: 256,
        ..Default::default()
    };
    let b = bake(&mesh, &[m], None, caster.as_ref(), &s).expect("bake");
    b.validate().expect("valid");
    (b.levels[4], b.vertex_slices(4).len())
}

#[test]
fn a_diffuse_vertex_stops_at_the_coarsest_level_a_glossy_one_refines() {
    let lambert = Material::Lambert {
        albedo: Vec3::splat(0.5),
    };
    let glossy = |e: f32| Material::BlinnPhong {
        diffuse: Vec3::splat(0.1),
        specular: Vec3::splat(0.5),
        exponent: e,
    };
    // Measured 2026-12-02 (levels of the centre vertex, 1024 paths per slice): threshold
    // 0.02: Lambert 1, Blinn-Phong 16 and 64: 2; threshold 0.05: 1, 1, 2; 0.1 and 0.2: all 1.
    // The Lambert slices differ between views by Monte Carlo noise only (mean distance far
    // below 0.02), the exponent-64 highlight moves with the view.
    let t = 0.02;
    assert_eq!(centre_level(lambert, t), (1, 17));
    assert_eq!(centre_level(glossy(64.0), t), (2, 73));
    assert_eq!(centre_level(glossy(64.0), 0.05), (2, 73));
    assert_eq!(centre_level(glossy(16.0), 0.05), (1, 17));
}
