//! Tests of the SH bake: maths against closed forms and against independent Monte Carlo.

use super::*;
use crate::transport::{surface_ray, vertex_geometric_normals};
use relight_scene::accel::build_default;
use relight_scene::shapes::{ground_plane, uv_sphere};
use relight_sphere::sh::eval_sh_slow;
use relight_sphere::warp::{square_to_cosine_hemisphere, Frame, Rng};

fn lambert(a: Vec3) -> Material {
    Material::Lambert { albedo: a }
}

fn settings(order: usize, samples: u32, transfer: ShTransferKind) -> ShBakeSettings {
    ShBakeSettings {
        order,
        samples,
        seed: 3,
        transfer,
        bounces: 0,
        threads: None,
        progress: false,
    }
}

fn interreflected(order: usize, samples: u32, bounces: u32) -> ShBakeSettings {
    ShBakeSettings {
        bounces,
        ..settings(order, samples, ShTransferKind::Interreflected)
    }
}

/// A random order-`order` scalar SH lighting: DC 3, other coefficients in [-0.6, 0.6].
fn random_light(order: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng::new(seed, 0);
    (0..sh_count(order))
        .map(|i| {
            if i == 0 {
                3.0
            } else {
                1.2 * rng.next_f32() - 0.6
            }
        })
        .collect()
}

/// Value in direction `d` of the band-limited function with SH coefficients `c`.
fn sh_value(order: usize, c: &[f32], d: Vec3) -> f32 {
    let mut y = vec![0.0f64; sh_count(order)];
    eval_sh_slow(order, d, &mut y);
    y.iter().zip(c).map(|(a, &b)| a * b as f64).sum::<f64>() as f32
}

/// Sphere of radius 1 floating just above a 6 x 6 ground plane (material 1).
fn sphere_on_plane() -> TriMesh {
    let mut m = uv_sphere(Vec3::new(0.0, 1.05, 0.0), 1.0, 12, 24);
    m.append(&ground_plane(Vec3::ZERO, 6.0, 12), 1);
    m
}

/// Two `size x size` planes `gap` apart facing each other: the floor (material 0, facing +Y)
/// and the ceiling (material 1, facing -Y), each `div x div` quads.
fn facing_planes(size: f32, gap: f32, div: u32) -> TriMesh {
    let mut m = ground_plane(Vec3::ZERO, size, div);
    let mut top = ground_plane(Vec3::new(0.0, gap, 0.0), size, div);
    top.indices.iter_mut().for_each(|t| t.swap(1, 2));
    top.normals.iter_mut().for_each(|n| *n = -Vec3::Y);
    m.append(&top, 1);
    m
}

/// Independent Monte Carlo estimate of `(1/pi) ∫ V L H dw` at vertex `v` with `m` iid
/// cosine-weighted samples: `(mean, standard deviation of one sample)`.
fn mc_shadowed(
    mesh: &TriMesh,
    caster: &dyn RayCaster,
    v: usize,
    radiance: impl Fn(Vec3) -> f32,
    m: u32,
) -> (f64, f64) {
    let ng = vertex_geometric_normals(mesh)[v];
    let frame = Frame::from_normal(mesh.normals[v]);
    let mut rng = Rng::new(12345, v as u64);
    let (mut s, mut s2) = (0.0f64, 0.0f64);
    for _ in 0..m {
        let d = frame
            .to_world(square_to_cosine_hemisphere(rng.next_vec2()))
            .normalize();
        let x = if caster.occluded(&surface_ray(mesh.positions[v], ng, d)) {
            0.0
        } else {
            radiance(d) as f64
        };
        s += x;
        s2 += x * x;
    }
    let mean = s / m as f64;
    (mean, (s2 / m as f64 - mean * mean).max(0.0).sqrt())
}

