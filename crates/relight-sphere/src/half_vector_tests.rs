use super::*;
use std::f32::consts::PI;

/// `(directions, solid angles)` of a fine latlong grid of the whole sphere (exact cell areas).
fn sphere_grid(w: usize) -> (Vec<Vec3>, Vec<f32>) {
    let h = w / 2;
    let mut d = Vec::with_capacity(w * h);
    let mut a = Vec::with_capacity(w * h);
    for r in 0..h {
        let (t0, t1) = (PI * r as f32 / h as f32, PI * (r + 1) as f32 / h as f32);
        let area = (t0.cos() - t1.cos()) * 2.0 * PI / w as f32;
        let t = 0.5 * (t0 + t1);
        for c in 0..w {
            let p = 2.0 * PI * (c as f32 + 0.5) / w as f32;
            d.push(Vec3::new(t.sin() * p.cos(), t.cos(), t.sin() * p.sin()));
            a.push(area);
        }
    }
    (d, a)
}

/// A sky with a gradient, a bright window and a dark ground: smooth and sharp features.
fn sky(d: Vec3) -> f32 {
    let window = Vec3::new(0.3, 0.8, 0.52).normalize();
    let w = if d.dot(window) > 0.985 { 40.0 } else { 0.0 };
    1.0 + 0.8 * d.y.max(0.0) + w - 0.7 * (-d.y).max(0.0)
}

/// The cases: a term's axis `m` and view `v` at `theta_v`, rotated so that the plane of
/// incidence is general (not aligned with the grid's axes).
fn frame(theta_deg: f32, turn: f32) -> (Vec3, Vec3) {
    let rot = glam::Quat::from_axis_angle(Vec3::new(0.2, 1.0, -0.4).normalize(), turn);
    let m = rot * Vec3::new(0.1, 0.9, 0.3).normalize();
    let (a, _) = m.any_orthonormal_pair();
    let t = theta_deg.to_radians();
    (m, (m * t.cos() + a * t.sin()).normalize())
}

#[test]
fn the_table_integrates_half_vector_terms_better_than_one_lookup() {
    // Off-grid sharpness and view angles (interpolated entries), against the sphere's
    // quadrature; each tap and the control integrated by the same quadrature (no chain),
    // so the figures are those of the representation. The control is one isotropic Gaussian
    // at the mirror direction with sharpness s / 4 and the term's exact mass (the "one
    // lookup" of docs/RESULTS.md, section sg, normalised as well as it can be).
    let (dirs, areas) = sphere_grid(1024);
    let l: Vec<f32> = dirs.iter().map(|&d| sky(d)).collect();
    let quad = |f: &dyn Fn(Vec3) -> f32| -> f32 {
        dirs.iter()
            .zip(&areas)
            .zip(&l)
            .map(|((&d, &a), &li)| f(d) * a * li)
            .sum()
    };
    let mut worst = 0.0f32;
    let mut worst_control = 0.0f32;
    for &s in &[3.3f32, 21.0, 90.0] {
        for &theta in &[12.0f32, 37.0, 58.0, 71.0] {
            for &turn in &[0.0f32, 1.3, 2.9] {
                let (m, v) = frame(theta, turn);
                let exact = quad(&|w| term(s, m, v, w));
                let unit = SgLobe::new(m, s, Vec3::ONE);
                let approx = integrate_term(&unit, v, |g| {
                    Vec3::splat(quad(&|w| {
                        g.amplitude.x * (g.sharpness * (g.axis.dot(w) - 1.0)).exp()
                    }))
                })
                .x;
                let mass = quad(&|w| term(s, m, v, w) / sky(w));
                let w0 = (2.0 * v.dot(m) * m - v).normalize();
                let lx = s / 4.0;
                let control = mass / unit_integral(lx) * quad(&|w| (lx * (w0.dot(w) - 1.0)).exp());
                let e = (approx - exact).abs() / exact;
                let ec = (control - exact).abs() / exact;
                println!("s {s} theta {theta} turn {turn}: table {e:.4} one lookup {ec:.4}");
                worst = worst.max(e);
                worst_control = worst_control.max(ec);
            }
        }
    }
    println!("worst: table {worst:.4}, one lookup {worst_control:.4}");
    assert!(worst < 0.05, "table {worst}");
    assert!(worst_control > 2.0 * worst, "control {worst_control}");
}

