use super::*;
use relight_scene::accel::build_default;
use relight_scene::shapes::{aabb_box, ground_plane};
use relight_sphere::vmf::log_likelihood;
use std::f64::consts::PI;

fn lambert(a: f32) -> Material {
    Material::Lambert {
        albedo: Vec3::splat(a),
    }
}

fn blinn(exponent: f32) -> Material {
    Material::BlinnPhong {
        diffuse: Vec3::new(0.3, 0.2, 0.1),
        specular: Vec3::new(0.5, 0.6, 0.7),
        exponent,
    }
}

/// A 4x4 plane facing +Y (material 0) and, if `occluder`, a box standing on it beside the
/// origin (material 1): x in [0.2, 0.8], y in [0, 0.6], z in [-0.5, 0.5].
fn scene(occluder: bool, plane: Material, boxm: Material) -> (TriMesh, Vec<Material>) {
    let mut mesh = ground_plane(Vec3::ZERO, 4.0, 2);
    mesh.material_ids = vec![0; mesh.indices.len()];
    if occluder {
        let mut b = aabb_box(Vec3::new(0.2, 0.0, -0.5), Vec3::new(0.8, 0.6, 0.5), 1);
        b.material_ids = vec![0; b.indices.len()];
        mesh.append(&b, 1);
    }
    let mats = crate::sg::transport::vertex_materials(&mesh, &[plane, boxm]);
    (mesh, mats)
}

fn origin(m: Material) -> SurfacePoint {
    SurfacePoint {
        position: Vec3::ZERO,
        normal: Vec3::Y,
        geometric_normal: Vec3::Y,
        material: m,
    }
}

