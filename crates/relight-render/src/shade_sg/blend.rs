//! Interpolating lobes across the three nearest views and across a triangle (thesis section
//! 2.3: "corresponding Gaussians ... are interpolated using the barycentric weights"), and
//! matching the lobes of the corners before they are blended (the per-(vertex, view) lobe
//! matching the thesis discusses in section 3.4).
//!
//! # Blends ([`LobeBlend`])
//! * [`LobeBlend::Linear`] ([`blend3`]): axes summed with the weights and renormalised,
//!   sharpness and amplitude linear, as the paper's vertex program interpolates its
//!   `mean_var`. The blend's energy `a int G ~ 2 pi a / lambda` is a weighted mean of the
//!   corners' (weights `w_j lambda_j`), so it never exceeds the brightest corner; but a corner
//!   whose lobe has **no energy** (a lobe the fit switched off, an occluded view) still pulls
//!   the sharpness: blended with a broad zero-amplitude lobe, a sharp lobe keeps almost all its
//!   energy across the whole triangle instead of fading out (`(w a) / (w lambda + (1 - w)
//!   lambda_0) ~ a / lambda` for `lambda_0 << lambda`).
//! * [`LobeBlend::Energy`] ([`blend3_energy`]): the energies `E_j = a_j int G_j` (per channel)
//!   are interpolated linearly, so the blend's energy is exactly the barycentric mean of the
//!   corners'; the axis and the sharpness are blended with weights `w_j e_j` (`e_j` the
//!   channel sum of `E_j`), so a corner without energy has no say in the shape, and the
//!   amplitude is `E / int G` of the blended shape.
//!
//! # Half-vector lobes ([`keep_mass`])
//! A lobe in the half-vector domain (`--lobe-domain half-vector`) holds, over the light
//! directions, `int a K(m . h(w)) dw`, which depends on the view it is seen from: for a sharp
//! lobe about `4 (v . m) a int K dh` (the Jacobian `|dw / dh| = 4 v . h`). Each corner's
//! lobe was fitted, and scaled to its data's integral, for its own view `v_j` (a bake view,
//! or the view a vertex's lobes were blended for), so `a_j ~ E_j / (4 (v_j . m) int K)`;
//! blending the amplitudes linearly and integrating at a view `v` between them gives
//! `sum w_j E_j (v . m) / (v_j . m)`, which exceeds the blend of the energies `sum w_j E_j`
//! wherever `v . m` is a convex mix of the `v_j . m` (the mean of `1 / c` is at least
//! `1 / mean c`): on Spot's conductor the blend across views brightened the object by 4.5 %
//! (docs/RESULTS.md, section sg). [`keep_mass`] rescales the blended lobe so that its
//! integral seen from `v` is `sum w_j E_j`, the corners' integrals each seen from its own
//! view: the half-vector counterpart of [`LobeBlend::Energy`]'s energy, applied after
//! either blend.
//!
//! # Matching ([`match_corners`])
//! With two or more lobes, slot `k` of one corner need not be the Gaussian of slot `k` of
//! another (a "flip", section 3.4). Matching permutes the lobes of each corner to the
//! reference corner's (the one of lowest index: the lowest vertex index of a triangle, so both
//! triangles of an edge whose lowest vertex is on it agree) by the assignment minimising
//! `sum |mu - mu'|^2 + 0.1 (ln lambda - ln lambda')^2`, the distance of the bake's matching
//! (`relight_bake::sg::fit`). Brute force up to three lobes, greedy beyond.

use glam::Vec3;
use relight_sphere::half_vector;
use relight_sphere::sg::SgLobe;
use relight_sphere::sg_kernel::LobeKernel;

/// How lobes are interpolated (module docs; which blend the frame uses where is
/// `ShadeOptions`'s, chosen by the figures of docs/RESULTS.md, section sg).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LobeBlend {
    /// Linear axis (renormalised), sharpness and amplitude: the paper's; the frame's blend
    /// across views.
    Linear,
    /// Linear energy; axis and sharpness weighted by energy: the frame's blend across a
    /// triangle's corners.
    Energy,
}

/// Blend three lobes with weights `w` (summing to 1): axes summed and renormalised,
/// sharpness and amplitude linear (module docs). If the axes cancel, the axis of the
/// heaviest corner is kept.
#[inline]
pub fn blend3(l: [&SgLobe; 3], w: [f32; 3]) -> SgLobe {
    let axis = l[0].axis * w[0] + l[1].axis * w[1] + l[2].axis * w[2];
    SgLobe {
        axis: axis.try_normalize().unwrap_or(l[heaviest(w)].axis),
        sharpness: l[0].sharpness * w[0] + l[1].sharpness * w[1] + l[2].sharpness * w[2],
        amplitude: l[0].amplitude * w[0] + l[1].amplitude * w[1] + l[2].amplitude * w[2],
    }
}

