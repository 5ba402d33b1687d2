//! Tests of `shade_vmf`: the lookup by kappa, the frame under a constant environment, and
//! the whole method (bake + frame) against the path tracer with the same Blinn-Phong BRDF.

use super::*;
use crate::pathtrace::{self, PtSettings};
use relight_bake::vmf::{bake, VmfBakeSettings};
use relight_scene::material::Material;
use relight_scene::scene::Scene;
use relight_scene::shapes::{ground_plane, uv_sphere};
use relight_sphere::envmap::EnvMap;

/// A smooth, coloured environment: a sky gradient and a broad warm blob.
fn smooth_env(d: Vec3) -> Vec3 {
    let blob = (6.0 * (d.dot(Vec3::new(-0.5, 0.6, 0.62).normalize()) - 1.0)).exp();
    Vec3::new(0.3, 0.4, 0.6) * (1.0 + 0.7 * d.y) + Vec3::new(5.0, 3.5, 1.5) * blob
}

#[test]
fn kappa_beyond_the_chain_is_clamped_with_its_energy_kept() {
    let env = Environment::new(EnvMap::latlong_from_fn(128, 64, smooth_env));
    let lighting = vmf_lighting(&env, 32, 1);
    let top = kappa_resolved(&lighting);
    // 32-texel finest face: kappa = 32^2 / 4, and each level doubles kappa.
    assert_eq!(top, 256.0);
    let levels = lighting.prefiltered().levels();
    for w in levels.windows(2) {
        assert!((w[0].lambda / w[1].lambda - 2.0).abs() < 1e-3, "{w:?}");
    }
    let axis = Vec3::new(0.3, 0.5, -0.8).normalize();
    let amp = Vec3::new(0.7, 0.5, 0.2);
    let at = |kappa: f32| integrate(&lighting, &VmfLobe::new(axis, kappa, amp));
    // Past the sharpest level: the same fetch as at the sharpest level, not zero, not more.
    for k in [2.0 * top, 1e4, 1e8] {
        assert_eq!(at(k), at(top), "kappa {k}");
    }
    // Below it the lookup still changes with kappa (the clamp only starts at the top).
    assert_ne!(at(top / 3.0), at(top));
    // Energy: under a constant environment every lobe gives alpha L, whatever its kappa.
    let l = Vec3::new(0.5, 1.0, 2.0);
    let mut c = Environment::new(EnvMap::constant(l));
    c.scale = 1.5;
    let lc = vmf_lighting(&c, 32, 1);
    for k in [0.0, 0.1, 3.0, 100.0, top, 1e4, 1e8] {
        let got = integrate(&lc, &VmfLobe::new(axis, k, amp));
        let want = amp * l * 1.5;
        assert!(
            ((got - want).abs() / want).max_element() < 1e-5,
            "kappa {k}: {got} vs {want}"
        );
    }
}

/// Sphere (Blinn-Phong, exponent 32) on a Lambert plane under [`smooth_env`].
fn glossy_scene(width: u32, height: u32) -> Scene {
    let mut mesh = uv_sphere(Vec3::new(0.0, 0.5, 0.0), 0.5, 16, 32);
    mesh.material_ids = vec![0; mesh.indices.len()];
    let mut plane = ground_plane(Vec3::ZERO, 4.0, 8);
    plane.material_ids = vec![0; plane.indices.len()];
    mesh.append(&plane, 1);
    Scene {
        maps: Default::default(),
        mesh,
        materials: vec![
            Material::BlinnPhong {
                diffuse: Vec3::new(0.15, 0.1, 0.05),
                specular: Vec3::splat(0.5),
                exponent: 32.0,
            },
            Material::Lambert {
                albedo: Vec3::splat(0.5),
            },
        ],
        env: Environment::new(EnvMap::latlong_from_fn(128, 64, smooth_env)),
        camera: Camera::look_at([0.0, 1.2, 2.6], [0.0, 0.4, 0.0], 40.0, width, height),
        objects: Vec::new(),
    }
}

/// What [`method_vs_path_tracer`] measured over the fully covered pixels.
struct Agreement {
    /// Relative RMSE of the frame against the path tracer.
    rel: f64,
    /// The same of the frame against exact integration of its own lobes.
    chain: f64,
    /// The path tracer's own expected relative RMSE.
    floor: f64,
    /// Mean of the frame over mean of the path tracer.
    ratio: f64,
    /// Pixels compared.
    n: usize,
}

