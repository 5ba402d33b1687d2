use super::kernel::GlossyKernel;
use super::*;
use crate::transport::with_threads;
use rayon::prelude::*;
use relight_scene::accel::build_default;
use relight_scene::shapes::{aabb_box, ground_plane};
use std::f64::consts::PI as PI64;

fn conductor(alpha: f32) -> Material {
    Material::GgxConductor {
        specular: Vec3::new(0.9, 0.8, 0.7),
        alpha,
    }
}

fn glossy_materials() -> Vec<Material> {
    vec![
        Material::BlinnPhong {
            diffuse: Vec3::splat(0.4),
            specular: Vec3::splat(0.5),
            exponent: 20.0,
        },
        conductor(0.3),
        Material::GgxPlastic {
            diffuse: Vec3::new(0.5, 0.3, 0.1),
            specular: Vec3::ONE,
            alpha: 0.3,
            ior: 1.49,
        },
    ]
}

/// `∫ f(w) dw` over the upper hemisphere of the local frame, midpoint rule in
/// `(cos theta, phi)` with `n x 4n` cells, in f64.
fn hemisphere_integral(n: usize, f: impl Fn(Vec3) -> f64) -> f64 {
    let np = 4 * n;
    let mut s = 0.0;
    for i in 0..n {
        let c = (i as f64 + 0.5) / n as f64;
        let sz = (1.0 - c * c).sqrt();
        for j in 0..np {
            let ph = (j as f64 + 0.5) / np as f64 * 2.0 * PI64;
            s += f(Vec3::new(
                (sz * ph.cos()) as f32,
                (sz * ph.sin()) as f32,
                c as f32,
            ));
        }
    }
    s * 2.0 * PI64 / (n * np) as f64
}

/// `sum_w T(w) dA(w)` of one cube map, per channel.
fn total(cube: &[Vec3], table: &CubeTable) -> Vec3 {
    cube.iter()
        .zip(&table.solid_angle)
        .map(|(&t, &a)| t * a)
        .sum()
}

/// A 4x4 plane facing +Y, 2x2 quads: vertex 4 is at the origin.
fn plane() -> TriMesh {
    ground_plane(Vec3::ZERO, 4.0, 2)
}

const CENTRE: usize = 4;

/// Settings of the tests: the defaults with fewer indirect paths unless said otherwise.
fn settings() -> SgBakeSettings {
    SgBakeSettings {
        indirect_paths: 16,
        ..SgBakeSettings::default()
    }
}

