//! The visibility unions kept across frames (`shade_cuts::cache`): a triangle's merged cut
//! from its union and a light cut's tables is the traversal's, bit for bit, at every light
//! cut size from the root alone to every leaf; frames from the records are the same bits as
//! fresh merges under a moving camera, a budget that evicts, a budget that holds nothing,
//! and changes of light cut, which keep the records.

use super::cache::LightTables;
use super::corner_tests::{camera, sphere_on_plane};
use super::triangle::TriangleCut;
use super::ward_tests::sky;
use super::*;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::samples::sample_power;
use relight_sphere::EnvMap;

/// Cameras around the sphere (each sees triangles the previous one did not), then the first
/// again.
fn orbit() -> Vec<Camera> {
    let mut cams: Vec<Camera> = (0..4)
        .map(|i| {
            let a = 1.2 * i as f32;
            Camera::look_at(
                [3.6 * a.sin(), 2.4, 3.6 * a.cos()],
                [0.0, 0.6, 0.0],
                40.0,
                64,
                48,
            )
        })
        .collect();
    cams.push(cams[0]);
    cams
}

#[test]
fn frames_from_kept_merges_are_the_bits_of_fresh_merges() {
    let (mesh, _, bake) = sphere_on_plane(CutFunction::Visibility);
    // Glossy materials (merged per triangle; Lambert goes through the corner lists), one
    // of them through the generic per-cluster path (Blinn-Phong: tree nodes, five-point rule).
    let materials = [
        vec![
            Material::GgxPlastic {
                diffuse: Vec3::new(0.4, 0.3, 0.2),
                specular: Vec3::ONE,
                alpha: 0.1,
                ior: 1.5,
            },
            Material::GgxConductor {
                specular: Vec3::new(0.9, 0.6, 0.3),
                alpha: 0.2,
            },
        ],
        vec![
            Material::BlinnPhong {
                diffuse: Vec3::splat(0.3),
                specular: Vec3::splat(0.4),
                exponent: 40.0,
            };
            2
        ],
    ];
    let lights = [sky as fn(Vec3) -> Vec3, |d| sky(-d)].map(|f| {
        let env = Environment::new(EnvMap::latlong_from_fn(128, 64, f));
        let power = sample_power(&bake.samples, &env).unwrap();
        LightCut::build(&bake.tree, &power, 2.0, 128).unwrap()
    });
    let opts = RasterOptions::default();
    for materials in materials {
        let shader = |budget| {
            CutsShader::new(&mesh, materials.clone(), &bake, CutFunction::Visibility)
                .with_cluster_spread(true)
                .with_merge_cache(budget)
        };
        let fresh = shader(0);
        let full = shader(DEFAULT_MERGE_CACHE_BYTES);
        // After the first frame: room for about two frames' records, so moving on evicts.
        full.render(&lights[0], &camera(), None, &opts);
        let one_frame = full.merge_cache_bytes();
        assert!(one_frame > 0, "the first frame keeps its merges");
        let small_budget = 2 * one_frame;
        let small = shader(small_budget);
        let tiny = shader(64);
        for (l, light) in lights.iter().enumerate() {
            for (i, cam) in orbit().iter().enumerate() {
                let want = fresh.render(light, cam, None, &opts);
                assert_eq!(fresh.merge_cache_bytes(), 0);
                let before = full.merge_cache_bytes();
                for (s, budget) in [
                    (&full, DEFAULT_MERGE_CACHE_BYTES),
                    (&small, small_budget),
                    (&tiny, 64),
                ] {
                    let got = s.render(light, cam, None, &opts);
                    assert_eq!(got.image.pixels, want.image.pixels, "budget {budget}");
                    assert!(s.merge_cache_bytes() <= budget);
                }
                // The first camera again, or under the second light cut (the records are kept
                // across light cuts): every triangle from its record, nothing merged.
                if i == 4 || (l == 1 && i == 0) {
                    assert_eq!(full.merge_cache_bytes(), before);
                }
            }
        }
        assert!(full.merge_cache_bytes() > 0);
        assert_eq!(tiny.merge_cache_bytes(), 0, "no triangle fits in 64 bytes");
    }
}

#[test]
fn merged_cut_from_the_union_is_the_traversal_at_every_light_cut_size() {
    let (mesh, _, bake) = sphere_on_plane(CutFunction::Visibility);
    let shader = CutsShader::new(
        &mesh,
        vec![Material::default()],
        &bake,
        CutFunction::Visibility,
    );
    let lights = bake.tree.light_count();
    // A sun: the light cut is finer than the unions around it and coarser elsewhere.
    let env = Environment::new(EnvMap::latlong_from_fn(128, 64, |d| {
        sky(d)
            + Vec3::splat(4e3) * (d.dot(Vec3::new(0.4, 0.8, 0.3).normalize()) > 0.999) as u8 as f32
    }));
    let power = sample_power(&bake.samples, &env).unwrap();
    let (mut fresh, mut walked) = (TriangleCut::default(), TriangleCut::default());
    let mut record = vec![];
    let (mut inside, mut split) = (0usize, 0usize);
    for budget in [1, 7, 64, 256, lights] {
        let light = LightCut::build(&bake.tree, &power, 2.0, budget).unwrap();
        let tables = LightTables::new(&bake.tree, &light).unwrap();
        for tri in 0..mesh.indices.len() as u32 {
            TriangleCut::union(&shader, tri, &mut record);
            for spread in [false, true] {
                fresh.build(&shader, &light, tri, spread);
                walked.walk(&light, &tables, &record, spread);
                assert_eq!(
                    walked.bits(),
                    fresh.bits(),
                    "triangle {tri}, light cut {budget}"
                );
            }
            for c in &record {
                if light.index[tables.cover[c.leftleaf as usize] as usize] >= c.node {
                    inside += 1;
                } else {
                    split += 1;
                }
            }
        }
    }
    // Both cases of the pass ran: union clusters lit by one light-cut node, and union clusters
    // split into the light-cut nodes inside them.
    assert!(inside > 0 && split > 0, "{inside} {split}");
}