/// Local view at `theta` degrees from the normal, towards local +X.
fn view(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// Mean and standard error of the per-path estimates `M w_i` of a class (paths that did not
/// contribute count as 0).
fn mean_and_error(samples: &[WeightedDir], paths: u32) -> (f64, f64) {
    let m = paths as f64;
    let (mut s, mut s2) = (0.0, 0.0);
    for w in samples {
        let x = w.weight.x as f64 * m;
        s += x;
        s2 += x * x;
    }
    let mean = s / m;
    (mean, ((s2 / m - mean * mean) / m).max(0.0).sqrt())
}

/// (a) Unoccluded Lambert: the direct class holds the whole albedo, no other class has
/// anything, and the lobe is the cosine lobe about the normal.
#[test]
fn unoccluded_lambert_direct_class_is_the_albedo() {
    let m = Material::Lambert {
        albedo: Vec3::new(0.7, 0.5, 0.3),
    };
    let (mesh, mats) = scene(false, m, m);
    let caster = build_default(&mesh);
    let sc = SliceScene {
        mesh: &mesh,
        caster: caster.as_ref(),
        vertex_materials: &mats,
    };
    let settings = SliceSettings {
        paths: 4096,
        ..Default::default()
    };
    for theta in [0.0, 50.0, 85.0] {
        let samples = trace_slice(&sc, &origin(m), view(theta), &settings, 1, 0);
        let slice = samples.estimate(KappaEstimate::Banerjee, settings.kappa_max);
        let direct = slice.class_integral(PathClass::Direct);
        let (mean, err) = mean_and_error(samples.class(Term::Diffuse, PathClass::Direct), 4096);
        assert!((mean - direct.x as f64).abs() < 1e-5);
        // Five standard errors (about 0.4 % of the albedo here).
        assert!(
            (mean - 0.7).abs() < 5.0 * err + 1e-6,
            "theta {theta}: {mean} +- {err}"
        );
        for c in 0..3 {
            let a = [0.7, 0.5, 0.3][c];
            assert!((direct[c] - a).abs() < 0.02 * a, "{direct}");
        }
        assert_eq!(slice.integral(), direct, "nothing to bounce off");
        assert_eq!(
            slice.lobe(Term::Glossy, PathClass::Direct).amplitude,
            Vec3::ZERO
        );
        // The cosine lobe about the normal (world +Y): axis within 1 degree, kappa within 5 %
        // of A^{-1}(2/3) (Banerjee's eq. 13 is 1 % above the exact inverse at r = 2/3).
        let l = slice.lobe(Term::Diffuse, PathClass::Direct);
        assert!(l.axis.angle_between(Vec3::Y) < 1f32.to_radians(), "{l:?}");
        let k = super::super::material_lobes::cosine_kappa();
        assert!((l.kappa / k - 1.0).abs() < 0.05, "{} vs {k}", l.kappa);
    }
}

/// `int f(v, w) V(w) dw` over the local hemisphere by a midpoint rule with shadow rays.
/// (`visibility = false`: unshadowed).
fn shadowed_transfer(
    sc: &SliceScene,
    p: &SurfacePoint,
    v: Vec3,
    n: usize,
    visibility: bool,
) -> [f64; 3] {
    let frame = Frame::from_normal(p.normal);
    let np = 4 * n;
    let mut s = [0.0f64; 3];
    for i in 0..n {
        let c = (i as f64 + 0.5) / n as f64;
        let sz = (1.0 - c * c).sqrt();
        for j in 0..np {
            let ph = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
            let w = Vec3::new((sz * ph.cos()) as f32, (sz * ph.sin()) as f32, c as f32);
            let f = p.material.eval(v, w);
            if f.max_element() <= 0.0 {
                continue;
            }
            let ray = surface_ray(p.position, p.geometric_normal, frame.to_world(w));
            if !visibility || !sc.caster.occluded(&ray) {
                for k in 0..3 {
                    s[k] += f[k] as f64;
                }
            }
        }
    }
    s.map(|x| x * 2.0 * PI / (n * np) as f64)
}

/// (b) With a box beside the point, the direct class's integral is the shadowed transfer.
#[test]
fn occluded_direct_class_matches_brute_force_shadowed_transfer() {
    let (mesh, mats) = scene(true, blinn(32.0), lambert(0.5));
    let caster = build_default(&mesh);
    let sc = SliceScene {
        mesh: &mesh,
        caster: caster.as_ref(),
        vertex_materials: &mats,
    };
    let settings = SliceSettings {
        paths: 8192,
        max_bounces: 0,
        ..Default::default()
    };
    let p = origin(blinn(32.0));
    // Local +X of the frame of +Y: find the view whose mirror direction goes into the box
    // (the box is at world +X) and one whose mirror direction is free.
    let frame = Frame::from_normal(Vec3::Y);
    for (name, world_view) in [
        ("mirror into the box", Vec3::new(-0.6, 0.5, 0.0)),
        ("mirror free", Vec3::new(0.6, 0.5, 0.0)),
    ] {
        let v = frame.to_local(world_view.normalize());
        let samples = trace_slice(&sc, &p, v, &settings, 2, 5);
        let slice = samples.estimate(KappaEstimate::Banerjee, settings.kappa_max);
        let got = slice.class_integral(PathClass::Direct);
        let exact = shadowed_transfer(&sc, &p, v, 200, true);
        let unshadowed = shadowed_transfer(&sc, &p, v, 200, false);
        // The box matters: it hides most of the glossy lobe in the first case (and a part of
        // the diffuse term in both).
        let lost = 1.0 - exact[0] / unshadowed[0];
        assert!(lost > 0.05, "{name}: the box hides only {lost}");
        let (md, ed) = mean_and_error(samples.class(Term::Diffuse, PathClass::Direct), 8192);
        let (mg, eg) = mean_and_error(samples.class(Term::Glossy, PathClass::Direct), 8192);
        // The two terms share their paths (correlated): add the errors, an upper bound.
        let err = ed + eg;
        assert!((md + mg - got.x as f64).abs() < 1e-5);
        // Five standard errors, plus 2e-3 for the quadrature's 200 x 800 shadow rays along
        // the box's silhouette.
        assert!(
            (got.x as f64 - exact[0]).abs() < 5.0 * err + 2e-3,
            "{name}: slice {} +- {err}, brute force {}",
            got.x,
            exact[0]
        );
        // No bounces: no indirect classes.
        assert_eq!(slice.class_integral(PathClass::IndirectDiffuse), Vec3::ZERO);
    }
}

/// The environment of (c): a constant plus a vMF light (world frame).
struct TestEnv {
    ambient: Vec3,
    light: VmfLobe,
}

impl TestEnv {
    fn radiance(&self, dir: Vec3) -> Vec3 {
        self.ambient + self.light.eval(dir)
    }
}

/// Mean and standard error (channel x) of an independent path tracer's outgoing radiance at
/// `p` towards `v` (local): the path tracer's own BRDF sampling ([`Material::sample`]) at
/// every vertex, the same scattering rules and bounce limit as the slices, written again
/// here (no code of the module under test).
fn path_traced(
    sc: &SliceScene,
    p: &SurfacePoint,
    v: Vec3,
    env: &TestEnv,
    max_bounces: u32,
    n: u32,
) -> (Vec3, f64) {
    let frame = Frame::from_normal(p.normal);
    let mut rng = Rng::new(99, 0);
    let (mut sum, mut s2) = (Vec3::ZERO, 0.0f64);
    for _ in 0..n {
        let Some(s) = p.material.sample(v, rng.next_vec2(), rng.next_f32()) else {
            continue;
        };
        let dir = frame.to_world(s.wo);
        if dir.dot(p.geometric_normal) <= 0.0 {
            continue;
        }
        let mut ray = surface_ray(p.position, p.geometric_normal, dir);
        let mut t = s.weight;
        let mut bounces = 0;
        loop {
            let Some(hit) = sc.caster.intersect(&ray) else {
                let l = t * env.radiance(ray.dir.normalize());
                sum += l;
                s2 += (l.x as f64).powi(2);
                break;
            };
            if bounces >= max_bounces {
                break;
            }
            // Scatter without the code under test: one-sided, the nearest corner's material,
            // the path tracer's sample weight `eval / pdf`.
            let tri = hit.tri as usize;
            let ng = sc.mesh.geometric_normal(tri);
            if ng.dot(ray.dir) >= 0.0 {
                break;
            }
            let f = Frame::from_normal(sc.mesh.shading_normal(tri, hit.u, hit.v).normalize());
            let bary = [1.0 - hit.u - hit.v, hit.u, hit.v];
            let k = (0..3).fold(0, |k, j| if bary[j] > bary[k] { j } else { k });
            let m = sc.vertex_materials[sc.mesh.indices[tri][k] as usize];
            let Some(s) = m.sample(f.to_local(-ray.dir), rng.next_vec2(), rng.next_f32()) else {
                break;
            };
            let next = f.to_world(s.wo);
            if next.dot(ng) <= 0.0 {
                break;
            }
            t *= s.weight;
            bounces += 1;
            ray = surface_ray(sc.mesh.point(tri, hit.u, hit.v), ng, next);
        }
    }
    let mean = sum / n as f32;
    let var = (s2 / n as f64 - (mean.x as f64).powi(2)).max(0.0) / n as f64;
    (mean, var.sqrt())
}

/// `sum_i w_i L(s_i)` over every class: the slice's own Monte Carlo estimate of `L_o`, and its
/// standard error (channel x; per-path sums over the classes).
fn samples_render(samples: &SliceSamples, env: &TestEnv) -> (Vec3, f64) {
    let m = samples.paths as f64;
    let mut sum = Vec3::ZERO;
    // Per-path values are not kept; the classes of one path share its direction, so group
    // equal directions (exact f32 equality: the same ray) to rebuild per-path sums.
    let mut per_path: Vec<(Vec3, f64)> = Vec::new();
    for term in &samples.classes {
        for class in term {
            for w in class {
                let l = w.weight * env.radiance(w.dir);
                sum += l;
                match per_path.iter_mut().rev().find(|(d, _)| *d == w.dir) {
                    Some(e) => e.1 += l.x as f64 * m,
                    None => per_path.push((w.dir, l.x as f64 * m)),
                }
            }
        }
    }
    let mean = sum.x as f64;
    let s2: f64 = per_path.iter().map(|e| e.1 * e.1).sum();
    (sum, ((s2 / m - mean * mean).max(0.0) / m).sqrt())
}

/// Run `f` on the slice scene of [`occluded_scene`].
fn with_occluded<T>(f: impl FnOnce(&SliceScene) -> T) -> T {
    let (mesh, mats) = occluded_scene();
    let caster = build_default(&mesh);
    f(&SliceScene {
        mesh: &mesh,
        caster: caster.as_ref(),
        vertex_materials: &mats,
    })
}

fn occluded_scene() -> (TriMesh, Vec<Material>) {
    scene(true, blinn(32.0), lambert(0.6))
}

/// The light of (c): from the -X side above, so that it lights the box's face that the point
/// sees (indirect diffuse) and its mirror direction for the views below.
fn test_env() -> TestEnv {
    TestEnv {
        ambient: Vec3::splat(0.2),
        light: VmfLobe::new(
            Vec3::new(-0.6, 0.7, 0.2).normalize(),
            20.0,
            Vec3::splat(6.0),
        ),
    }
}

/// Render lobes against the environment: `sum_j alpha_j ambient + <lobe_j, light>`.
fn render_lobes<'a>(lobes: impl IntoIterator<Item = &'a VmfLobe>, env: &TestEnv) -> Vec3 {
    lobes
        .into_iter()
        .map(|l| l.amplitude * env.ambient + inner_product(l, &env.light))
        .sum()
}

