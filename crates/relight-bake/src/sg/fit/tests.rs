//! Tests of the flood-fill fit against synthetic transport whose answer is known.

use super::graph::{regions, Adjacency};
use super::target::{group, CubeTables};
use super::vertex::{fit_vertex, fit_view, match_to, ComponentFit, VertexInput};
use super::*;
use crate::sg::transport::{TransportSource, VertexTransport};
use crate::sg::{FitStart, LobeOrder};
use glam::Vec3;
use relight_sphere::sg::{eval_mixture, unit_integral, SgLobe};
use relight_sphere::sg_fit::{self, FitOptions};
use relight_sphere::warp::Rng;

/// A synthetic transport: `f(x, v, w)` tabulated on the texels of every view.
struct Synthetic<F: Fn(usize, usize, Vec3) -> Vec3 + Sync> {
    vertices: usize,
    tables: CubeTables,
    f: F,
}

impl<F: Fn(usize, usize, Vec3) -> Vec3 + Sync> Synthetic<F> {
    fn new(vertices: usize, res: usize, f: F) -> Self {
        Synthetic {
            vertices,
            tables: CubeTables::new(res),
            f,
        }
    }
}

impl<F: Fn(usize, usize, Vec3) -> Vec3 + Sync> TransportSource for Synthetic<F> {
    fn vertex_count(&self) -> usize {
        self.vertices
    }
    fn direct_res(&self) -> usize {
        self.tables.n
    }
    fn indirect_res(&self) -> usize {
        0
    }
    fn compute(&self, x: usize, out: &mut VertexTransport) {
        let nv = views().vertices().len();
        out.view_visible = vec![true; nv];
        out.direct.clear();
        for v in 0..nv {
            for &d in self.tables.dirs() {
                out.direct.push((self.f)(x, v, d));
            }
        }
        out.indirect.clear();
        out.diffuse_sh = vec![x as f32; 4];
    }
}

fn views() -> &'static Icosphere {
    static VIEWS: std::sync::OnceLock<Icosphere> = std::sync::OnceLock::new();
    VIEWS.get_or_init(|| Icosphere::new(VIEW_FREQUENCY))
}

/// A `w x h` grid of vertices (two triangles per cell).
fn grid(w: usize, h: usize) -> Vec<[u32; 3]> {
    let mut t = vec![];
    for j in 0..h - 1 {
        for i in 0..w - 1 {
            let a = (j * w + i) as u32;
            let (b, c, d) = (a + 1, a + w as u32, a + w as u32 + 1);
            t.push([a, b, d]);
            t.push([a, d, c]);
        }
    }
    t
}

fn config(lobes: usize) -> FitConfig {
    FitConfig {
        direct_lobes: lobes,
        indirect_lobes: 0,
        fit: SgFitSettings {
            max_iterations: 30,
            mean_weight: 0.01,
            width_weight: 0.01,
            spatial_weight: 0.01,
            relax_sweeps: 1,
            energy_weight: 0.0,
            fit_start: FitStart::Neighbour,
            lobe_order: LobeOrder::Joint,
            lobe_shape: Default::default(),
            lobe_kernel: Default::default(),
            lobe_domain: Default::default(),
            regions: 0,
            // The recovery tests check the least-squares fit itself.
            energy: false,
        },
    }
}

/// Two lobes that move smoothly with the vertex and the view (the known answer).
fn truth(x: usize, v: usize) -> Vec<SgLobe> {
    let d = views().vertices()[v];
    let s = 0.05 * x as f32;
    vec![
        SgLobe::new(
            Vec3::new(0.3 + s, 1.0, 0.2) + 0.3 * d,
            40.0,
            Vec3::new(1.0, 0.7, 0.4),
        ),
        SgLobe::new(
            Vec3::new(-0.8, 0.3 - s, 0.4) + 0.3 * d,
            12.0,
            Vec3::new(0.3, 0.4, 0.6),
        ),
    ]
}