/// Standard deviation over seeds `1..=8` of a bake-derived value: the bake's actual noise
/// (stratified sampling is far below the iid bound `sigma / sqrt(n)`).
fn seed_spread(f: impl Fn(u64) -> Vec<f64>) -> Vec<f64> {
    let runs: Vec<Vec<f64>> = (1..=8).map(&f).collect();
    let k = runs.len() as f64;
    (0..runs[0].len())
        .map(|j| {
            let mean = runs.iter().map(|r| r[j]).sum::<f64>() / k;
            (runs.iter().map(|r| (r[j] - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt()
        })
        .collect()
}

#[test]
fn unshadowed_order3_irradiance_matches_rh2001_closed_form() {
    // R&H 2001: E(n) = sum_l A_l L_lm Y_lm(n), A = (pi, 2pi/3, pi/4); radiance = E / pi at
    // albedo 1. Independent of the bake's own A_l: constants written out here.
    let mesh = uv_sphere(Vec3::ZERO, 1.0, 8, 16);
    let t = bake(
        &mesh,
        &[lambert(Vec3::ONE)],
        build_default(&mesh).as_ref(),
        &settings(3, 1, ShTransferKind::Unshadowed),
    )
    .unwrap();
    t.validate().unwrap();
    let l: Vec<Vec<f32>> = (0..3).map(|c| random_light(3, 20 + c)).collect();
    let light: Vec<Vec3> = (0..9)
        .map(|i| Vec3::new(l[0][i], l[1][i], l[2][i]))
        .collect();
    let a_l = [PI, 2.0 * PI / 3.0, PI / 4.0];
    for v in 0..mesh.vertex_count() {
        let n = mesh.normals[v];
        let mut y = [0.0f64; 9];
        eval_sh_slow(3, n, &mut y);
        let e: Vec3 = (0..9)
            .map(|i| light[i] * a_l[(i as f32).sqrt() as usize] * y[i] as f32)
            .sum();
        let got = t.eval_vertex(v, Vec3::ONE, &light);
        // 1e-5 relative: f32 evaluation of 9-term sums of O(1) values.
        assert!(
            (got - e / PI).abs().max_element() < 1e-5 * (e / PI).abs().max_element().max(1.0),
            "v{v}: {got} vs {}",
            e / PI
        );
    }
}

#[test]
fn shadowed_equals_unshadowed_on_a_convex_sphere() {
    let mesh = uv_sphere(Vec3::ZERO, 1.0, 12, 24);
    let caster = build_default(&mesh);
    let mats = [lambert(Vec3::ONE)];
    // The default order and the highest the brief asks for.
    for order in [5, 10] {
        let run = |kind| bake(&mesh, &mats, caster.as_ref(), &settings(order, 256, kind)).unwrap();
        let (sh, un) = (
            run(ShTransferKind::Shadowed),
            run(ShTransferKind::Unshadowed),
        );
        sh.validate().unwrap();
        un.validate().unwrap();
        let light = random_light(order, 7);
        let light3: Vec<Vec3> = light.iter().map(|&x| Vec3::splat(x)).collect();
        for v in 0..mesh.vertex_count() {
            // Nothing is occluded on a convex object, so the DC coefficient is the mean of a
            // constant: y_0 exactly (1e-5 = f32 rounding of 256 sums; one blocked ray would
            // lower it by y_0 / 256 = 1.1e-3).
            let dc = sh.vertex(v)[0];
            assert!((dc - 0.282_094_8).abs() < 1e-5, "order {order} v{v}: {dc}");
            // The rest agrees within Monte Carlo noise: 4 sigma of a plain (iid) estimate with
            // the same sample count bounds the stratified one.
            let f = |d| sh_value(order, &light, d);
            let (_, sigma) = mc_shadowed(&mesh, caster.as_ref(), v, f, 256);
            let a = sh.eval_vertex(v, Vec3::ONE, &light3).x as f64;
            let b = un.eval_vertex(v, Vec3::ONE, &light3).x as f64;
            let tol = 4.0 * sigma / 16.0 + 1e-5;
            assert!(
                (a - b).abs() < tol,
                "order {order} v{v}: {a} vs {b} (tol {tol})"
            );
        }
    }
}

#[test]
fn prt_radiance_matches_monte_carlo_for_band_limited_light() {
    // Light band-limited to the bake order: PRT has no projection error, only sampling noise.
    let mesh = sphere_on_plane();
    let caster = build_default(&mesh);
    let mats = [lambert(Vec3::ONE), lambert(Vec3::ONE)];
    let n = 256;
    let bake_seed = |seed: u64| {
        let s = ShBakeSettings {
            seed,
            ..settings(3, n, ShTransferKind::Shadowed)
        };
        bake(&mesh, &mats, caster.as_ref(), &s).unwrap()
    };
    let t = bake_seed(0);
    let light = random_light(3, 11);
    let light3: Vec<Vec3> = light.iter().map(|&x| Vec3::splat(x)).collect();
    // Plane vertices in the sphere's penumbra and sphere vertices facing the plane.
    let probes: Vec<usize> = (0..mesh.vertex_count())
        .filter(|&v| {
            let p = mesh.positions[v];
            let r = (p.x * p.x + p.z * p.z).sqrt();
            (p.y == 0.0 && (0.4..1.6).contains(&r)) || (p.y > 0.1 && p.y < 0.6)
        })
        .step_by(7)
        .collect();
    assert!(probes.len() >= 8, "{}", probes.len());
    let spread = seed_spread(|seed| {
        let t = bake_seed(seed);
        probes
            .iter()
            .map(|&v| t.eval_vertex(v, Vec3::ONE, &light3).x as f64)
            .collect()
    });
    let mut partially_shadowed = 0;
    for (&v, &s_prt) in probes.iter().zip(&spread) {
        let m = 20_000;
        let (mc, sigma) = mc_shadowed(&mesh, caster.as_ref(), v, |d| sh_value(3, &light, d), m);
        let prt = t.eval_vertex(v, Vec3::ONE, &light3).x as f64;
        // Both estimate the same integral: 4 combined standard errors, the bake's measured
        // over seeds.
        let tol = 4.0 * (sigma * sigma / m as f64 + s_prt * s_prt).sqrt();
        assert!(
            (prt - mc).abs() < tol,
            "v{v}: PRT {prt} vs MC {mc} (tol {tol})"
        );
        // Unoccluded, the DC transfer would be y_0 = 0.2821.
        partially_shadowed += (t.vertex(v)[0] < 0.27) as usize;
    }
    assert!(
        partially_shadowed * 2 >= probes.len(),
        "probes must see occlusion"
    );
}

#[test]
fn interreflected_with_black_surroundings_is_shadowed_times_albedo() {
    // Floor albedo rho, ceiling albedo 0: nothing is reflected onto the floor, so every
    // Neumann pass adds exactly 0 and the RGB transfer is the vertex albedo times the shadowed
    // one, bit for bit (same directions, same rays).
    let mesh = facing_planes(2.0, 0.5, 6);
    let caster = build_default(&mesh);
    let rho = Vec3::new(0.6, 0.4, 0.2);
    let mats = [lambert(rho), lambert(Vec3::ZERO)];
    let sh = bake(
        &mesh,
        &mats,
        caster.as_ref(),
        &settings(3, 64, ShTransferKind::Shadowed),
    )
    .unwrap();
    let ir = bake(&mesh, &mats, caster.as_ref(), &interreflected(3, 64, 2)).unwrap();
    ir.validate().unwrap();
    let albedo = crate::transport::vertex_albedo(&mesh, &mats);
    for v in 0..mesh.vertex_count() {
        let albedo = albedo[v];
        for i in 0..9 {
            let expect = albedo * sh.vertex(v)[i];
            let got = Vec3::from_slice(&ir.vertex(v)[3 * i..3 * i + 3]);
            assert_eq!(got, expect, "v{v} i{i}");
        }
    }
}

#[test]
fn interreflection_between_facing_planes_matches_one_bounce_path_tracing() {
    let (size, gap, div) = (2.0, 0.5, 16);
    let mesh = facing_planes(size, gap, div);
    let caster = build_default(&mesh);
    let (rho_floor, rho_ceil) = (Vec3::splat(0.5), Vec3::new(0.9, 0.1, 0.1));
    let mats = [lambert(rho_floor), lambert(rho_ceil)];
    let ir_seed = |seed: u64| {
        let s = ShBakeSettings {
            seed,
            ..interreflected(3, 256, 1)
        };
        bake(&mesh, &mats, caster.as_ref(), &s).unwrap()
    };
    let ir = ir_seed(0);
    let sh = bake(
        &mesh,
        &mats,
        caster.as_ref(),
        &settings(3, 256, ShTransferKind::Shadowed),
    )
    .unwrap();
    // Constant white environment: L_0 = ∫ y_0 = 2 sqrt(pi).
    let mut light = vec![Vec3::ZERO; 9];
    light[0] = Vec3::splat(2.0 * PI.sqrt());
    let v = 8 * (div as usize + 1) + 8; // centre of the floor
    assert_eq!(mesh.positions[v], Vec3::ZERO);
    let prt = ir.eval_vertex(v, Vec3::ONE, &light);
    let direct = sh.eval_vertex(v, rho_floor, &light);
    let spread = seed_spread(|seed| {
        ir_seed(seed)
            .eval_vertex(v, Vec3::ONE, &light)
            .to_array()
            .map(f64::from)
            .to_vec()
    });

    // Path-traced reference at the same point: direct + one diffuse bounce, continuous hit
    // points (no vertex interpolation).
    let ng = vertex_geometric_normals(&mesh);
    let frame = Frame::from_normal(Vec3::Y);
    let mut rng = Rng::new(777, 0);
    let m = 200_000;
    let (mut s, mut s2) = ([0.0f64; 3], [0.0f64; 3]);
    for _ in 0..m {
        let d = frame
            .to_world(square_to_cosine_hemisphere(rng.next_vec2()))
            .normalize();
        let x = match caster.intersect(&surface_ray(mesh.positions[v], ng[v], d)) {
            None => Vec3::ONE,
            Some(hit) => {
                let tri = hit.tri as usize;
                let g = mesh.geometric_normal(tri);
                if g.dot(d) >= 0.0 {
                    Vec3::ZERO
                } else {
                    let q = mesh.point(tri, hit.u, hit.v);
                    let fq = Frame::from_normal(mesh.shading_normal(tri, hit.u, hit.v));
                    let d2 = fq
                        .to_world(square_to_cosine_hemisphere(rng.next_vec2()))
                        .normalize();
                    let rho_q = mats[mesh.material_ids[tri] as usize].diffuse_albedo();
                    if caster.occluded(&surface_ray(q, g, d2)) {
                        Vec3::ZERO
                    } else {
                        rho_q
                    }
                }
            }
        } * rho_floor;
        for c in 0..3 {
            s[c] += x[c] as f64;
            s2[c] += (x[c] * x[c]) as f64;
        }
    }
    let mean = s.map(|x| x / m as f64);
    let sigma: Vec<f64> = (0..3)
        .map(|c| (s2[c] / m as f64 - mean[c] * mean[c]).max(0.0).sqrt())
        .collect();
    for c in 0..3 {
        // 4 combined standard errors (the bake's measured over seeds), plus 2% of the
        // indirect part for the linear interpolation of the ceiling's vertex transfer over
        // 1/8-wide cells (the reference uses exact hit points).
        let indirect = (prt[c] - direct[c]) as f64;
        let se = (sigma[c] * sigma[c] / m as f64 + spread[c] * spread[c]).sqrt();
        let tol = 4.0 * se + 0.02 * indirect;
        assert!(
            (prt[c] as f64 - mean[c]).abs() < tol,
            "channel {c}: PRT {} vs PT {} (tol {tol})",
            prt[c],
            mean[c]
        );
    }
    // Interreflection adds light, and it is the ceiling's colour that bleeds onto the floor.
    let indirect = prt - direct;
    assert!(indirect.min_element() > 0.0);
    assert!(indirect.x > 5.0 * indirect.y, "colour bleeding: {indirect}");
}

#[test]
fn bake_is_deterministic_for_a_seed_whatever_the_thread_count() {
    let mesh = sphere_on_plane();
    let caster = build_default(&mesh);
    let mats = [lambert(Vec3::splat(0.7)), lambert(Vec3::new(0.2, 0.5, 0.8))];
    let one = ShBakeSettings {
        threads: Some(1),
        ..interreflected(3, 32, 1)
    };
    let two = ShBakeSettings {
        threads: Some(2),
        ..one
    };
    let a = bake(&mesh, &mats, caster.as_ref(), &one).unwrap();
    let b = bake(&mesh, &mats, caster.as_ref(), &two).unwrap();
    assert_eq!(a.data, b.data);
    let c = bake(
        &mesh,
        &mats,
        caster.as_ref(),
        &ShBakeSettings { seed: 4, ..two },
    )
    .unwrap();
    assert_ne!(a.data, c.data);
}

#[test]
fn vertex_ranges_are_the_rows_of_the_whole_bake() {
    let mesh = sphere_on_plane();
    let caster = build_default(&mesh);
    let mats = [lambert(Vec3::splat(0.7)), lambert(Vec3::new(0.2, 0.5, 0.8))];
    let n = mesh.vertex_count();
    for s in [
        settings(3, 32, ShTransferKind::Unshadowed),
        settings(3, 32, ShTransferKind::Shadowed),
        interreflected(3, 32, 1),
    ] {
        let whole = bake(&mesh, &mats, caster.as_ref(), &s).unwrap();
        // Uneven parts, one of them empty, not aligned with the parallel chunks.
        let cuts = [0, 37, 37, n / 2 + 5, n];
        let mut joined = Vec::new();
        for w in cuts.windows(2) {
            let part = bake_range(&mesh, &mats, caster.as_ref(), &s, w[0]..w[1]).unwrap();
            assert_eq!(part.vertex_count, w[1] - w[0]);
            part.validate().unwrap();
            joined.extend_from_slice(&part.data);
        }
        assert_eq!(joined, whole.data, "{:?}", s.transfer);
    }
    let s = settings(2, 8, ShTransferKind::Shadowed);
    assert!(bake_range(&mesh, &mats, caster.as_ref(), &s, 0..n + 1).is_err());
}

#[test]
fn kept_hits_and_retraced_rays_give_the_same_bits() {
    let mesh = sphere_on_plane();
    let caster = build_default(&mesh);
    let mats = [lambert(Vec3::new(0.8, 0.6, 0.4)), lambert(Vec3::splat(0.5))];
    let s = interreflected(4, 64, 2);
    let all = 0..mesh.vertex_count();
    let kept =
        bake_with_hit_budget(&mesh, &mats, caster.as_ref(), &s, all.clone(), usize::MAX).unwrap();
    let traced = bake_with_hit_budget(&mesh, &mats, caster.as_ref(), &s, all, 0).unwrap();
    assert_eq!(kept.data, traced.data);
    // (That closest-hit rays of the kept-hits pass see the same visibility as the occlusion
    // rays of the shadowed bake is checked bit for bit by
    // `interreflected_with_black_surroundings_is_shadowed_times_albedo`.)
}

#[test]
fn validation_rejects_bad_settings_and_layouts() {
    let ok = ShBakeSettings::default();
    assert!(ok.validate().is_ok());
    assert!(ShBakeSettings { order: 0, ..ok }.validate().is_err());
    assert!(ShBakeSettings {
        order: MAX_ORDER + 1,
        ..ok
    }
    .validate()
    .is_err());
    assert!(ShBakeSettings { samples: 0, ..ok }.validate().is_err());
    assert!(ShBakeSettings {
        threads: Some(0),
        ..ok
    }
    .validate()
    .is_err());
    let t = ShTransfer {
        order: 2,
        kind: ShTransferKind::Shadowed,
        vertex_count: 2,
        channels: 1,
        data: vec![0.0; 8],
    };
    assert!(t.validate().is_ok());
    let short = ShTransfer {
        data: vec![0.0; 7],
        ..t.clone()
    };
    assert_eq!(
        short.validate().unwrap_err().to_string(),
        "data has 7 floats, expected 2 vertices x 4 coefficients x 1 channels = 8"
    );
    assert_eq!(
        ShTransfer {
            channels: 3,
            ..t.clone()
        }
        .validate()
        .unwrap_err()
        .to_string(),
        "Shadowed transfer must have 1 channels, has 3"
    );
    let mut nan = t.clone();
    nan.data[5] = f32::NAN;
    assert_eq!(
        nan.validate(),
        Err(ShTransferError::NonFinite { vertex: 1 })
    );
    // A material id out of range is a scene error, not a panic.
    let mesh = ground_plane(Vec3::ZERO, 1.0, 1);
    let caster = build_default(&mesh);
    assert!(matches!(
        bake(&mesh, &[], caster.as_ref(), &ok),
        Err(BakeError::Scene(_))
    ));
}

#[test]
fn sizes_that_drive_allocations_are_refused_before_any_work() {
    let ok = ShBakeSettings::default();
    let e = ShBakeSettings {
        samples: 4_000_000_000,
        ..ok
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("samples 4000000000") && e.contains("1048576"),
        "{e}"
    );
    // Order 32 RGB transfer of 10^9 vertices: ~12 TB, refused by the memory estimate.
    let big = ShBakeSettings {
        order: 32,
        transfer: ShTransferKind::Interreflected,
        ..ok
    };
    let bytes = transfer_bytes(&big, 1_000_000_000);
    assert_eq!(bytes, 1_000_000_000u128 * 1024 * 3 * 4 * 3);
    assert!(matches!(
        crate::check_memory(bytes),
        Err(BakeError::Memory { .. })
    ));
    assert!(crate::check_memory(1 << 20).is_ok());
}