#[test]
fn interpolated_taps_keep_a_constant_environment_s_integral() {
    // At grid points the weights are scaled to `int g` exactly; between them the
    // interpolation must stay close.
    let (dirs, areas) = sphere_grid(1024);
    let (mut worst, mut worst_broad) = (0.0f32, 0.0f32);
    // 1e-4 is broader than the grid (held at `S_MIN`): its integral must stay near 4 pi, not
    // grow as `1 / s` (the regression: a GGX plastic rendered many times too bright).
    for &s in &[1e-4f32, 0.01, 0.4, 2.7, 33.0, 410.0] {
        for &theta in &[2.5f32, 27.5, 52.5, 77.5] {
            let (m, v) = frame(theta, 0.7);
            let exact: f32 = dirs
                .iter()
                .zip(&areas)
                .map(|(&w, &a)| term(s, m, v, w) * a)
                .sum();
            let c = v.dot(m);
            let model: f32 = taps(s, c)
                .iter()
                .map(|t| t.weight * unit_integral(t.sharpness))
                .sum();
            let e = (model - exact).abs() / exact;
            println!("s {s} theta {theta}: mass error {e:.4}");
            if s < 4.0 {
                worst_broad = worst_broad.max(e);
            } else {
                worst = worst.max(e);
            }
        }
    }
    println!("worst mass error: {worst:.4}, broad terms (s < 4) {worst_broad:.4}");
    assert!(worst < 0.02, "{worst}");
    assert!(worst_broad < 0.02, "{worst_broad}");
}

#[test]
fn every_table_entry_approximates_its_term() {
    // The stored (scaled) taps of every grid entry against `g` on the fit's own quadrature:
    // relative L2 distance. The header of the table states the fits' largest error.
    // Measured by the generator: up to theta_v = 70 degrees
    // at most 0.063 for s >= 4 and 0.156 for broader terms (s = 1-3, whose image in `w`
    // spans most of the sphere); at grazing views five isotropic Gaussians cannot follow a
    // shape `1 / c^2` times thinner across the plane than along it (up to 0.46 at 85
    // degrees).
    let mut worst = (0.0f64, 0, 0);
    let mut worst_broad = 0.0f64;
    let mut worst_grazing = 0.0f64;
    for i in 0..S_COUNT {
        for j in 0..THETA_COUNT {
            let (s, th) = (grid_s(i), grid_theta(j));
            let e = relative_l2(s, th, &taps(s, th.cos()));
            if grid_theta(j).to_degrees() > 70.5 {
                worst_grazing = worst_grazing.max(e);
                continue;
            }
            if s < 4.0 {
                worst_broad = worst_broad.max(e);
                continue;
            }
            if e > worst.0 {
                worst = (e, i, j);
            }
        }
    }
    println!("worst entry up to 70 degrees: {worst:?}, broad {worst_broad:.3}; beyond: {worst_grazing:.3}");
    assert!(worst.0 < 0.07, "{worst:?}");
    assert!(worst_broad < 0.17, "{worst_broad}");
    assert!(worst_grazing < 0.47, "{worst_grazing}");
}

#[test]
fn the_table_is_the_generator_s_output() {
    // Refitting an entry from its stored predecessor (the continuation's warm start) gives
    // the stored entry: the table is current with `fit_entry`.
    for &(i, j) in &[(20usize, 7usize), (6, 12)] {
        let s = grid_s(i);
        // The continuation's start: the mean of the entries above and before (fit_table).
        let (a, b) = (
            table::TABLE[(i + 1) * THETA_COUNT + j],
            table::TABLE[i * THETA_COUNT + j + 1],
        );
        let start: [WarpTap; TAPS] = std::array::from_fn(|k| {
            from_unit(
                s,
                &[
                    0.5 * (a[k][0] + b[k][0]),
                    (a[k][1] * b[k][1]).sqrt(),
                    0.5 * (a[k][2] + b[k][2]),
                ],
            )
        });
        let e = fit_entry(s, grid_theta(j), &start);
        let stored = table::TABLE[i * THETA_COUNT + j];
        for (k, tap) in e.taps.iter().enumerate() {
            let u = to_unit(s, tap);
            for q in 0..3 {
                assert!(
                    (u[q] - stored[k][q]).abs() <= 1e-3 * (1.0 + stored[k][q].abs()),
                    "entry ({i}, {j}) tap {k}: {u:?} vs {:?}",
                    stored[k]
                );
            }
        }
    }
}