/// (c) Rendering the slice against a smooth environment matches an independent path tracer.
/// Three steps, each with its own tolerance:
/// 1. the slice's samples (`sum w_i L(s_i)`, before any fit) are an unbiased estimate of
///    `L_o`: within five combined standard errors of the path tracer;
/// 2. the one-lobe fits render within 12 % of their own samples for the glossy direct class
///    (a Blinn-Phong lobe is nearly a vMF; what is left is the box and the horizon cutting
///    it: measured 1.4 %, 11 %, 5 % for the three views) and within 30 % for the whole slice,
///    whose gap is the diffuse term's classes': a clamped cosine lobe with the box cut out
///    of it is far from one vMF (measured 6 %, 18 %, 24 %; the paper, section 5.2: "this
///    assumption is not valid for diffuse materials");
/// 3. that this gap is the one-lobe approximation: three EM lobes per class
///    ([`SliceSamples::fit_em_nested`]) on the same samples close most of it (measured 3 %,
///    3.6 %, 12 %), so they must do better than one lobe and stay within 15 %.
#[test]
fn slice_lobes_render_like_the_path_tracer() {
    with_occluded(|sc| {
        let settings = SliceSettings {
            paths: 8192,
            max_bounces: 2,
            ..Default::default()
        };
        let env = test_env();
        let p = origin(blinn(32.0));
        let frame = Frame::from_normal(Vec3::Y);
        let opts = EmOptions {
            kappa_max: settings.kappa_max,
            ..Default::default()
        };
        for world_view in [
            Vec3::new(0.6, 0.7, -0.2),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-0.5, 0.4, 0.3),
        ] {
            let v = frame.to_local(world_view.normalize());
            let samples = trace_slice(sc, &p, v, &settings, 4, 1);
            let slice = samples.estimate(KappaEstimate::Banerjee, settings.kappa_max);
            let (reference, ref_err) = path_traced(sc, &p, v, &env, 2, 50_000);
            let (mc, mc_err) = samples_render(&samples, &env);
            let err = (ref_err * ref_err + mc_err * mc_err).sqrt();
            assert!(
                (mc.x as f64 - reference.x as f64).abs() < 5.0 * err,
                "view {world_view}: samples {mc} +- {mc_err}, path tracer {reference} +- {ref_err}"
            );
            // The indirect classes carry something here (the box is lit and seen).
            assert!(slice.class_integral(PathClass::IndirectDiffuse).x > 0.0);

            let rel = |a: Vec3, b: Vec3| ((a - b).abs() / b).max_element();
            let glossy = slice.lobe(Term::Glossy, PathClass::Direct);
            let glossy_samples: Vec3 = samples
                .class(Term::Glossy, PathClass::Direct)
                .iter()
                .map(|w| w.weight * env.radiance(w.dir))
                .sum();
            let gap_glossy = rel(render_lobes([glossy], &env), glossy_samples);
            assert!(
                gap_glossy < 0.12,
                "view {world_view}: glossy direct gap {gap_glossy}"
            );
            let one = slice.shade(env.ambient, &env.light);
            assert_eq!(one, render_lobes(slice.lobes.iter().flatten(), &env));
            let gap_one = rel(one, mc);
            assert!(
                gap_one < 0.30,
                "view {world_view}: lobes {one}, samples {mc}, path tracer {reference}"
            );
            let fits = samples.fit_em_nested(3, &opts);
            let three = render_lobes(
                fits.iter()
                    .flatten()
                    .filter_map(|f| f.last())
                    .flat_map(|f| f.lobes.iter()),
                &env,
            );
            let gap_three = rel(three, mc);
            assert!(
            gap_three < 0.15 && gap_three < gap_one,
            "view {world_view}: three lobes {three} (gap {gap_three}), one {one} (gap {gap_one})"
        );
        }
    });
}