#[test]
fn recovers_known_mixtures_on_every_vertex_and_view() {
    let src = Synthetic::new(6, 16, |x, v, d| eval_mixture(&truth(x, v), d));
    let tris = grid(3, 2);
    let fit = fit_mesh(&src, &tris, &config(2), &ProgressBar::hidden());
    let (mut worst, mut sum) = ((0f32, 0f64), 0.0);
    for x in 0..6 {
        for v in 0..92 {
            let (t, got) = (truth(x, v), fit.direct.get(x, v));
            let p = match_to(got, &t);
            let mut err = 0f64;
            let mut norm = 0f64;
            for (k, g) in t.iter().enumerate() {
                worst.0 = worst.0.max(got[p[k]].axis.angle_between(g.axis));
            }
            for (&d, &w) in src.tables.dirs().iter().zip(src.tables.solid_angles()) {
                let e = eval_mixture(got, d) - eval_mixture(&t, d);
                err += (w * e.length_squared()) as f64;
                norm += (w * eval_mixture(&t, d).length_squared()) as f64;
            }
            worst.1 = worst.1.max((err / norm).sqrt());
            sum += (err / norm).sqrt();
        }
    }
    // Noise-free data from the model itself, on a grouped 6x16x16 target and with alignment
    // priors (weight 0.01 of the data energy) pulling towards neighbouring views: the axes
    // come back within 1 degree and the full-resolution relative L2 error within 2 %.
    assert!(
        worst.0 < 1f32.to_radians(),
        "axis error {} deg",
        worst.0.to_degrees()
    );
    // The worst (vertex, view) of 552 within 8 % (the sweeps stop at a 0.1 % relative
    // decrease, and grouped cells lose the residual inside them); the mean within 2 %.
    assert!(worst.1 < 0.08, "relative L2 error {}", worst.1);
    assert!(sum / 552.0 < 0.02, "mean relative L2 error {}", sum / 552.0);
    assert!(fit.stats.mean_relative_error[0] < 0.02, "{:?}", fit.stats);
    assert_eq!(fit.diffuse_stride, 4);
    assert_eq!(fit.diffuse_sh[4 * 5], 5.0);
    assert!(fit.indirect.is_none());
}

/// A glossy transport like the bake's: Blinn-Phong (exponent `e`) or GGX (`alpha`) lobe of
/// view `v` at normal `n`, with half of the hemisphere masked by a wall along `mask`.
fn glossy(n: Vec3, v: Vec3, w: Vec3, mask: Vec3, brdf: (bool, f32)) -> Vec3 {
    let (cos_i, cos_o) = (n.dot(w), n.dot(v).max(0.09));
    if cos_i <= 0.0 || w.dot(mask) < 0.0 {
        return Vec3::ZERO;
    }
    let h = (w + v).normalize();
    let c = n.dot(h).max(0.0);
    let f = if brdf.0 {
        (brdf.1 + 2.0) / (2.0 * std::f32::consts::PI) * c.powf(brdf.1)
    } else {
        let a2 = brdf.1 * brdf.1;
        let dd = (c * c * (a2 - 1.0) + 1.0).powi(2);
        let g = |x: f32| 2.0 * x / (x + (a2 + (1.0 - a2) * x * x).sqrt());
        a2 / (std::f32::consts::PI * dd) * g(cos_i) * g(cos_o) / (4.0 * cos_i * cos_o)
    };
    Vec3::new(0.9, 0.7, 0.5) * f * cos_i
}