#[test]
fn unoccluded_direct_matches_glossy_albedo_and_constant_environment() {
    let mesh = plane();
    let caster = build_default(&mesh);
    let s = settings();
    for m in glossy_materials() {
        let ctx = TransportContext::new(&mesh, vec![m; 9], caster.as_ref(), &s).unwrap();
        let mut out = VertexTransport::default();
        ctx.compute(CENTRE, &mut out);
        // Nothing to bounce off: no indirect transport.
        assert!(out.indirect.iter().all(|&t| t == Vec3::ZERO));
        let td = ctx.direct.len();
        let frame = Frame::from_normal(Vec3::Y);
        let (mut worst, mut worst_lo) = (0.0f32, 0.0f32);
        for v in 0..ctx.views().len() {
            let (d, vis) = ctx.view_direction(CENTRE, v);
            if !vis {
                continue;
            }
            let wi = frame.to_local(d);
            let got = total(&out.direct[v * td..(v + 1) * td], &ctx.direct);
            // Independent: quadrature of the glossy part over the hemisphere.
            let want = hemisphere_integral(400, |wo| m.glossy_eval(wi, wo).x as f64) as f32;
            // 0.5%: midpoint rule of a 6x32x32 cube map (2.8-degree texels) on lobes of
            // ~15 degrees, cut by the horizon near the clamping angle (measured: <= 0.2%).
            let err = (got.x - want).abs() / want.max(1e-3);
            worst = worst.max(err);
            assert!(
                err < 0.005,
                "{m:?} view {v} ({d}): cube {} vs {want}",
                got.x
            );
            // Constant environment L = 1: glossy total + diffuse L00 part = full albedo.
            let l00 = 2.0 * PI64.sqrt() as f32;
            let (view_k, _) = m.diffuse_factors(wi.z, 1.0);
            let lo = got + m.diffuse_albedo() * (view_k * out.diffuse_sh[0] * l00);
            let mut rng = Rng::new(9, v as u64);
            let n = 40_000;
            let (mut sum, mut sum2) = (Vec3::ZERO, Vec3::ZERO);
            for _ in 0..n {
                let w = m
                    .sample(wi, rng.next_vec2(), rng.next_f32())
                    .map_or(Vec3::ZERO, |s| s.weight);
                sum += w;
                sum2 += w * w;
            }
            let mean = sum / n as f32;
            let se = ((sum2 / n as f32 - mean * mean).max(Vec3::ZERO) / n as f32).sqrt();
            // 5 standard errors of the Monte Carlo reference (about 400 comparisons per run:
            // Bonferroni at 1e-4 each needs 3.9) plus the 0.5% above.
            let z = (lo - mean).abs() / se.max(Vec3::splat(1e-6));
            worst_lo = worst_lo.max(z.max_element());
            let tol = se * 5.0 + mean * 0.005 + Vec3::splat(1e-4);
            assert!(
                (lo - mean).abs().cmple(tol).all(),
                "{m:?} view {v}: PRT {lo} vs MC {mean} +- {se}"
            );
        }
        eprintln!(
            "{m:?}: worst relative error of the direct total {worst:.4}, of L_o in MC \
             standard errors {worst_lo:.2}"
        );
    }
}

#[test]
fn blocked_hemisphere_gives_zero_transport() {
    let mut mesh = plane();
    let open_caster = build_default(&mesh);
    mesh.append(&aabb_box(Vec3::splat(-3.0), Vec3::splat(3.0), 1), 0);
    // Our watertight BVH: texel directions with x = +-z run exactly along the diagonals of
    // the box's faces, which Embree's default (non-watertight) mode may slip through when the
    // workspace enables it.
    let caster = relight_scene::accel::build(&mesh, relight_scene::accel::Backend::Bvh).unwrap();
    let s = settings();
    let mats = vec![conductor(0.3); mesh.vertex_count()];
    let mut out = VertexTransport::default();
    // The same vertex without the box sees the sky (so the test can fail).
    let open = plane();
    let ctx = TransportContext::new(&open, mats[..9].to_vec(), open_caster.as_ref(), &s).unwrap();
    ctx.compute(CENTRE, &mut out);
    assert!(out.direct.iter().any(|&t| t.x > 0.0) && out.diffuse_sh[0] > 0.0);
    let ctx = TransportContext::new(&mesh, mats, caster.as_ref(), &s).unwrap();
    ctx.compute(CENTRE, &mut out);
    assert!(out.direct.iter().all(|&t| t == Vec3::ZERO));
    assert!(out.diffuse_sh.iter().all(|&c| c == 0.0));
    // Paths hit the inside (back faces) of the box: absorbed.
    assert!(out.indirect.iter().all(|&t| t == Vec3::ZERO));
}

/// A glossy floor (the plane, 4000 wide) and a Lambertian wall: the -X face of a box at
/// `x = 1`, 20 high and 40 wide (the floor must catch the shallow downward rays from the
/// top of the wall). Returns the mesh and its per-vertex materials.
fn floor_and_wall(floor: Material, rho: f32) -> (TriMesh, Vec<Material>) {
    let mut mesh = ground_plane(Vec3::ZERO, 4000.0, 2);
    let n_floor = mesh.vertex_count();
    mesh.append(
        &aabb_box(Vec3::new(1.0, 0.0, -20.0), Vec3::new(3.0, 20.0, 20.0), 1),
        0,
    );
    let mut mats = vec![floor; n_floor];
    mats.resize(
        mesh.vertex_count(),
        Material::Lambert {
            albedo: Vec3::splat(rho),
        },
    );
    (mesh, mats)
}