/// (d) More EM lobes per class never lower the likelihood, and the EM's one lobe is at least
/// as likely as the closed-form eq. 13-14 lobe.
#[test]
fn nested_em_per_class_never_lowers_the_likelihood() {
    with_occluded(|sc| {
        let settings = SliceSettings {
            paths: 2048,
            max_bounces: 1,
            ..Default::default()
        };
        let p = origin(blinn(32.0));
        let v = Frame::from_normal(Vec3::Y).to_local(Vec3::new(-0.6, 0.5, 0.0).normalize());
        let samples = trace_slice(sc, &p, v, &settings, 3, 2);
        let opts = EmOptions {
            kappa_max: settings.kappa_max,
            max_iterations: 100,
            ..Default::default()
        };
        let fits = samples.fit_em_nested(3, &opts);
        let closed = samples.estimate(KappaEstimate::Banerjee, settings.kappa_max);
        let mut checked = 0;
        for t in Term::ALL {
            for c in PathClass::ALL {
                let f = &fits[t.index()][c.index()];
                let data = samples.class(t, c);
                if data.is_empty() {
                    assert!(f.is_empty());
                    continue;
                }
                assert_eq!(f.len(), 3);
                for k in 1..3 {
                    assert!(
                        f[k].log_likelihood >= f[k - 1].log_likelihood,
                        "{t:?} {c:?}: {} lobes {} < {} lobes {}",
                        k + 1,
                        f[k].log_likelihood,
                        k,
                        f[k - 1].log_likelihood
                    );
                }
                let one = log_likelihood(data, &[*closed.lobe(t, c)]).expect("samples");
                // 1e-5 nats: the closed-form lobe is rounded to f32 (the EM's is not).
                assert!(
                    f[0].log_likelihood >= one - 1e-5,
                    "{t:?} {c:?}: EM {} < closed form {one}",
                    f[0].log_likelihood
                );
                // Energy kept by every fit.
                let total: Vec3 = data.iter().map(|w| w.weight).sum();
                for fit in f {
                    let a: Vec3 = fit.lobes.iter().map(|l| l.amplitude).sum();
                    assert!((a - total).abs().max_element() <= 1e-4 * total.max_element());
                }
                checked += 1;
            }
        }
        assert!(checked >= 4, "only {checked} classes had samples");
    });
}