#[test]
fn grouping_keeps_the_fit_of_realistic_glossy_lobes() {
    let tables = CubeTables::new(32);
    let n = Vec3::new(0.2, 1.0, 0.1).normalize();
    let v = Vec3::new(0.6, 0.7, -0.3).normalize();
    let mask = Vec3::new(-1.0, 0.0, 0.3).normalize();
    for brdf in [
        (true, 20.0),
        (true, 100.0),
        (true, 500.0),
        (false, 0.05),
        (false, 0.2),
        (false, 0.5),
    ] {
        let data: Vec<Vec3> = tables
            .dirs()
            .iter()
            .map(|&w| glossy(n, v, w, mask, brdf))
            .collect();
        let full = tables.full_target(&data);
        let grouped = group(&tables, &data);
        assert!(
            grouped.target.len() * 4 < full.len(),
            "{}",
            grouped.target.len()
        );
        let o = FitOptions {
            lambda_max: 256.0,
            ..FitOptions::default()
        };
        // The optimum on all texels, refined on the grouped target, measured again on all
        // texels: grouping moves it by less than 0.01 in relative L2 error (cells hold data
        // within 0.4 % of the peak of a plane; what is lost is the residual inside a cell).
        let b = sg_fit::fit(&full, 2, &o, None);
        let r = sg_fit::refine(&grouped.target, &b.lobes, &o, None);
        let r_full = (sg_fit::objective_of(&full, &r.lobes, &o, None) / full.norm2()).sqrt();
        eprintln!(
            "{brdf:?}: {} cells of {}, error {r_full:.4} (all texels {:.4})",
            grouped.target.len(),
            full.len(),
            b.relative_error
        );
        assert!(
            r_full < b.relative_error + 0.01,
            "{brdf:?}: {r_full} vs {}",
            b.relative_error
        );
        // Grouping preserves the data's integral exactly (up to f32 sums).
        let sum: Vec3 = data
            .iter()
            .zip(tables.solid_angles())
            .map(|(&t, &w)| t * w)
            .sum();
        assert!((grouped.integral - sum).abs().max_element() < 1e-4 * sum.max_element());
    }
}

#[test]
fn alignment_makes_ambiguous_views_coherent() {
    // One broad lobe plus noise fitted with two lobes: how the second lobe splits the first
    // is ambiguous, so without alignment it wanders from view to view.
    let mut rng = Rng::new(5, 5);
    let noise: Vec<f32> = (0..92 * 6 * 16 * 16)
        .map(|_| rng.next_f32() - 0.5)
        .collect();
    let tables = CubeTables::new(16);
    let f = move |_: usize, v: usize, d: Vec3| {
        let g = SgLobe::new(Vec3::Y + 0.4 * views().vertices()[v], 6.0, Vec3::ONE);
        let i = v * 6 * 256 + relight_sphere::cubemap::dir_to_texel(16, d);
        g.eval(d) * (1.0 + 0.05 * noise[i])
    };
    let src = Synthetic {
        vertices: 1,
        tables,
        f,
    };
    let roughness = |w: f64| {
        let mut c = config(2);
        (c.fit.mean_weight, c.fit.width_weight) = (w, w);
        let fit = fit_mesh(&src, &[], &c, &ProgressBar::hidden());
        let ico = views();
        let mut sum = 0.0;
        let mut edges = 0;
        for v in 0..92 {
            for &u in ico.neighbours(v) {
                let (a, b) = (fit.direct.get(0, v), fit.direct.get(0, u as usize));
                for k in 0..2 {
                    sum += a[k].axis.angle_between(b[k].axis) as f64
                        + 0.5 * (a[k].sharpness / b[k].sharpness).ln().abs() as f64;
                }
                edges += 1;
            }
        }
        sum / edges as f64
    };
    let (free, aligned) = (roughness(0.0), roughness(0.05));
    // Neighbouring views are 13 degrees apart and the true lobe moves ~5 degrees between
    // them: the aligned fit must vary at most half as much as the free one.
    assert!(aligned < 0.5 * free, "aligned {aligned} free {free}");
}