#[inline]
fn heaviest(w: [f32; 3]) -> usize {
    if w[0] >= w[1] && w[0] >= w[2] {
        0
    } else if w[1] >= w[2] {
        1
    } else {
        2
    }
}

/// Blend three lobes with weights `w` (summing to 1) by energy (module docs): the result's
/// integral `a int G` is `sum w_j a_j int G_j` exactly, per channel. Without energy at any
/// corner it is [`blend3`] with zero amplitude.
#[inline]
pub fn blend3_energy(kernel: LobeKernel, l: [&SgLobe; 3], w: [f32; 3]) -> SgLobe {
    let mut energy = Vec3::ZERO;
    let mut u = [0f32; 3];
    for j in 0..3 {
        let e = l[j].amplitude * super::kernel_integral_f32(kernel, l[j].sharpness);
        energy += e * w[j];
        u[j] = w[j] * e.element_sum();
    }
    let total = u[0] + u[1] + u[2];
    // Also catches a NaN total.
    if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return SgLobe {
            amplitude: Vec3::ZERO,
            ..blend3(l, w)
        };
    }
    let u = u.map(|x| x / total);
    let axis = l[0].axis * u[0] + l[1].axis * u[1] + l[2].axis * u[2];
    let sharpness = l[0].sharpness * u[0] + l[1].sharpness * u[1] + l[2].sharpness * u[2];
    SgLobe {
        axis: axis.try_normalize().unwrap_or(l[heaviest(u)].axis),
        sharpness,
        amplitude: energy / super::kernel_integral_f32(kernel, sharpness),
    }
}

/// The integral over the light directions of `l`'s shape at unit amplitude, seen from `v`
/// ([`half_vector::lobe_mass`]): a half-vector lobe's integral per unit of amplitude.
#[inline]
pub fn unit_mass(kernel: LobeKernel, l: &SgLobe, v: Vec3) -> f32 {
    let unit = SgLobe {
        amplitude: Vec3::ONE,
        ..*l
    };
    half_vector::lobe_mass(kernel, &unit, v).x
}

/// A half-vector lobe `blended` from `l` with weights `w` (module docs, "Half-vector
/// lobes"), its amplitude rescaled per channel so that its integral over the light
/// directions seen from `v` is `sum_j w_j a_j mass_j`, with `mass_j` corner `j`'s
/// [`unit_mass`] seen from the view it was made for. The factor is bounded to `[1/4, 4]` of
/// the blend's own amplitude (as the bake's energy rescaling), so a view that barely reaches
/// the lobe (`v . m` near 0) does not blow it up; a lobe that `v` does not reach is returned
/// as blended.
#[inline]
pub fn keep_mass(
    kernel: LobeKernel,
    blended: SgLobe,
    l: [&SgLobe; 3],
    mass: [f32; 3],
    w: [f32; 3],
    v: Vec3,
) -> SgLobe {
    let unit = unit_mass(kernel, &blended, v);
    if unit.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return blended;
    }
    let target: Vec3 = (0..3).map(|j| l[j].amplitude * (mass[j] * w[j])).sum();
    let a = blended.amplitude;
    SgLobe {
        amplitude: (target / unit).clamp(a * 0.25, a * 4.0),
        ..blended
    }
}

/// Blend with `mode`.
#[inline]
pub fn blend3_with(mode: LobeBlend, kernel: LobeKernel, l: [&SgLobe; 3], w: [f32; 3]) -> SgLobe {
    match mode {
        LobeBlend::Linear => blend3(l, w),
        LobeBlend::Energy => blend3_energy(kernel, l, w),
    }
}

/// Lobes per component at most (the bake's limit).
pub const MAX_MATCH: usize = 10;

/// Distance of two lobes for matching (module docs): the slow form of the matrix
/// [`match_corners`] fills (tests compare the two).
#[cfg(test)]
fn lobe_distance(a: &SgLobe, b: &SgLobe) -> f32 {
    let dl = a.sharpness.ln() - b.sharpness.ln();
    (a.axis - b.axis).length_squared() + 0.1 * dl * dl
}

