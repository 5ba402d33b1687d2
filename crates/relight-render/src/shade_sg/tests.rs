//! Tests of `shade_sg`: the fast path against closed forms and against numerical integration.

use super::*;
use relight_bake::sg::VIEW_FREQUENCY;
use relight_sphere::warp::Rng;

/// A 16 x 16 camera looking at the unit sphere (which covers about half of the image).
fn camera(w: u32) -> Camera {
    Camera::look_at([0.3, 0.5, 3.2], [0.0, 0.0, 0.0], 40.0, w, w)
}

fn reflect(v: Vec3, n: Vec3) -> Vec3 {
    2.0 * n.dot(v) * n - v
}

fn lambert(a: f32) -> Material {
    Material::Lambert {
        albedo: Vec3::splat(a),
    }
}

/// A smooth, coloured environment with a broad bright blob (no features finer than the
/// lobes, so the prefilter's trilinear error stays small).
fn smooth_env(d: Vec3) -> Vec3 {
    let blob = (4.0 * (d.dot(Vec3::new(0.5, 0.6, 0.62).normalize()) - 1.0)).exp();
    Vec3::new(0.3, 0.4, 0.6) * (1.1 + 0.8 * d.y)
        + Vec3::new(4.0, 3.0, 1.5) * blob
        + Vec3::splat(0.1 * (1.0 + (2.0 * d.x).sin()))
}

#[test]
fn constant_environment_gives_the_sum_of_lobe_integrals() {
    let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 10, 20);
    let (lam, amp) = (
        [30.0, 300.0],
        [Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.5, 0.1, 0.2)],
    );
    let mut rng = Rng::new(3, 0);
    let axes: Vec<Vec3> = (0..mesh.vertex_count() * 92 * 2)
        .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
        .collect();
    // Random axes per (vertex, view, lobe), the same sharpness and amplitude per slot
    // everywhere: the expected radiance is the same at every pixel whatever the blends do to
    // the axes, as long as energy is kept: by the energy blend whatever lobes are paired
    // (`ShadeOptions::ENERGY`), by the linear blend when slot `k` meets slot `k` (`PAPER`).
    // (The default's linear view blend of *matched* lobes pairs these random axes across
    // slots, whose linear blend does not keep the energy; the matching exists for bakes
    // whose slots do swap.)
    let views_per_vertex = 92;
    let bake = SgBake::from_fn(
        &mesh,
        2,
        |x, _, v, k| {
            let j = Icosphere::new(VIEW_FREQUENCY).nearest_vertex(v);
            SgLobe::new(axes[(x * views_per_vertex + j) * 2 + k], lam[k], amp[k])
        },
        3,
        // DC only: y_00 = 0.2821, so sum T L = L under constant radiance L (L_00 = 2 sqrt(pi) L).
        |_| {
            let mut t = vec![0.0; 9];
            t[0] = 0.282_094_8;
            t
        },
        lambert(0.25),
    );
    let l = Vec3::new(0.5, 1.0, 2.0);
    let mut env = Environment::new(EnvMap::constant(l));
    env.scale = 1.5;
    env.rotate_y_deg = 37.0;
    let lighting = SgLighting::new(&env, 3, 32);
    let glossy: Vec3 = (0..2)
        .map(|k| amp[k] * relight_sphere::sg::unit_integral(lam[k]))
        .sum();
    let expect = env.scale * l * (0.25 + glossy);
    for options in [ShadeOptions::ENERGY, ShadeOptions::PAPER] {
        let r = SgRenderer::new(&mesh, &bake).with_options(options);
        let (img, _) = r.render(&lighting, &camera(16), None, &RasterOptions::default());
        let mut covered = 0;
        for (p, c) in img.image.pixels.iter().zip(&img.coverage) {
            if *c > 0.0 {
                covered += 1;
                // Only float rounding: normalised prefilter weights, bilinear weights summing
                // to one, exact SH projection of a constant map (1e-4 relative).
                assert!(
                    ((*p - expect).abs() / expect).max_element() < 1e-4,
                    "{options:?}: {p} vs {expect}"
                );
            }
        }
        assert!(covered > 50, "{covered}");
    }
}