#[test]
fn regions_cover_the_mesh_and_are_connected() {
    // A 12x12 grid plus an isolated vertex (index 144) and a separate triangle (145..148).
    let mut tris = grid(12, 12);
    tris.push([145, 146, 147]);
    let adj = Adjacency::new(148, &tris);
    for requested in [1, 5, 40] {
        let r = regions(&adj, requested);
        // Every component gets a region: 3 components at least; about `requested` overall.
        assert!(
            r.orders.len() >= 3.max(requested.min(144) * 3 / 4),
            "{}",
            r.orders.len()
        );
        let mut seen = [false; 148];
        for (ri, order) in r.orders.iter().enumerate() {
            for (i, &x) in order.iter().enumerate() {
                assert!(!seen[x as usize]);
                seen[x as usize] = true;
                assert_eq!(r.region_of[x as usize] as usize, ri);
                assert_eq!(r.rank[x as usize] as usize, i);
                // Breadth-first: every vertex after the seed has an earlier neighbour.
                assert!(
                    i == 0
                        || adj.neighbours(x as usize).iter().any(|&y| {
                            r.region_of[y as usize] as usize == ri && r.rank[y as usize] < i as u32
                        }),
                    "vertex {x} of region {ri}"
                );
            }
        }
        assert!(seen.iter().all(|&s| s));
        // Deterministic.
        assert_eq!(regions(&adj, requested).orders, r.orders);
    }
}

#[test]
fn the_fit_does_not_depend_on_the_thread_count() {
    let src = Synthetic::new(20, 8, |x, v, d| eval_mixture(&truth(x, v), d));
    let tris = grid(5, 4);
    let mut c = config(2);
    c.fit.regions = 3;
    let run = |threads| {
        crate::transport::with_threads(Some(threads), || {
            fit_mesh(&src, &tris, &c, &ProgressBar::hidden())
        })
        .unwrap()
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.direct, b.direct);
    assert_eq!(a.stats, b.stats);
    assert_eq!(a.diffuse_sh, b.diffuse_sh);
}

/// Two equal lobes (same amplitude and sharpness) at `+-` an offset from `Y`: only the
/// order of the axes distinguishes the two labellings.
fn twin_lobes(x: usize, v: usize) -> Vec<SgLobe> {
    let d = views().vertices()[v];
    let off = Vec3::new(0.5, 0.0, 0.1 * x as f32 / 20.0);
    vec![
        SgLobe::new(Vec3::Y + off + 0.2 * d, 30.0, Vec3::ONE),
        SgLobe::new(Vec3::Y - off + 0.2 * d, 30.0, Vec3::ONE),
    ]
}

#[test]
fn flips_are_counted_and_removed_by_relaxation() {
    let src = Synthetic::new(20, 8, |x, v, d| eval_mixture(&twin_lobes(x, v), d));
    let tris = grid(5, 4);
    let adj = Adjacency::new(20, &tris);
    let views_n = views().vertices().len();
    let c = config(2);
    let fit = fit_mesh(&src, &tris, &c, &ProgressBar::hidden());
    // Clean data, one region: the flood fill keeps the labelling everywhere.
    assert_eq!(fit.stats.flips, 0, "{:?}", fit.stats);
    // Swap the two lobes of vertex 7 (degree 6 in the grid) in every view: each of its edges
    // is then flipped in every view.
    let mut comp = Component {
        fit: ComponentFit::new(8, 2, &c.fit, views()),
        lobes: fit.direct.lobes.clone(),
        error: vec![-1.0; 20 * 92],
    };
    for v in 0..views_n {
        let i = (7 * views_n + v) * 2;
        comp.lobes.swap(i, i + 1);
    }
    let degree = adj.neighbours(7).len() as u64;
    let mut comps = vec![comp];
    let mut iterations = 0;
    let (before, after) = relax(
        &src,
        &mut comps,
        &adj,
        1,
        &ProgressBar::hidden(),
        &mut iterations,
    );
    assert_eq!(before, degree * views_n as u64);
    assert_eq!(after, 0);
    assert!(iterations > 0);
    // And the relaxed vertex carries the neighbours' labelling again.
    let field = flips::LobeField {
        views: views_n,
        n: 2,
        lobes: &comps[0].lobes,
    };
    assert!((0..views_n).all(|v| !field.flipped(7, 8, v)));
}