#[test]
fn indirect_off_a_diffuse_wall_matches_closed_form() {
    // One bounce off the wall (Lambert rho) escapes iff its cosine-weighted direction goes
    // up (the floor catches the lower half): probability 1/2. So the indirect total of view
    // v is (rho / 2) ∫_{w hits the wall} glossy_eval(v, w) dw.
    let m = conductor(0.3);
    let rho = 0.6;
    let (mesh, mats) = floor_and_wall(m, rho);
    let caster = build_default(&mesh);
    let s = SgBakeSettings {
        indirect_paths: 4096,
        max_depth: 1,
        ..settings()
    };
    let ctx = TransportContext::new(&mesh, mats.clone(), caster.as_ref(), &s).unwrap();
    let mut out = VertexTransport::default();
    ctx.compute(CENTRE, &mut out);
    let ti = ctx.indirect.len();
    let frame = Frame::from_normal(Vec3::Y);
    let hits_wall = |w: Vec3| {
        let t = 1.0 / w.x;
        w.x > 0.0 && t * w.y <= 20.0 && (t * w.z).abs() <= 20.0
    };
    let (mut sum_got, mut sum_want, mut checked, mut worst) = (0.0f32, 0.0f32, 0, 0.0f32);
    for v in 0..ctx.views().len() {
        let cube = &out.indirect[v * ti..(v + 1) * ti];
        // Light escapes from the wall towards -X and up only: texels clearly elsewhere stay 0.
        for (t, &d) in ctx.indirect.dirs.iter().enumerate() {
            if d.x > 0.2 || d.y < -0.2 {
                assert_eq!(cube[t], Vec3::ZERO, "view {v} texel {t} ({d})");
            }
        }
        let (d, vis) = ctx.view_direction(CENTRE, v);
        if !vis {
            continue;
        }
        let wi = frame.to_local(d);
        let want = 0.5
            * rho
            * hemisphere_integral(300, |wo| {
                if hits_wall(frame.to_world(wo)) {
                    m.glossy_eval(wi, wo).x as f64
                } else {
                    0.0
                }
            }) as f32;
        let got = total(cube, &ctx.indirect).x;
        sum_got += got;
        sum_want += want;
        if want > 0.05 {
            checked += 1;
            worst = worst.max((got - want).abs() / want);
            // 8%: 4096 paths, about half escape: ~2% standard error, plus the cube-map
            // direct/indirect split at the wall's edges.
            assert!(
                (got - want).abs() < 0.08 * want,
                "view {v}: {got} vs {want}"
            );
        } else {
            assert!(got < want + 0.01, "view {v}: {got} vs {want}");
        }
    }
    eprintln!(
        "wall: {checked} views checked, worst {worst:.4}, all views {:.4}",
        (sum_got - sum_want) / sum_want
    );
    assert!(checked >= 10, "{checked} views see the wall in their lobe");
    // All views together: 2% (standard error ~0.3%, plus paths passing under the floor's
    // edge and the finite wall).
    assert!(
        (sum_got - sum_want).abs() < 0.02 * sum_want,
        "{sum_got} vs {sum_want}"
    );
    // More bounces only add light: the first bounces draw the same random numbers.
    let s3 = SgBakeSettings { max_depth: 3, ..s };
    let ctx3 = TransportContext::new(&mesh, mats, caster.as_ref(), &s3).unwrap();
    let mut out3 = VertexTransport::default();
    ctx3.compute(CENTRE, &mut out3);
    let t1 = total(&out.indirect, &ctx.indirect).x;
    let t3 = total(&out3.indirect, &ctx.indirect).x;
    assert!(t3 > t1 * 1.001, "{t3} vs {t1}");
}

