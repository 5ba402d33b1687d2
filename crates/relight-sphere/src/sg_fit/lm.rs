//! The Levenberg-Marquardt solver of [`super`]: lobes in f64 with their tangent frames, the
//! residual rows and their analytic Jacobian, the normal equations (structured data rows),
//! the Cholesky solve and the bounded steps (module docs of [`super`] for the maths).

// Index loops over RGB channels and lobes mirror the formulas of the module docs.
#![allow(clippy::needless_range_loop)]

use super::{Arrangement, FitOptions, FitTarget, SgFit};
use crate::sg::SgLobe;
use crate::sg_kernel::LobeKernel;
use crate::Vec3;

/// [`Arrangement`] in f64: `sqrt(delta)` and the neighbours' difference vectors
/// `(k1, k2, mu^s_k1 - mu^s_k2)`.
pub(super) struct Arr64 {
    pub(super) sw: f64,
    pub(super) pairs: Vec<(usize, usize, [f64; 3])>,
}

impl Arr64 {
    pub(super) fn new(a: &Arrangement, n: usize) -> Option<Arr64> {
        debug_assert!(n > 0 && a.neighbours.len().is_multiple_of(n) && a.weight >= 0.0);
        if a.weight <= 0.0 || n < 2 {
            return None;
        }
        let mut pairs = vec![];
        for s in a.neighbours.chunks_exact(n) {
            for k1 in 0..n {
                for k2 in k1 + 1..n {
                    let d = s[k1].axis - s[k2].axis;
                    pairs.push((k1, k2, [d.x as f64, d.y as f64, d.z as f64]));
                }
            }
        }
        Some(Arr64 {
            sw: a.weight.sqrt(),
            pairs,
        })
    }
}

#[inline]
pub(super) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(super) fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// A lobe in f64 with its tangent frame; `p = [a_r, a_g, a_b, alpha, beta, ln lambda]`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Lobe64 {
    pub(super) mu: [f64; 3],
    pub(super) s: [f64; 3],
    pub(super) t: [f64; 3],
    pub(super) log_l: f64,
    pub(super) a: [f64; 3],
}

impl Lobe64 {
    pub(super) fn from_lobe(g: &SgLobe) -> Lobe64 {
        let mut l = Lobe64 {
            mu: [0.0; 3],
            s: [0.0; 3],
            t: [0.0; 3],
            log_l: (g.sharpness as f64).ln(),
            a: [
                g.amplitude.x as f64,
                g.amplitude.y as f64,
                g.amplitude.z as f64,
            ],
        };
        l.set_axis([g.axis.x as f64, g.axis.y as f64, g.axis.z as f64]);
        l
    }

    /// Sets the axis and rebuilds the tangent frame (Duff et al. 2017, in f64).
    pub(super) fn set_axis(&mut self, mu: [f64; 3]) {
        let n = normalize(mu);
        let sign = 1f64.copysign(n[2]);
        let a = -1.0 / (sign + n[2]);
        let b = n[0] * n[1] * a;
        self.mu = n;
        self.s = [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
        self.t = [b, sign + n[1] * n[1] * a, -n[1]];
    }

    pub(super) fn to_lobe(self) -> SgLobe {
        let f = |a: [f64; 3]| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32);
        SgLobe {
            axis: f(self.mu).normalize(),
            sharpness: self.log_l.exp() as f32,
            amplitude: f(self.a),
        }
    }
}