/// Bake `scene` (view level 2, 256 paths, diffuse SH order `order`), render it and compare
/// with relight's path tracer at 1024 spp, one bounce both (the bake's `max_bounces = 1`;
/// the path tracer's `max_depth = 3`), over the pixels fully covered by the mesh (edges
/// differ by anti-aliasing).
fn method_vs_path_tracer(scene: &Scene, order: u32) -> Agreement {
    let caster = relight_scene::accel::build_default(&scene.mesh);
    let settings = VmfBakeSettings {
        view_level: 2,
        paths: 256,
        material_samples: 256,
        diffuse_sh_order: order,
        ..Default::default()
    };
    let b = bake(
        &scene.mesh,
        &scene.materials,
        None,
        caster.as_ref(),
        &settings,
    )
    .expect("bake");
    let r = VmfRenderer::new(&scene.mesh, &b).with_vertex_materials(
        relight_bake::sg::transport::vertex_materials(&scene.mesh, &scene.materials),
    );
    let lighting = vmf_lighting(&scene.env, 64, settings.diffuse_sh_order as usize);
    let opts = RasterOptions { supersample: 2 };
    let (img, _) = r.render(&lighting, &scene.camera, None, &opts);
    let reference = r.render_reference(&lighting, &scene.env, &scene.camera, &opts);
    let (pt, var) = pathtrace::render_with_variance(
        scene,
        caster.as_ref(),
        &PtSettings {
            spp: 1024,
            max_depth: 3,
            seed: 7,
            show_background: false,
            ..Default::default()
        },
    );
    let (mut se, mut se_ref, mut noise, mut norm, mut n) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0);
    let (mut sum_a, mut sum_p) = (0.0f64, 0.0f64);
    for i in 0..img.image.pixels.len() {
        if img.coverage[i] < 1.0 {
            continue;
        }
        let (a, p) = (img.image.pixels[i], pt.pixels[i]);
        se += ((a - p).length_squared() / 3.0) as f64;
        se_ref += ((img.image.pixels[i] - reference.image.pixels[i]).length_squared() / 3.0) as f64;
        noise += (var.pixels[i].element_sum() / 3.0) as f64;
        norm += (p.length_squared() / 3.0) as f64;
        sum_a += a.element_sum() as f64;
        sum_p += p.element_sum() as f64;
        n += 1;
    }
    let m = Agreement {
        rel: (se / norm).sqrt(),
        chain: (se_ref / norm).sqrt(),
        floor: (noise / norm).sqrt(),
        ratio: sum_a / sum_p,
        n,
    };
    eprintln!(
        "vmf (diffuse SH order {order}) vs path tracer: relative RMSE {:.4} over {} pixels; prefiltered chain vs exact integration {:.4}; path tracer noise {:.4}; mean ratio {:.4}",
        m.rel, m.n, m.chain, m.floor, m.ratio
    );
    m
}

/// The whole method against relight's path tracer, same scene and BRDF. See the assertion
/// for the tolerance and why.
#[test]
fn glossy_scene_matches_the_path_tracer() {
    let m = method_vs_path_tracer(&glossy_scene(48, 36), 5);
    // Measured 2026-12-02: relative RMSE 0.054, mean ratio 0.992 (diffuse SH order 5; 0.071
    // and 0.966 with the paper's diffuse lobes), of which the path tracer's noise is 0.019
    // and the prefiltered chain's trilinear lookup 0.008 (the fast frame against exact
    // integration of the same lobes; 0.018 with the lobes); the rest is the method's own approximation: one vMF
    // lobe per glossy light-path class, eq. 6 interpolation across level-2 views and across
    // triangles of a 16 x 32 sphere, 256 paths per slice. The bounds leave margin for a
    // different noise draw; a lost class or a wrong frame moves both far past them.
    // Re-measured 2026-12-07: 0.0544, noise 0.0187, so 0.0511 without the noise; bounded by
    // that plus 20 % in quadrature with the run's noise (0.064 today; the run is seeded). The
    // 0.09 this replaces passed a 1.7x worse method.
    const E: f64 = 0.0511;
    let bound = (1.2 * E).hypot(m.floor);
    assert!(m.n > 500);
    assert!(m.rel <= bound, "relative RMSE {} above {bound}", m.rel);
    assert!((m.ratio - 1.0).abs() < 0.05, "mean ratio {}", m.ratio);
    assert!(m.chain < 0.03, "prefiltered chain vs exact: {}", m.chain);
}