#[test]
fn fast_path_matches_numerical_integration() {
    let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 12, 24);
    // One lobe per view about the view's mirror direction, sharpness varying over the mesh.
    let bake = SgBake::from_fn(
        &mesh,
        1,
        |x, n, v, _| {
            SgLobe::new(
                reflect(v, n).try_normalize().unwrap_or(n),
                40.0 + 160.0 * (x % 5) as f32 / 4.0,
                Vec3::new(2.0, 1.5, 1.0),
            )
        },
        1,
        |_| vec![0.0],
        lambert(0.0),
    );
    let mut env = Environment::new(EnvMap::cube_from_fn(32, smooth_env));
    env.rotate_y_deg = -20.0;
    let lighting = SgLighting::new(&env, 1, 32);
    let r = SgRenderer::new(&mesh, &bake);
    let cam = camera(20);
    let opts = RasterOptions::default();
    let (fast, _) = r.render(&lighting, &cam, None, &opts);
    let slow = r.render_reference(&lighting, &env, &cam, &opts);
    let (mut worst, mut sum, mut n) = (0f32, 0f32, 0);
    for (a, b) in fast.image.pixels.iter().zip(&slow.image.pixels) {
        if b.max_element() > 0.0 {
            let e = ((*a - *b).abs() / *b).max_element();
            worst = worst.max(e);
            sum += e;
            n += 1;
        }
    }
    // The prefilter's error on a smooth map: the trilinear blend between levels one octave
    // apart and its bilinear texel lookup (env_prefilter docs: 1-5 % away from bright
    // sources). On this map: 2.2 % worst, 0.44 % mean (measured); 4 % and 1.5 % leave margin.
    assert!(n > 100, "{n}");
    assert!(
        worst < 0.04 && sum / (n as f32) < 0.015,
        "worst {worst}, mean {}",
        sum / n as f32
    );
}