#[test]
fn slices_are_deterministic_per_seed_and_stream() {
    with_occluded(|sc| {
        let s = SliceSettings {
            paths: 256,
            max_bounces: 3,
            ..Default::default()
        };
        let p = origin(blinn(16.0));
        let v = view(30.0);
        let a = trace_slice(sc, &p, v, &s, 7, 11);
        assert_eq!(a, trace_slice(sc, &p, v, &s, 7, 11));
        assert_ne!(a, trace_slice(sc, &p, v, &s, 7, 12));
        assert_ne!(a, trace_slice(sc, &p, v, &s, 8, 11));
    });
}

/// A point on the floor inside a closed box: every path hits a back face (surfaces are
/// one-sided), nothing escapes, every lobe has zero amplitude and no NaN.
#[test]
fn slices_without_escaping_samples_have_zero_lobes() {
    let mut mesh = aabb_box(Vec3::splat(-1.0), Vec3::splat(1.0), 1);
    mesh.material_ids = vec![0; mesh.indices.len()];
    let mats = crate::sg::transport::vertex_materials(&mesh, &[lambert(0.5)]);
    let caster = build_default(&mesh);
    let sc = SliceScene {
        mesh: &mesh,
        caster: caster.as_ref(),
        vertex_materials: &mats,
    };
    let p = SurfacePoint {
        position: Vec3::new(0.0, -0.9, 0.0),
        ..origin(blinn(64.0))
    };
    let s = SliceSettings {
        paths: 256,
        ..Default::default()
    };
    let slice = transfer_slice(&sc, &p, view(20.0), &s, 0, 0);
    for l in slice.lobes.iter().flatten() {
        assert_eq!(l.amplitude, Vec3::ZERO);
        assert!(l.axis.is_finite() && l.kappa.is_finite());
    }
    let env = test_env();
    assert_eq!(slice.shade(env.ambient, &env.light), Vec3::ZERO);
    // A view below the horizon gives nothing either.
    let below = transfer_slice(
        &sc,
        &origin(blinn(64.0)),
        Vec3::new(0.0, 0.6, -0.8),
        &s,
        0,
        0,
    );
    assert_eq!(below.integral(), Vec3::ZERO);
}

#[test]
fn settings_are_validated() {
    assert!(SliceSettings::default().validate().is_ok());
    let bad = [
        SliceSettings {
            paths: 0,
            ..Default::default()
        },
        SliceSettings {
            max_bounces: MAX_BOUNCES + 1,
            ..Default::default()
        },
        SliceSettings {
            material_samples: 0,
            ..Default::default()
        },
        SliceSettings {
            kappa_max: f32::NAN,
            ..Default::default()
        },
        SliceSettings {
            kappa_max: 0.5,
            ..Default::default()
        },
    ];
    for s in bad {
        assert!(matches!(s.validate(), Err(BakeError::Settings(_))), "{s:?}");
    }
}