/// Calls `row(residual, indices, values)` for every residual of the objective with the
/// non-zero entries of its Jacobian row (the single place where the model is differentiated).
pub(super) fn for_each_row(
    target: &FitTarget,
    lobes: &[Lobe64],
    opts: &FitOptions,
    prior: Option<&[Lobe64]>,
    arr: Option<&Arr64>,
    data: bool,
    mut row: impl FnMut(f64, &[usize], &[f64]),
) {
    let n = lobes.len();
    let ln_eps = ln_epsilon(opts);
    let (mut g, mut gc, mut gl, mut lam) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut idx, mut val) = (vec![0usize; 4 * n], vec![0.0; 4 * n]);
    for (k, l) in lobes.iter().enumerate() {
        lam[k] = l.log_l.exp();
    }
    let texels = if data { target.len() } else { 0 };
    for i in 0..texels {
        let (w, t) = (target.dirs[i], target.values[i]);
        if !texel_values(
            opts.kernel,
            lobes,
            &lam,
            w,
            t,
            ln_eps,
            &mut g,
            &mut gc,
            &mut gl,
        ) {
            continue;
        }
        let sw = target.sqrt_w[i];
        for c in 0..3 {
            let mut f = 0.0;
            for (k, l) in lobes.iter().enumerate() {
                let sa = sw * l.a[c];
                f += l.a[c] * g[k];
                idx[4 * k..4 * k + 4].copy_from_slice(&[
                    6 * k + c,
                    6 * k + 3,
                    6 * k + 4,
                    6 * k + 5,
                ]);
                val[4 * k] = sw * g[k];
                val[4 * k + 1] = sa * gc[k] * dot(l.s, w);
                val[4 * k + 2] = sa * gc[k] * dot(l.t, w);
                val[4 * k + 3] = sa * gl[k];
            }
            row(sw * (f - t[c]), &idx, &val);
        }
    }
    if let Some(p) = prior {
        let (wm, ww) = (
            opts.prior_weights.mean.sqrt(),
            opts.prior_weights.width.sqrt(),
        );
        for (k, (l, q)) in lobes.iter().zip(p).enumerate() {
            if wm > 0.0 {
                for c in 0..3 {
                    row(
                        wm * (l.mu[c] - q.mu[c]),
                        &[6 * k + 3, 6 * k + 4],
                        &[wm * l.s[c], wm * l.t[c]],
                    );
                }
            }
            if ww > 0.0 {
                row(ww * (l.log_l - q.log_l), &[6 * k + 5], &[ww]);
            }
        }
    }
    if let Some(en) = opts.energy {
        let sw = en.weight.sqrt();
        let (mut idx, mut val) = (Vec::with_capacity(2 * n), Vec::with_capacity(2 * n));
        for c in 0..3 {
            idx.clear();
            val.clear();
            let mut sum = 0.0;
            for (k, l) in lobes.iter().enumerate() {
                let (i, di) = kernel_integral64(opts.kernel, lam[k]);
                sum += l.a[c] * i;
                idx.extend([6 * k + c, 6 * k + 5]);
                val.extend([sw * i, sw * l.a[c] * di]);
            }
            row(sw * (sum - en.integral[c]), &idx, &val);
        }
    }
    if let Some(a) = arr {
        for &(k1, k2, d) in &a.pairs {
            let (l1, l2) = (&lobes[k1], &lobes[k2]);
            let diff = [
                l1.mu[0] - l2.mu[0],
                l1.mu[1] - l2.mu[1],
                l1.mu[2] - l2.mu[2],
            ];
            let m = -dot(diff, d);
            if m <= 0.0 {
                continue;
            }
            let f = 1.5 * a.sw * m.sqrt();
            row(
                a.sw * m * m.sqrt(),
                &[6 * k1 + 3, 6 * k1 + 4, 6 * k2 + 3, 6 * k2 + 4],
                &[
                    -f * dot(l1.s, d),
                    -f * dot(l1.t, d),
                    f * dot(l2.s, d),
                    f * dot(l2.t, d),
                ],
            );
        }
    }
}

/// Objective `E` and its data part.
pub(super) fn objective(
    t: &FitTarget,
    l: &[Lobe64],
    o: &FitOptions,
    p: Option<&[Lobe64]>,
    a: Option<&Arr64>,
) -> f64 {
    let mut e = data_cost(t, l, o);
    for_each_row(t, l, o, p, a, false, |r, _, _| e += r * r);
    e
}

/// `ln zero_epsilon` (texels with zero data where every `lambda (mu . w - 1)` is below it
/// are skipped), or `-inf` when skipping is off.
pub(super) fn ln_epsilon(o: &FitOptions) -> f64 {
    if o.zero_epsilon > 0.0 {
        o.zero_epsilon.ln()
    } else {
        f64::NEG_INFINITY
    }
}