#[test]
fn occluded_views_get_zero_amplitude_and_the_neighbours_shape() {
    // Views with a negative x component see nothing.
    let occluded = |v: usize| views().vertices()[v].x < -0.3;
    let src = Synthetic::new(1, 8, move |x, v, d| {
        if occluded(v) {
            Vec3::ZERO
        } else {
            eval_mixture(&truth(x, v), d)
        }
    });
    let fit = fit_mesh(&src, &[], &config(2), &ProgressBar::hidden());
    let ico = views();
    let mut checked = 0;
    for v in (0..92).filter(|&v| occluded(v)) {
        let l = fit.direct.get(0, v);
        for (k, g) in l.iter().enumerate() {
            assert_eq!(g.amplitude, Vec3::ZERO);
            assert!(g.axis.is_finite() && g.sharpness.is_finite() && g.sharpness > 0.0);
            // Mean of the neighbouring views' axes (the alignment prior), up to the changes
            // of those neighbours after this view was visited in the last sweep: two sweeps
            // do not converge the harmonic interpolation inside the occluded cap, hence 15
            // degrees (neighbouring views are 13 degrees apart).
            let mean: Vec3 = ico
                .neighbours(v)
                .iter()
                .map(|&u| fit.direct.get(0, u as usize)[k].axis)
                .sum();
            let a = g.axis.angle_between(mean.normalize()).to_degrees();
            assert!(a < 15.0, "view {v}: {a} degrees");
        }
        checked += 1;
    }
    assert!(checked > 10);
}

#[test]
fn a_mirror_lobe_is_clamped_to_the_resolution_and_keeps_its_energy() {
    // A lobe of sharpness 1e4 (sigma 0.6 degrees) on a 6x16x16 map: texels are ~6 degrees.
    let mirror = SgLobe::new(Vec3::new(0.3, 1.0, 0.2), 1e4, Vec3::new(50.0, 40.0, 30.0));
    let src = Synthetic::new(1, 16, move |_, _, d| mirror.eval(d));
    let fit = fit_mesh(&src, &[], &config(1), &ProgressBar::hidden());
    let tables = CubeTables::new(16);
    let data: Vec<Vec3> = tables.dirs().iter().map(|&d| mirror.eval(d)).collect();
    let integral: Vec3 = data
        .iter()
        .zip(tables.solid_angles())
        .map(|(&t, &w)| t * w)
        .sum();
    for v in 0..92 {
        let g = fit.direct.get(0, v)[0];
        // Bounded by (16 / 2)^2 = 64, the finest lobe the map resolves.
        assert!(g.sharpness <= 64.0 * 1.001, "{g:?}");
        // The integral of the clamped lobe equals the tabulated data's (1e-3: f32 sums).
        let e = g.amplitude * unit_integral(g.sharpness);
        assert!(
            (e - integral).abs().max_element() < 1e-3 * integral.max_element(),
            "{e} {integral}"
        );
    }
}

#[test]
fn degenerate_neighbourhoods_are_fitted_without_the_spatial_term() {
    // Vertices: 0..4 a quad; 4, 5, 6 a triangle coincident with 0, 1, 2 but not welded;
    // 7 in no triangle; 8 only in a degenerate triangle [8, 8, 8].
    let tris = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [8, 8, 8]];
    let src = Synthetic::new(9, 16, |x, v, d| eval_mixture(&truth(x % 4, v), d));
    let c = config(2);
    let fit = fit_mesh(&src, &tris, &c, &ProgressBar::hidden());
    let comp = ComponentFit::new(16, 2, &c.fit, views());
    let mut buf = VertexTransport::default();
    // The seed of the component {4, 5, 6}.
    let r = regions(&Adjacency::new(9, &tris), auto_regions(9));
    let seed = r.orders[r.region_of[4] as usize][0] as usize;
    for x in [seed, 7, 8] {
        // A seed or an isolated vertex: the same as a fit of the vertex alone.
        src.compute(x, &mut buf);
        let alone = fit_vertex(
            &comp,
            &VertexInput {
                data: &buf.direct,
                warm: None,
                spatial: &[],
                views: &comp.view_dirs,
                relax: None,
            },
        );
        for v in 0..92 {
            assert_eq!(
                fit.direct.get(x, v),
                &alone.lobes[v * 2..v * 2 + 2],
                "vertex {x}"
            );
        }
    }
    for x in 0..9 {
        for v in 0..92 {
            let l = fit.direct.get(x, v);
            assert!(l
                .iter()
                .all(|g| g.axis.is_finite() && g.amplitude.is_finite()));
        }
    }
    assert!(fit.stats.mean_relative_error[0] < 0.05, "{:?}", fit.stats);
}