/// The GGX plastic's diffuse base as SH transfer times its view factor (the coating's
/// Fresnel transmission towards the viewer, `diffuse_sh` module docs) against the paper's
/// one diffuse lobe per class, both against the path tracer on [`glossy_scene`] with every
/// material a plastic.
#[test]
fn plastic_diffuse_sh_beats_the_diffuse_lobes() {
    let mut scene = glossy_scene(48, 36);
    scene.materials = vec![
        Material::GgxPlastic {
            diffuse: Vec3::new(0.6, 0.35, 0.2),
            specular: Vec3::ONE,
            alpha: 0.2,
            ior: 1.5,
        },
        Material::GgxPlastic {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::ONE,
            alpha: 0.5,
            ior: 1.5,
        },
    ];
    let lobes = method_vs_path_tracer(&scene, 0);
    let sh = method_vs_path_tracer(&scene, 5);
    // Measured 2026-12-02: lobes 0.078 (mean ratio 0.982), SH 0.044 (1.000), the path
    // tracer's noise 0.019. The same slices, the same glossy lobes: only the diffuse base's
    // representation differs, so the SH transfer (4.4 % against one lobe's 23 % on a Lambert point's own
    // samples, `diffuse_sh` docs) must be closer, by more than the path tracer's noise.
    assert!(
        sh.rel + sh.floor < lobes.rel,
        "SH {} (noise {}) vs lobes {}",
        sh.rel,
        sh.floor,
        lobes.rel
    );
    assert!(
        (sh.ratio - 1.0).abs() <= (lobes.ratio - 1.0).abs() + 0.005,
        "mean ratio: SH {} vs lobes {}",
        sh.ratio,
        lobes.ratio
    );
}

/// A hand-made bake whose vertices have views of different levels (0 to 3, as an adaptive
/// bake may give): every slice has the same total amplitude but view-dependent axes and
/// kappas. Under a constant environment every pixel is `L` times that total, whatever the
/// levels of its triangle's corners; at a baked view a vertex's slice is that view's.
#[test]
fn mixed_view_levels_render_and_baked_views_are_exact() {
    use relight_bake::vmf::bake::MAX_VIEW_LEVEL;
    use relight_bake::vmf::{views_of_level, TransferSlice};
    let mesh = uv_sphere(Vec3::ZERO, 1.0, 8, 16);
    let settings = VmfBakeSettings {
        view_level: 3,
        min_view_level: 0,
        angular_threshold: 0.1,
        diffuse_sh_order: 0,
        ..Default::default()
    };
    let amp = [0.1, 0.2, 0.05, 0.3, 0.15, 0.2].map(Vec3::splat);
    let slice = |v: Vec3, x: usize| TransferSlice {
        lobes: std::array::from_fn(|t| {
            std::array::from_fn(|c| {
                let k = t * 3 + c;
                let axis = (v + Vec3::new(0.1 * k as f32, 0.2, -0.1 * x as f32)).normalize();
                VmfLobe::new(axis, 1.0 + 10.0 * k as f32 + v.z * 50.0, amp[k])
            })
        }),
    };
    let (mut levels, mut offsets, mut slices) = (vec![], vec![0], vec![]);
    for x in 0..mesh.vertex_count() {
        let l = (x % (MAX_VIEW_LEVEL as usize - 1)) as u32;
        levels.push(l as u8);
        slices.extend(views_of_level(l).iter().map(|&v| slice(v, x)));
        offsets.push(slices.len());
    }
    let bake = VmfBake {
        settings,
        levels,
        offsets,
        slices,
        diffuse_sh: vec![],
    };
    bake.validate().expect("valid");
    let r = VmfRenderer::new(&mesh, &bake);
    // At a baked view, the slice is that view's (world view = the local view in the frame).
    for x in [0, 5, 17, 40] {
        let l = bake.levels[x] as u32;
        let frame = Frame::from_normal(mesh.normals[x].normalize());
        for (v, &local) in views_of_level(l).iter().enumerate().step_by(3) {
            let got = r.view_slice(x, frame.to_world(local));
            let want = bake.slice(x, v);
            for (a, b) in got.lobes.iter().flatten().zip(want.lobes.iter().flatten()) {
                assert!((a.axis - b.axis).length() < 1e-4, "vertex {x} view {v}");
                assert!((a.kappa - b.kappa).abs() < 1e-3 * b.kappa.max(1.0));
                assert!((a.amplitude - b.amplitude).abs().max_element() < 1e-6);
            }
        }
    }
    let l = Vec3::new(0.5, 1.0, 2.0);
    let env = Environment::new(EnvMap::constant(l));
    let lighting = vmf_lighting(&env, 32, 1);
    let camera = Camera::look_at([0.3, 0.5, 3.2], [0.0, 0.0, 0.0], 40.0, 16, 16);
    let (img, _) = r.render(&lighting, &camera, None, &RasterOptions { supersample: 2 });
    let want: Vec3 = amp.iter().sum::<Vec3>() * l;
    let mut covered = 0;
    for (p, c) in img.image.pixels.iter().zip(&img.coverage) {
        if *c >= 1.0 {
            covered += 1;
            // Float rounding only (normalised prefilter weights, blended amplitudes).
            assert!(
                ((*p - want).abs() / want).max_element() < 1e-4,
                "{p} vs {want}"
            );
        }
    }
    assert!(covered > 50);
}