/// The unit lobes at texel `w` with data `v`: values `g[k]`, `gc[k] = dg / d(mu_k . w)` and
/// `gl[k] = dg / d ln lambda_k` for the fit's kernel ([`crate::sg_kernel`]), and whether the
/// texel counts: its data is not zero, or some lobe is above `ln_eps` there ([`ln_epsilon`]).
/// For the Gaussian `g = e^e`, `gc = lambda g`, `gl = e g` with `e = lambda (mu . w - 1)`.
#[inline]
#[allow(clippy::too_many_arguments)]
fn texel_values(
    kernel: LobeKernel,
    lobes: &[Lobe64],
    lam: &[f64],
    w: [f64; 3],
    v: [f64; 3],
    ln_eps: f64,
    g: &mut [f64],
    gc: &mut [f64],
    gl: &mut [f64],
) -> bool {
    let mut live = v != [0.0; 3];
    match kernel {
        LobeKernel::Gaussian => {
            for (k, l) in lobes.iter().enumerate() {
                gl[k] = lam[k] * (dot(l.mu, w) - 1.0);
                live |= gl[k] > ln_eps;
            }
            if live {
                for k in 0..lobes.len() {
                    let e = gl[k];
                    g[k] = e.exp();
                    gc[k] = lam[k] * g[k];
                    gl[k] = e * g[k];
                }
            }
        }
        _ => {
            for (k, l) in lobes.iter().enumerate() {
                let x = dot(l.mu, w) - 1.0;
                let (mut s, mut sc, mut sl) = (0.0, 0.0, 0.0);
                for &(c, wt) in kernel.terms() {
                    let cl = c as f64 * lam[k];
                    let t = wt as f64 * (cl * x).exp();
                    s += t;
                    sc += cl * t;
                    sl += cl * x * t;
                }
                (g[k], gc[k], gl[k]) = (s, sc, sl);
                live |= s.ln() > ln_eps;
            }
        }
    }
    live
}

/// The data term alone (the rows of [`for_each_row`] without their Jacobian): the hot loop
/// of every trial step.
pub(super) fn data_cost(t: &FitTarget, lobes: &[Lobe64], o: &FitOptions) -> f64 {
    let n = lobes.len();
    debug_assert!(n <= 10);
    let ln_eps = ln_epsilon(o);
    let mut lam = [0.0; 10];
    for (k, l) in lobes.iter().enumerate() {
        lam[k] = l.log_l.exp();
    }
    let (mut g, mut gc, mut gl) = ([0.0; 10], [0.0; 10], [0.0; 10]);
    let mut sum = 0.0;
    for i in 0..t.len() {
        let (w, v) = (t.dirs[i], t.values[i]);
        if !texel_values(
            o.kernel, lobes, &lam, w, v, ln_eps, &mut g, &mut gc, &mut gl,
        ) {
            continue;
        }
        let mut f = [-v[0], -v[1], -v[2]];
        for (k, l) in lobes.iter().enumerate() {
            for c in 0..3 {
                f[c] += l.a[c] * g[k];
            }
        }
        let sw = t.sqrt_w[i];
        sum += (0..3).map(|c| (sw * f[c]) * (sw * f[c])).sum::<f64>();
    }
    sum
}