#[test]
fn bake_of_a_glossy_sphere_is_complete_and_deterministic() {
    use crate::sg::{bake, SgBakeSettings};
    use relight_scene::material::Material;
    let mut mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 1.0, 4, 6);
    mesh.material_ids = vec![0; mesh.triangle_count()];
    let mats = [Material::BlinnPhong {
        diffuse: Vec3::splat(0.2),
        specular: Vec3::splat(0.5),
        exponent: 40.0,
    }];
    let caster = relight_scene::accel::build_default(&mesh);
    let settings = SgBakeSettings {
        direct_res: 8,
        indirect_res: 4,
        indirect_paths: 4,
        direct_lobes: 2,
        indirect_lobes: 1,
        ..SgBakeSettings::default()
    };
    let run = |threads| {
        let s = SgBakeSettings {
            threads: Some(threads),
            ..settings
        };
        bake(&mesh, &mats, None, caster.as_ref(), &s).unwrap()
    };
    let (a, b) = (run(1), run(2));
    let nv = mesh.vertex_count();
    assert_eq!(a.direct.lobes.len(), nv * 92 * 2);
    assert_eq!(a.indirect.as_ref().map(|l| l.lobes.len()), Some(nv * 92));
    a.diffuse.validate().unwrap();
    assert_eq!(a.diffuse.order, 5);
    assert!(a
        .direct
        .lobes
        .iter()
        .all(|g| g.axis.is_finite() && g.amplitude.is_finite()));
    assert!(a
        .direct
        .lobes
        .iter()
        .any(|g| g.amplitude.max_element() > 0.0));
    assert_eq!(a.direct, b.direct);
    assert_eq!(a.indirect, b.indirect);
    assert_eq!(a.stats, b.stats);
    // Out-of-range settings are an error, not a panic.
    let bad = SgBakeSettings {
        direct_lobes: 0,
        ..settings
    };
    assert!(bake(&mesh, &mats, None, caster.as_ref(), &bad).is_err());
}

#[test]
fn energy_conservation_matches_the_data_integral() {
    // A heavy-tailed lobe (a sharp plus a broad Gaussian, like GGX) in every view, fitted
    // with one lobe: least squares loses the tail's energy; with `energy` the lobe's integral
    // is the data's, so a constant environment renders exactly.
    let tables = CubeTables::new(16);
    let one: Vec<Vec3> = tables
        .dirs()
        .iter()
        .map(|w| {
            let d = w.dot(Vec3::Y);
            Vec3::new(1.0, 0.5, 0.25) * (0.9 * (20.0 * (d - 1.0)).exp())
                + Vec3::splat(0.05) * (2.0 * (d - 1.0)).exp()
        })
        .collect();
    let t = group(&tables, &one);
    let data: Vec<Vec3> = (0..92).flat_map(|_| one.iter().copied()).collect();
    for energy in [false, true] {
        let settings = SgFitSettings {
            energy,
            ..config(1).fit
        };
        let c = ComponentFit::new(16, 1, &settings, views());
        let input = VertexInput {
            data: &data,
            warm: None,
            spatial: &[],
            views: &c.view_dirs,
            relax: None,
        };
        let fit = fit_vertex(&c, &input);
        for g in &fit.lobes {
            let have = g.amplitude * unit_integral(g.sharpness);
            let rel = ((have - t.integral) / t.integral).abs().max_element();
            if energy {
                assert!(rel < 1e-4, "integral {have} vs data {}", t.integral);
            } else {
                assert!(rel > 0.02, "least squares should miss the tail: {rel}");
            }
        }
    }
}