/// The permutation `p` (slot `k` takes `other[p[k]]`) that best matches `other` to
/// `reference` (module docs); the identity wins ties. Only the first `reference.len()`
/// entries are meaningful.
///
/// # Panics
/// Debug builds assert equal lengths of at most `MAX_MATCH`.
pub fn match_corners(reference: &[SgLobe], other: &[SgLobe]) -> [u8; MAX_MATCH] {
    let n = reference.len();
    debug_assert!(n == other.len() && n <= MAX_MATCH);
    let mut p = [0u8; MAX_MATCH];
    for (k, x) in p.iter_mut().enumerate() {
        *x = k as u8;
    }
    // The n x n distances of `lobe_distance`, with each lobe's log-sharpness taken once
    // (the same f32 operations, so the same result, at a sixth of the logarithms for n = 3).
    let lr: [f32; MAX_MATCH] =
        std::array::from_fn(|k| reference.get(k).map_or(0.0, |l| l.sharpness.ln()));
    let lo: [f32; MAX_MATCH] =
        std::array::from_fn(|j| other.get(j).map_or(0.0, |l| l.sharpness.ln()));
    let mut dm = [[0.0f32; MAX_MATCH]; MAX_MATCH];
    for k in 0..n {
        for j in 0..n {
            let dl = lr[k] - lo[j];
            dm[k][j] = (reference[k].axis - other[j].axis).length_squared() + 0.1 * dl * dl;
        }
    }
    let d = |k: usize, j: usize| dm[k][j];
    match n {
        0 | 1 => {}
        2 => {
            if d(0, 1) + d(1, 0) < d(0, 0) + d(1, 1) {
                p[0] = 1;
                p[1] = 0;
            }
        }
        3 => {
            const PERMS: [[u8; 3]; 6] = [
                [0, 1, 2],
                [0, 2, 1],
                [1, 0, 2],
                [1, 2, 0],
                [2, 0, 1],
                [2, 1, 0],
            ];
            let cost = |q: &[u8; 3]| (0..3).map(|k| d(k, q[k] as usize)).sum::<f32>();
            let mut best = (cost(&PERMS[0]), 0);
            for (i, q) in PERMS.iter().enumerate().skip(1) {
                let c = cost(q);
                if c < best.0 {
                    best = (c, i);
                }
            }
            p[..3].copy_from_slice(&PERMS[best.1]);
        }
        _ => {
            let mut used = [false; MAX_MATCH];
            for (k, slot) in p.iter_mut().enumerate().take(n) {
                let j = (0..n)
                    .filter(|&j| !used[j])
                    .min_by(|&a, &b| d(k, a).total_cmp(&d(k, b)))
                    .unwrap_or(k);
                used[j] = true;
                *slot = j as u8;
            }
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade_sg::unit_integral_f32;
    use relight_sphere::warp::Rng;

    fn random_lobe(rng: &mut Rng) -> SgLobe {
        SgLobe::new(
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5,
            1.0 + 1000.0 * rng.next_f32() * rng.next_f32(),
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()),
        )
    }

    fn weights(rng: &mut Rng) -> [f32; 3] {
        let (u, v) = (rng.next_f32(), rng.next_f32());
        if u + v > 1.0 {
            [1.0 - u, 1.0 - v, u + v - 1.0]
        } else {
            [u, v, 1.0 - u - v]
        }
    }

    #[test]
    fn energy_blend_interpolates_energy_exactly() {
        let mut rng = Rng::new(9, 1);
        for _ in 0..1000 {
            let l: Vec<SgLobe> = (0..3).map(|_| random_lobe(&mut rng)).collect();
            let w = weights(&mut rng);
            let b = blend3_energy(LobeKernel::Gaussian, [&l[0], &l[1], &l[2]], w);
            let want: Vec3 = (0..3)
                .map(|j| l[j].amplitude * unit_integral_f32(l[j].sharpness) * w[j])
                .sum();
            let got = b.amplitude * unit_integral_f32(b.sharpness);
            // f32 rounding of a few products and one division.
            assert!(
                ((got - want).abs() / want.max(Vec3::splat(1e-6))).max_element() < 1e-4,
                "{got} vs {want}"
            );
        }
    }

    #[test]
    fn keep_mass_blends_half_vector_lobes_by_their_integrals() {
        // One half-vector GGX-kernel lobe (axis +z, sharpness 150), fitted at three views 40,
        // 55 and 70 degrees from its axis and scaled there to integrals 1.0, 0.9 and 0.7 (a
        // conductor's directional albedo falling towards grazing). Seen from a view between
        // them, the kept blend holds the weighted mean of those integrals (f32 rounding and
        // the table's bilinear interpolation, evaluated the same way on both sides: 1e-4);
        // the linear blend of the amplitudes holds more (the control: 7-12 % here).
        let kernel = LobeKernel::Ggx;
        let view = |deg: f32, az: f32| {
            let (t, a) = (deg.to_radians(), az.to_radians());
            Vec3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos())
        };
        let src = [view(40.0, 0.0), view(55.0, 30.0), view(70.0, -20.0)];
        let energy = [1.0f32, 0.9, 0.7];
        let l: [SgLobe; 3] = std::array::from_fn(|j| {
            let unit = SgLobe::new(Vec3::Z, 150.0, Vec3::ONE);
            let mass = half_vector::lobe_mass(kernel, &unit, src[j]).x;
            SgLobe::new(Vec3::Z, 150.0, Vec3::splat(energy[j] / mass))
        });
        let mut worst_control = f32::INFINITY;
        for w in [[0.6f32, 0.3, 0.1], [0.2, 0.5, 0.3], [0.1, 0.2, 0.7]] {
            let v = (src[0] * w[0] + src[1] * w[1] + src[2] * w[2]).normalize();
            let want: f32 = (0..3).map(|j| energy[j] * w[j]).sum();
            let corners = [&l[0], &l[1], &l[2]];
            let plain = blend3(corners, w);
            let mass = [0, 1, 2].map(|j| unit_mass(kernel, &l[j], src[j]));
            let kept = keep_mass(kernel, plain, corners, mass, w, v);
            let got = half_vector::lobe_mass(kernel, &kept, v).x;
            assert!((got / want - 1.0).abs() < 1e-4, "{w:?}: {got} vs {want}");
            let control = half_vector::lobe_mass(kernel, &plain, v).x / want - 1.0;
            eprintln!("{w:?}: the linear blend holds {control:+.4} more");
            worst_control = worst_control.min(control);
        }
        assert!(worst_control > 0.01, "control: {worst_control}");
    }

    #[test]
    fn a_corner_without_energy_does_not_shape_the_energy_blend() {
        let sharp = SgLobe::new(Vec3::Z, 500.0, Vec3::ONE);
        let off = SgLobe::new(Vec3::X, 0.05, Vec3::ZERO);
        for w in [0.1f32, 0.5, 0.9] {
            let b = blend3_energy(
                LobeKernel::Gaussian,
                [&sharp, &off, &off],
                [w, 1.0 - w, 0.0],
            );
            assert!((b.sharpness - 500.0).abs() < 1e-3 && b.axis.dot(Vec3::Z) > 0.9999);
            // The energy fades with the weight; the linear blend keeps almost all of it.
            let e = |l: &SgLobe| l.amplitude.x * unit_integral_f32(l.sharpness);
            assert!((e(&b) / e(&sharp) - w).abs() < 1e-4);
            let lin = blend3([&sharp, &off, &off], [w, 1.0 - w, 0.0]);
            assert!(e(&lin) / e(&sharp) > 0.99, "{}", e(&lin) / e(&sharp));
        }
    }

    #[test]
    fn matching_is_the_cheapest_permutation_by_lobe_distance() {
        // Brute force over every permutation of 2 and 3 lobes with the slow distance.
        let mut rng = Rng::new(5, 3);
        for n in 2..=3usize {
            for _ in 0..200 {
                let a: Vec<SgLobe> = (0..n).map(|_| random_lobe(&mut rng)).collect();
                let b: Vec<SgLobe> = (0..n).map(|_| random_lobe(&mut rng)).collect();
                let cost =
                    |q: &[usize]| -> f32 { (0..n).map(|k| lobe_distance(&a[k], &b[q[k]])).sum() };
                let perms: Vec<Vec<usize>> = if n == 2 {
                    vec![vec![0, 1], vec![1, 0]]
                } else {
                    vec![
                        vec![0, 1, 2],
                        vec![0, 2, 1],
                        vec![1, 0, 2],
                        vec![1, 2, 0],
                        vec![2, 0, 1],
                        vec![2, 1, 0],
                    ]
                };
                let best = perms.iter().map(|q| cost(q)).fold(f32::INFINITY, f32::min);
                let p = match_corners(&a, &b);
                let got: Vec<usize> = p[..n].iter().map(|&j| j as usize).collect();
                assert!(cost(&got) <= best * (1.0 + 1e-6) + 1e-12, "n {n}: {got:?}");
            }
        }
    }

    #[test]
    fn matching_undoes_a_permutation() {
        let mut rng = Rng::new(2, 7);
        for n in 1..=5 {
            for _ in 0..50 {
                let a: Vec<SgLobe> = (0..n).map(|_| random_lobe(&mut rng)).collect();
                // Slot k of `b` holds a's lobe `shift(k)`.
                let s = rng.next_below(n as u32) as usize;
                let b: Vec<SgLobe> = (0..n).map(|k| a[(k + s) % n]).collect();
                let p = match_corners(&a, &b);
                for k in 0..n {
                    assert_eq!(b[p[k] as usize], a[k], "n {n} shift {s}");
                }
            }
        }
    }
}