#[test]
fn views_below_the_horizon_are_clamped() {
    let mesh = plane();
    let caster = build_default(&mesh);
    let s = settings();
    let m = conductor(0.3);
    let ctx = TransportContext::new(&mesh, vec![m; 9], caster.as_ref(), &s).unwrap();
    let mut out = VertexTransport::default();
    ctx.compute(CENTRE, &mut out);
    let sin_h = 5f32.to_radians().sin();
    let frame = Frame::from_normal(Vec3::Y);
    let visible = ctx.visible_texels(CENTRE, &frame);
    let td = ctx.direct.len();
    let want = {
        let wi = frame.to_local(Vec3::new(5f32.to_radians().cos(), sin_h, 0.0));
        hemisphere_integral(400, |wo| m.glossy_eval(wi, wo).x as f64) as f32
    };
    let mut clamped = 0;
    for (v, &view) in ctx.views().iter().enumerate() {
        let (d, vis) = ctx.view_direction(CENTRE, v);
        assert_eq!(vis, view.y >= sin_h, "view {v}");
        assert_eq!(out.view_visible[v], vis);
        if vis {
            assert_eq!(d, view);
            continue;
        }
        clamped += 1;
        // Clamped to 5 degrees, same azimuth.
        assert!(
            (d.y - sin_h).abs() < 1e-5 && (d.length() - 1.0).abs() < 1e-5,
            "{d}"
        );
        let az = Vec3::new(view.x, 0.0, view.z).normalize();
        assert!(
            Vec3::new(d.x, 0.0, d.z).normalize().dot(az) > 0.9999,
            "{d} vs {view}"
        );
        // Its data is the transport of the clamped direction (1e-5: the GGX kernel's
        // rearranged arithmetic)...
        let mut cube = vec![Vec3::ZERO; td];
        let wi = frame.to_local(d);
        for &(i, wo) in &visible {
            cube[i as usize] = m.glossy_eval(wi, wo);
        }
        for (a, b) in out.direct[v * td..(v + 1) * td].iter().zip(&cube) {
            assert!(
                (*a - *b).abs().max_element() <= 1e-5 * b.max_element(),
                "{a} vs {b}"
            );
        }
        // ...which is not black: its total is the glossy albedo at 85 degrees (2%: the
        // lobe is cut by the horizon, where the texel midpoint rule is coarsest).
        let got = total(&cube, &ctx.direct).x;
        assert!(
            (got - want).abs() < 0.02 * want,
            "view {v}: {got} vs {want}"
        );
    }
    assert!(clamped >= 40, "{clamped} views below the horizon");
}