/// Additive half-vector lobes (`LobeOrder::Additive`): where a wall cuts a GGX lobe, slot
/// 1 of the two-lobe fit of a view is its one-lobe fit's lobe, and a residual lobe that
/// leaves the residual no smaller is dropped, so where coherence terms pull the residual
/// lobe (a prior from unrelated views) the two-lobe fit is never worse than the one-lobe
/// fit. (Where slot 1's peak is bounded, [`super::vertex`]'s `clamp_peak`, the residual is
/// that of the bounded lobe, as stored, and the raw one-lobe error is no bound: there the
/// check is against no lobe at all. Without the gate the test fails: some of these views
/// come out worse with two lobes.)
#[test]
fn additive_lobes_never_raise_a_views_error() {
    let settings = SgFitSettings {
        lobe_kernel: crate::sg::SgKernel::Ggx,
        lobe_domain: crate::sg::SgDomain::HalfVector,
        lobe_order: LobeOrder::Additive,
        ..SgFitSettings::default()
    };
    let [one, two] = [1, 2].map(|k| ComponentFit::new(16, k, &settings, views()));
    let mut rng = Rng::new(5, 0);
    let mut unit = || {
        let z = 2.0 * rng.next_f32() - 1.0;
        let phi = std::f32::consts::TAU * rng.next_f32();
        let s = (1.0 - z * z).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    };
    let (mut helped, mut cases) = (0, 0);
    for i in 0..3000 {
        let (n, mask, v) = (unit(), unit(), unit());
        // Views from grazing to head-on; a prior from unrelated views for half of them, a
        // warm start far from the data for half of those and of the others.
        let v = (v - n * v.dot(n)).normalize_or(n.any_orthonormal_vector());
        let v = (v + n * (0.05 + 2.0 * (i % 6) as f32 / 6.0)).normalize();
        let mut random_lobes = |sharp: f32, a: f32| {
            vec![
                SgLobe::new(unit(), sharp, Vec3::splat(a)),
                SgLobe::new(unit(), 0.1 * sharp, Vec3::ONE),
            ]
        };
        let prior = (i % 2 == 1).then(|| random_lobes(40.0, 1.0));
        let warm = (i % 4 >= 2).then(|| random_lobes(200.0, 5.0));
        let alpha = [0.1, 0.2, 0.4][i % 3];
        let data: Vec<Vec3> = one
            .tables
            .dirs()
            .iter()
            .map(|&w| glossy(n, v, w, mask, (false, alpha)))
            .collect();
        let t = one.view_target(&data, v);
        if t.norm2 <= 0.0 {
            continue;
        }
        let first = |l: &Option<Vec<SgLobe>>| l.as_ref().map(|p| p[..1].to_vec());
        let (l1, e1, _) = fit_view(&one, &t, first(&warm), first(&prior), &[], true);
        let (l2, e2, _) = fit_view(&two, &t, warm, prior.clone(), &[], true);
        assert_eq!(l2[0].axis, l1[0].axis, "slot 1 is the one-lobe fit's lobe");
        // (Up to rounding: the residual is of the lobes in f32, about 1e-7 of the data.)
        let bound = if prior.is_some() { e1 } else { 1.0 };
        assert!(
            e2 <= bound + 1e-5,
            "case {i}: {e2} > {bound} (one lobe {e1})"
        );
        cases += 1;
        helped += usize::from(e2 < 0.95 * e1);
    }
    eprintln!("{helped} of {cases} views fitted better by 5 % with a second lobe");
    assert!(cases >= 2000 && helped > 100, "{helped} of {cases}");
}