/// Normal equations `J^T J` (row-major `6n x 6n`) and `J^T r` of the whole objective. The
/// data rows are accumulated through their structure: with the geometric factors
/// `U = (sqrt(dA) g_k, sqrt(dA) g_k lambda_k (s_k . w), .. (t_k . w), sqrt(dA) g_k e_k)` per
/// lobe, a channel-`c` row is `U_k0` on `a_kc` and `a_kc U_km` on the shared parameters, so
/// `J^T J` needs only `sum U U^T` and `J^T r` only `sum r_c U` (a third of the work of
/// accumulating the rows one by one, which [`for_each_row`] still does for the prior rows
/// and for the tests).
pub(super) fn normal_equations(
    t: &FitTarget,
    lobes: &[Lobe64],
    o: &FitOptions,
    prior: Option<&[Lobe64]>,
    arr: Option<&Arr64>,
) -> (Vec<f64>, Vec<f64>) {
    let n = lobes.len();
    let (m, q) = (6 * n, 4 * n);
    let ln_eps = ln_epsilon(o);
    let lam: Vec<f64> = lobes.iter().map(|l| l.log_l.exp()).collect();
    let (mut g, mut gc, mut gl, mut u) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; q]);
    let (mut uu, mut ru) = (vec![0.0; q * q], vec![0.0; 3 * q]);
    for i in 0..t.len() {
        let (w, v) = (t.dirs[i], t.values[i]);
        if !texel_values(
            o.kernel, lobes, &lam, w, v, ln_eps, &mut g, &mut gc, &mut gl,
        ) {
            continue;
        }
        let sw = t.sqrt_w[i];
        let mut f = [-v[0], -v[1], -v[2]];
        for (k, l) in lobes.iter().enumerate() {
            for c in 0..3 {
                f[c] += l.a[c] * g[k];
            }
            u[4 * k] = sw * g[k];
            u[4 * k + 1] = sw * gc[k] * dot(l.s, w);
            u[4 * k + 2] = sw * gc[k] * dot(l.t, w);
            u[4 * k + 3] = sw * gl[k];
        }
        for a in 0..q {
            let ua = u[a];
            for b in a..q {
                uu[a * q + b] += ua * u[b];
            }
        }
        for c in 0..3 {
            let r = sw * f[c];
            for a in 0..q {
                ru[c * q + a] += r * u[a];
            }
        }
    }
    for a in 0..q {
        for b in 0..a {
            uu[a * q + b] = uu[b * q + a];
        }
    }
    let (mut jtj, mut jtr) = (vec![0.0; m * m], vec![0.0; m]);
    for (k, lk) in lobes.iter().enumerate() {
        for c in 0..3 {
            jtr[6 * k + c] = ru[c * q + 4 * k];
            for mm in 0..3 {
                jtr[6 * k + 3 + mm] += lk.a[c] * ru[c * q + 4 * k + 1 + mm];
            }
        }
        for (j, lj) in lobes.iter().enumerate() {
            let akj: f64 = (0..3).map(|c| lk.a[c] * lj.a[c]).sum();
            for c in 0..3 {
                jtj[(6 * k + c) * m + 6 * j + c] = uu[4 * k * q + 4 * j];
                for l in 0..3 {
                    let x = lj.a[c] * uu[4 * k * q + 4 * j + 1 + l];
                    jtj[(6 * k + c) * m + 6 * j + 3 + l] = x;
                    jtj[(6 * j + 3 + l) * m + 6 * k + c] = x;
                }
            }
            for a in 0..3 {
                for b in 0..3 {
                    jtj[(6 * k + 3 + a) * m + 6 * j + 3 + b] =
                        akj * uu[(4 * k + 1 + a) * q + 4 * j + 1 + b];
                }
            }
        }
    }
    for_each_row(t, lobes, o, prior, arr, false, |r, idx, val| {
        for (a, &i) in idx.iter().enumerate() {
            jtr[i] += val[a] * r;
            for (b, &j) in idx.iter().enumerate() {
                jtj[i * m + j] += val[a] * val[b];
            }
        }
    });
    (jtj, jtr)
}

/// Solves `a x = b` for symmetric positive definite `a` (row-major `m x m`) by Cholesky;
/// `None` if `a` is not numerically positive definite.
pub(super) fn cholesky_solve(a: &[f64], b: &[f64], m: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..=i {
            let mut s = a[i * m + j];
            for k in 0..j {
                s -= l[i * m + k] * l[j * m + k];
            }
            if i == j {
                if s <= 0.0 || !s.is_finite() {
                    return None;
                }
                l[i * m + i] = s.sqrt();
            } else {
                l[i * m + j] = s / l[j * m + j];
            }
        }
    }
    let mut y = b.to_vec();
    for i in 0..m {
        for k in 0..i {
            y[i] -= l[i * m + k] * y[k];
        }
        y[i] /= l[i * m + i];
    }
    for i in (0..m).rev() {
        for k in i + 1..m {
            y[i] -= l[k * m + i] * y[k];
        }
        y[i] /= l[i * m + i];
    }
    Some(y)
}

/// Applies step `d` with the bounds (amplitudes >= 0, log sharpness clamped).
pub(super) fn apply_step(lobes: &[Lobe64], d: &[f64], o: &FitOptions) -> Vec<Lobe64> {
    let (lo, hi) = ((o.lambda_min as f64).ln(), (o.lambda_max as f64).ln());
    lobes
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let p = &d[6 * k..6 * k + 6];
            let mut n = *l;
            for c in 0..3 {
                n.a[c] = (l.a[c] + p[c]).max(0.0);
            }
            n.set_axis([
                l.mu[0] + p[3] * l.s[0] + p[4] * l.t[0],
                l.mu[1] + p[3] * l.s[1] + p[4] * l.t[1],
                l.mu[2] + p[3] * l.s[2] + p[4] * l.t[2],
            ]);
            n.log_l = (l.log_l + p[5]).clamp(lo, hi);
            n
        })
        .collect()
}