#[test]
fn view_interpolation_reproduces_a_lobe_rotating_with_the_view() {
    // Reflection about n is linear and orthogonal, and `locate` returns b with
    // normalize(sum b_j v_j) = v, so blending the mirror axes of the three views gives the
    // mirror axis of v itself, up to rounding.
    let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 4, 8);
    let bake = SgBake::from_fn(
        &mesh,
        1,
        |_, n, v, _| SgLobe::new(reflect(v, n), 100.0, Vec3::ONE),
        1,
        |_| vec![0.0],
        lambert(0.5),
    );
    let r = SgRenderer::new(&mesh, &bake);
    let mut rng = Rng::new(7, 0);
    let mut out = [SgLobe::new(Vec3::Z, 1.0, Vec3::ZERO)];
    for i in 0..2000 {
        let v = relight_sphere::warp::square_to_uniform_sphere(glam::Vec2::new(
            rng.next_f32(),
            rng.next_f32(),
        ));
        let (_, b) = r.views().locate(v);
        assert!((b.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{b:?}");
        assert!(b.iter().all(|&w| w >= -1e-5), "{b:?}");
        let x = i % mesh.vertex_count();
        r.view_lobes(x, v, &mut out);
        let want = reflect(v, mesh.normals[x]);
        assert!(
            (out[0].axis - want).length() < 2e-5,
            "{} vs {want}",
            out[0].axis
        );
        assert!((out[0].sharpness - 100.0).abs() < 1e-3);
    }
}

#[test]
fn walking_locate_agrees_with_the_global_search() {
    let views = Icosphere::new(VIEW_FREQUENCY);
    let mut rng = Rng::new(13, 0);
    let mut hint = None;
    let mut prev = Vec3::Z;
    for i in 0..5000 {
        // Alternate small steps (the walk's case) and jumps (its fallback's).
        let u = glam::Vec2::new(rng.next_f32(), rng.next_f32());
        let jump = relight_sphere::warp::square_to_uniform_sphere(u);
        let d = if i % 7 == 0 {
            jump
        } else {
            (prev + 0.05 * jump).normalize()
        };
        let (t, b) = locate_near(&views, hint, d);
        assert!(b.iter().all(|&w| w >= -1e-5) && (b.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        let tri = views.triangles()[t].map(|j| views.vertices()[j as usize]);
        let back = (tri[0] * b[0] + tri[1] * b[1] + tri[2] * b[2]).normalize();
        assert!((back - d).length() < 1e-5, "{back} vs {d}");
        (hint, prev) = (Some(t), d);
    }
}

/// Lobes that vary non-linearly with the view: axis, sharpness and amplitude.
fn wavy_lobe(x: usize, v: Vec3) -> SgLobe {
    let axis = v + Vec3::new(0.7 * v.y * v.y, 0.3 * (3.0 * v.x).sin(), 0.1 * x as f32);
    SgLobe::new(
        axis,
        50.0 + 40.0 * v.z,
        Vec3::new(1.0 + v.x, 2.0, 1.5 - v.y),
    )
}

#[test]
fn view_blend_is_continuous_across_icosahedron_edges() {
    let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 3, 6);
    let bake = SgBake::from_fn(
        &mesh,
        1,
        |x, _, v, _| wavy_lobe(x, v),
        1,
        |_| vec![0.0],
        lambert(0.5),
    );
    let views = Icosphere::new(VIEW_FREQUENCY);
    let x = 1;
    let blend_in = |t: usize, p: Vec3| {
        let b = views.barycentrics(t, p);
        let [j0, j1, j2] = views.triangles()[t].map(|j| j as usize);
        let l = |j| &bake.direct.get(x, j)[0];
        blend3([l(j0), l(j1), l(j2)], b)
    };
    // A point on every edge, blended in both triangles sharing it: the same lobe.
    for t in 0..views.triangles().len() {
        let tri = views.triangles()[t].map(|j| views.vertices()[j as usize]);
        for k in 0..3 {
            let p = (0.3 * tri[(k + 1) % 3] + 0.7 * tri[(k + 2) % 3]).normalize();
            let u = views.triangle_neighbours(t)[k] as usize;
            let (a, b) = (blend_in(t, p), blend_in(u, p));
            assert!((a.axis - b.axis).length() < 1e-5, "t{t} k{k}");
            assert!((a.sharpness - b.sharpness).abs() < 1e-3);
            assert!((a.amplitude - b.amplitude).abs().max_element() < 1e-5);
        }
    }
    // Along a great circle crossing many triangles, in steps of 1e-3 rad: no jump larger
    // than a Lipschitz bound (the axis turns at most a few times faster than the view).
    let r = SgRenderer::new(&mesh, &bake);
    let mut out = [SgLobe::new(Vec3::Z, 1.0, Vec3::ZERO)];
    let mut prev: Option<SgLobe> = None;
    let (e1, e2) = (
        Vec3::new(1.0, 0.2, 0.1).normalize(),
        Vec3::new(-0.1, 0.3, 1.0),
    );
    let e2 = (e2 - e1 * e1.dot(e2)).normalize();
    let step = 1e-3;
    for i in 0..(2.0 * std::f32::consts::PI / step) as usize {
        let a = i as f32 * step;
        r.view_lobes(x, e1 * a.cos() + e2 * a.sin(), &mut out);
        if let Some(p) = prev {
            assert!((out[0].axis - p.axis).length() < 10.0 * step, "step {i}");
            assert!(
                (out[0].sharpness - p.sharpness).abs() < 200.0 * step,
                "step {i}"
            );
        }
        prev = Some(out[0]);
    }
}

#[test]
fn rotating_the_environment_equals_rotating_the_map() {
    let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 10, 20);
    let bake = SgBake::from_fn(
        &mesh,
        1,
        |x, n, v, _| {
            SgLobe::new(
                reflect(v, n) + 0.01 * n,
                60.0,
                Vec3::splat(1.0 + (x % 3) as f32),
            )
        },
        4,
        |n| {
            let mut t = vec![0.0; 16];
            sh::eval_sh(4, n, &mut t);
            t
        },
        lambert(0.4),
    );
    let r = SgRenderer::new(&mesh, &bake);
    let cam = camera(16);
    let opts = RasterOptions::default();
    for (deg, tol) in [(90.0f32, 1e-4f32), (33.0, 0.03)] {
        let mut rotated = Environment::new(EnvMap::cube_from_fn(32, smooth_env));
        rotated.rotate_y_deg = deg;
        let env_from_world = rotated.env_from_world();
        let moved = Environment::new(EnvMap::cube_from_fn(32, |d| smooth_env(env_from_world * d)));
        let (a, _) = r.render(&SgLighting::new(&rotated, 4, 32), &cam, None, &opts);
        let (b, _) = r.render(&SgLighting::new(&moved, 4, 32), &cam, None, &opts);
        for (p, q) in a.image.pixels.iter().zip(&b.image.pixels) {
            // 90 degrees about +Y maps the cube's texel grid onto itself: equal up to float
            // (1e-4). 33 degrees resamples the map on another grid: the bilinear error of a
            // smooth map at 6 x 32 x 32, well under 3 %.
            let e = ((*p - *q).abs() / q.max(Vec3::splat(1e-3))).max_element();
            assert!(e < tol, "{deg} deg: {p} vs {q}");
        }
    }
}

#[test]
fn fast_sample_matches_the_prefiltered_chain() {
    let env = Environment::new(EnvMap::cube_from_fn(16, smooth_env));
    let l = SgLighting::new(&env, 1, 16);
    let mut rng = Rng::new(11, 0);
    for _ in 0..500 {
        let d = relight_sphere::warp::square_to_uniform_sphere(glam::Vec2::new(
            rng.next_f32(),
            rng.next_f32(),
        ));
        let lambda = (rng.next_f32() * 10.0 - 3.0).exp();
        let (a, b) = (l.sample(d, lambda), l.prefiltered().sample(d, lambda));
        assert!(((a - b).abs() / b).max_element() < 1e-5, "{a} {b}");
    }
}

#[test]
fn cube_resampling_keeps_the_map() {
    // A smooth latlong map resampled to a 6 x 32 x 32 cube: the same function up to the two
    // bilinear reconstructions (latlong, then cube) of a map with a blob about 15 texels
    // wide (1.4 % measured; 3 %), and a power-of-two cube stays as is.
    let ll = EnvMap::latlong_from_fn(128, 65, smooth_env);
    assert_eq!(source_face_size(&ll), 32);
    let cube = to_cube(&ll, 32);
    let mut rng = Rng::new(17, 0);
    for _ in 0..500 {
        let u = glam::Vec2::new(rng.next_f32(), rng.next_f32());
        let d = relight_sphere::warp::square_to_uniform_sphere(u);
        let (a, b) = (cube.eval(d), smooth_env(d));
        assert!(((a - b).abs() / b).max_element() < 0.03, "{d}: {a} vs {b}");
    }
    assert_eq!(to_cube(&cube, 32).texels(), cube.texels());
    assert_eq!(
        source_face_size(&EnvMap::cube(24, vec![Vec3::ONE; 6 * 24 * 24])),
        32
    );
}

#[test]
fn unit_integral_f32_matches_f64() {
    for i in 0..2000 {
        let lambda = (i as f32 * 0.01 - 8.0).exp();
        let (a, b) = (
            unit_integral_f32(lambda),
            relight_sphere::sg::unit_integral(lambda),
        );
        assert!((a - b).abs() <= 2e-6 * b, "{lambda}: {a} {b}");
    }
}

#[test]
fn linear_sharpness_blend_keeps_energy_between_the_corners() {
    let mut rng = Rng::new(5, 0);
    for _ in 0..1000 {
        let l: Vec<SgLobe> = (0..3)
            .map(|_| {
                SgLobe::new(
                    Vec3::Z,
                    10.0 + 1000.0 * rng.next_f32(),
                    Vec3::splat(0.1 + rng.next_f32()),
                )
            })
            .collect();
        let (u, v) = (rng.next_f32(), rng.next_f32());
        let w = if u + v > 1.0 {
            [1.0 - u, 1.0 - v, u + v - 1.0]
        } else {
            [u, v, 1.0 - u - v]
        };
        let e = |l: &SgLobe| l.amplitude.x * unit_integral_f32(l.sharpness);
        let b = e(&blend3([&l[0], &l[1], &l[2]], w));
        let (lo, hi) = l
            .iter()
            .map(e)
            .fold((f32::MAX, 0f32), |(a, c), x| (a.min(x), c.max(x)));
        assert!(
            b >= lo * 0.9999 && b <= hi * 1.0001,
            "{b} not in [{lo}, {hi}]"
        );
    }
}