#[test]
fn deterministic_for_a_seed_and_any_thread_count() {
    let (mesh, mats) = floor_and_wall(conductor(0.2), 0.7);
    let caster = build_default(&mesh);
    let s = SgBakeSettings {
        direct_res: 8,
        indirect_paths: 32,
        ..settings()
    };
    let ctx = TransportContext::new(&mesh, mats.clone(), caster.as_ref(), &s).unwrap();
    let run = |ctx: &TransportContext, threads| {
        with_threads(Some(threads), || {
            (0..ctx.vertex_count())
                .into_par_iter()
                .map(|x| {
                    let mut out = VertexTransport::default();
                    ctx.compute(x, &mut out);
                    out
                })
                .collect::<Vec<_>>()
        })
        .unwrap()
    };
    let (a, b) = (run(&ctx, 1), run(&ctx, 2));
    let bits = |o: &VertexTransport| {
        let f = |v: &[Vec3]| {
            v.iter()
                .flat_map(|t| t.to_array().map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        (
            o.view_visible.clone(),
            f(&o.direct),
            f(&o.indirect),
            o.diffuse_sh.iter().map(|c| c.to_bits()).collect::<Vec<_>>(),
        )
    };
    for (x, (ta, tb)) in a.iter().zip(&b).enumerate() {
        assert_eq!(bits(ta), bits(tb), "vertex {x}");
    }
    assert!(a[CENTRE].indirect.iter().any(|&t| t != Vec3::ZERO));
    // Another seed draws other paths.
    let s2 = SgBakeSettings { seed: 1, ..s };
    let ctx2 = TransportContext::new(&mesh, mats, caster.as_ref(), &s2).unwrap();
    let mut out = VertexTransport::default();
    ctx2.compute(CENTRE, &mut out);
    assert_ne!(out.indirect, a[CENTRE].indirect);
    assert_eq!(out.direct, a[CENTRE].direct);
}

#[test]
fn lambert_vertex_has_only_diffuse_transport() {
    let mesh = plane();
    let caster = build_default(&mesh);
    let s = settings();
    let m = Material::Lambert {
        albedo: Vec3::splat(0.5),
    };
    let ctx = TransportContext::new(&mesh, vec![m; 9], caster.as_ref(), &s).unwrap();
    let mut out = VertexTransport::default();
    ctx.compute(CENTRE, &mut out);
    assert!(out
        .direct
        .iter()
        .chain(&out.indirect)
        .all(|&t| t == Vec3::ZERO));
    // Unoccluded cosine: the closed form of the unshadowed SH transfer, (A_l / pi) y_lm(n):
    // L00 = y00 = 1 / (2 sqrt(pi)), the L1 coefficient along Y = (2/3) sqrt(3 / (4 pi)).
    let y00 = 0.5 / PI64.sqrt();
    let y1 = (3.0 / (4.0 * PI64)).sqrt() * 2.0 / 3.0;
    // 2e-3: the cube map's midpoint rule of the clamped cosine.
    assert!(
        (out.diffuse_sh[0] as f64 - y00).abs() < 2e-3 * y00,
        "{}",
        out.diffuse_sh[0]
    );
    assert!(
        (out.diffuse_sh[1] as f64 - y1).abs() < 2e-3 * y1,
        "{}",
        out.diffuse_sh[1]
    );
    let above = ctx
        .views()
        .iter()
        .filter(|v| v.y >= 5f32.to_radians().sin())
        .count();
    assert_eq!(out.view_visible.iter().filter(|&&v| v).count(), above);
}

#[test]
fn new_rejects_bad_input() {
    let mesh = plane();
    let caster = build_default(&mesh);
    let s = settings();
    let m = conductor(0.3);
    let e = TransportContext::new(&mesh, vec![m; 8], caster.as_ref(), &s).err();
    assert!(matches!(e, Some(BakeError::Scene(ref msg)) if msg.contains("8 vertex materials")));
    let bad = SgBakeSettings { direct_res: 0, ..s };
    let e = TransportContext::new(&mesh, vec![m; 9], caster.as_ref(), &bad).err();
    assert!(matches!(e, Some(BakeError::Settings(ref msg)) if msg.contains("direct_res")));
    let mut mats = vec![m; 9];
    mats[3] = conductor(0.0);
    let e = TransportContext::new(&mesh, mats, caster.as_ref(), &s).err();
    assert!(matches!(e, Some(BakeError::Scene(ref msg)) if msg.contains("vertex 3")));
    let mut broken = mesh.clone();
    broken.normals.pop();
    let e = TransportContext::new(&broken, vec![m; 9], caster.as_ref(), &s).err();
    assert!(matches!(e, Some(BakeError::Scene(_))));
}

#[test]
fn materials_per_vertex_and_blends() {
    let mut mesh = plane();
    mesh.material_ids = (0..mesh.triangle_count() as u32).map(|t| t % 2).collect();
    let mats = [Material::Lambert { albedo: Vec3::ZERO }, conductor(0.3)];
    let per_vertex = vertex_materials(&mesh, &mats);
    for (v, m) in per_vertex.iter().enumerate() {
        let first = mesh
            .indices
            .iter()
            .position(|t| t.contains(&(v as u32)))
            .unwrap();
        assert_eq!(*m, mats[mesh.material_ids[first] as usize], "vertex {v}");
    }
    let a = Material::BlinnPhong {
        diffuse: Vec3::ONE,
        specular: Vec3::ZERO,
        exponent: 4.0,
    };
    let b = Material::BlinnPhong {
        diffuse: Vec3::ZERO,
        specular: Vec3::ONE,
        exponent: 400.0,
    };
    assert_eq!(blend_materials(&a, &b, 0.0).unwrap(), a);
    match blend_materials(&a, &b, 0.5).unwrap() {
        Material::BlinnPhong {
            diffuse,
            specular,
            exponent,
        } => {
            assert_eq!((diffuse, specular), (Vec3::splat(0.5), Vec3::splat(0.5)));
            // Geometric mean of 4 and 400.
            assert!((exponent - 40.0).abs() < 1e-3, "{exponent}");
        }
        other => panic!("{other:?}"),
    }
    let g = blend_materials(&conductor(0.01), &conductor(1.0), 0.5).unwrap();
    assert!(matches!(g, Material::GgxConductor { alpha, .. } if (alpha - 0.1).abs() < 1e-5));
    let e = blend_materials(&a, &conductor(0.3), 0.5).unwrap_err();
    assert_eq!(e, BlendError::DifferentKinds(a, conductor(0.3)));
    assert!(e.to_string().contains("different kinds"), "{e}");
    assert_eq!(
        blend_materials(&a, &b, 1.5),
        Err(BlendError::Parameter(1.5))
    );
    // Along X: t = 0 at x = -2, 1 at x = 2; vertex 4 (x = 0) halfway.
    let blended = blend_along_axis(&mesh, &a, &b, Vec3::X * 3.0).unwrap();
    for (p, m) in mesh.positions.iter().zip(&blended) {
        let t = (p.x + 2.0) / 4.0;
        assert_eq!(*m, blend_materials(&a, &b, t).unwrap(), "{p}");
    }
    assert_eq!(
        blend_along_axis(&mesh, &a, &b, Vec3::ZERO),
        Err(BlendError::Axis(Vec3::ZERO))
    );
    // Flat across the axis: t = 0 everywhere.
    assert!(blend_along_axis(&mesh, &a, &b, Vec3::Y)
        .unwrap()
        .iter()
        .all(|m| *m == a));
}

#[test]
fn glossy_kernel_matches_glossy_eval() {
    let mut rng = Rng::new(4, 0);
    let mut dirs = Vec::new();
    for i in 0..3000u32 {
        let w = relight_sphere::warp::square_to_uniform_hemisphere(rng.next_vec2());
        dirs.push((i, w));
    }
    let mats = [
        conductor(0.02),
        conductor(0.3),
        conductor(1.5),
        Material::GgxPlastic {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::new(1.0, 0.5, 0.25),
            alpha: 0.1,
            ior: 1.49,
        },
        Material::GgxPlastic {
            diffuse: Vec3::splat(0.5),
            specular: Vec3::ONE,
            alpha: 0.6,
            ior: 2.5,
        },
        glossy_materials()[0],
    ];
    for m in mats {
        let mut kernel = GlossyKernel::new(&m, &dirs, dirs.len() + 5);
        // Five texels that are not visible: the kernel must zero them.
        let mut out = vec![Vec3::splat(-1.0); dirs.len() + 5];
        for _ in 0..20 {
            let mut wi = relight_sphere::warp::square_to_uniform_hemisphere(rng.next_vec2());
            wi.z = wi.z.max(0.02);
            let wi = wi.normalize();
            kernel.eval_view(wi, &mut out);
            assert!(out[dirs.len()..].iter().all(|&t| t == Vec3::ZERO));
            for &(i, wo) in &dirs {
                let want = m.glossy_eval(wi, wo);
                let got = out[i as usize];
                // 2e-5 relative: the same formula with its factors in another order (f32).
                assert!(
                    (got - want).abs().max_element() <= 2e-5 * want.max_element() + 1e-30,
                    "{m:?} wi={wi} wo={wo}: {got} vs {want}"
                );
            }
        }
    }
}