/// Bounded Levenberg-Marquardt from `lobes`; returns (lobes, objective, iterations).
pub(super) fn levenberg_marquardt(
    target: &FitTarget,
    mut lobes: Vec<Lobe64>,
    o: &FitOptions,
    prior: Option<&[Lobe64]>,
    arr: Option<&Arr64>,
) -> (Vec<Lobe64>, f64, usize) {
    let m = 6 * lobes.len();
    let (lo, hi) = ((o.lambda_min as f64).ln(), (o.lambda_max as f64).ln());
    let mut cost = objective(target, &lobes, o, prior, arr);
    let mut damping = 1e-3;
    let mut it = 0;
    while it < o.max_iterations && cost > 1e-300 {
        it += 1;
        // Normal equations J^T J, J^T r from the analytic rows.
        let (jtj, jtr) = normal_equations(target, &lobes, o, prior, arr);
        // Freeze parameters at a bound whose descent direction points outward.
        let mut frozen = vec![false; m];
        for (k, l) in lobes.iter().enumerate() {
            for c in 0..3 {
                frozen[6 * k + c] = l.a[c] <= 0.0 && jtr[6 * k + c] > 0.0;
            }
            let g = jtr[6 * k + 5];
            frozen[6 * k + 5] = (l.log_l <= lo && g > 0.0) || (l.log_l >= hi && g < 0.0);
        }
        let max_diag = (0..m).map(|i| jtj[i * m + i]).fold(0.0, f64::max);
        let floor = (1e-12 * max_diag).max(1e-300);
        let mut improved = false;
        while damping < 1e12 {
            let mut a = jtj.clone();
            let mut b: Vec<f64> = jtr.iter().map(|x| -x).collect();
            for i in 0..m {
                if frozen[i] {
                    for j in 0..m {
                        a[i * m + j] = 0.0;
                        a[j * m + i] = 0.0;
                    }
                    a[i * m + i] = 1.0;
                    b[i] = 0.0;
                } else {
                    a[i * m + i] += damping * a[i * m + i].max(floor);
                }
            }
            let Some(d) = cholesky_solve(&a, &b, m) else {
                damping *= 10.0;
                continue;
            };
            let cand = apply_step(&lobes, &d, o);
            let c = objective(target, &cand, o, prior, arr);
            if c < cost {
                let rel = (cost - c) / cost;
                lobes = cand;
                cost = c;
                damping = (damping * 0.3).max(1e-12);
                improved = rel > o.tolerance;
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (lobes, cost, it)
}

/// `I(lambda) = int exp(lambda (mu . w - 1)) dw = 2 pi (1 - exp(-2 lambda)) / lambda` and
/// `lambda I'(lambda) = 4 pi exp(-2 lambda) - I(lambda)` (the energy term's Jacobian).
/// The kernel's unit lobe of sharpness `lambda` at cosine `cos` to its axis, in f64.
#[inline]
pub(super) fn unit64(kernel: LobeKernel, lambda: f64, cos: f64) -> f64 {
    match kernel {
        LobeKernel::Gaussian => (lambda * (cos - 1.0)).exp(),
        _ => kernel
            .terms()
            .iter()
            .map(|&(c, w)| w as f64 * (c as f64 * lambda * (cos - 1.0)).exp())
            .sum(),
    }
}

/// [`unit_integral64`] of a kernel's unit lobe: `sum_j w_j I(c_j lambda)` and its
/// `lambda d/dlambda` (module docs of [`crate::sg_kernel`]).
pub(super) fn kernel_integral64(kernel: LobeKernel, lambda: f64) -> (f64, f64) {
    kernel.terms().iter().fold((0.0, 0.0), |(i, d), &(c, w)| {
        let (ij, dj) = unit_integral64(c as f64 * lambda);
        (i + w as f64 * ij, d + w as f64 * dj)
    })
}

pub(super) fn unit_integral64(lambda: f64) -> (f64, f64) {
    let two_pi = 2.0 * std::f64::consts::PI;
    let e = (-2.0 * lambda).exp();
    let i = if lambda > 1e-8 {
        -two_pi * (-2.0 * lambda).exp_m1() / lambda
    } else {
        2.0 * two_pi
    };
    (i, 2.0 * two_pi * e - i)
}

pub(super) fn finish(
    target: &FitTarget,
    lobes: Vec<Lobe64>,
    cost: f64,
    it: usize,
    o: &FitOptions,
) -> SgFit {
    let data = data_cost(target, &lobes, o);
    let n2 = target.norm2();
    SgFit {
        lobes: lobes.into_iter().map(Lobe64::to_lobe).collect(),
        cost,
        relative_error: if n2 > 0.0 { (data / n2).sqrt() } else { 0.0 },
        iterations: it,
    }
}
