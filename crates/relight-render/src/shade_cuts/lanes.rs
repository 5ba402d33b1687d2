//! The per-fragment sums of `shade_cuts::triangle` (and of the local-light bounce,
//! `crate::shade_local`) over [`LANES`]-wide groups of merged clusters, written so the compiler vectorises them: plain `f32` arithmetic on `[f32; LANES]`
//! groups, no branch (masks become selects), and one body compiled twice, for the portable
//! target and with AVX2 + FMA enabled (chosen at run time with `is_x86_feature_detected!`,
//! like `shade_sh::avx2`). Rust never fuses a multiply and an add on its own, so the two
//! builds give the same bits.
//!
//! Layout: structure-of-arrays, each array a whole number of groups (zero clusters pad the
//! last one; they add `0`).

pub(crate) use super::corners::LANES;
use glam::Vec3;
use relight_scene::material::microfacet::TABLE_RES;

/// A fragment's view of one triangle's merged clusters (`shade_cuts::triangle::TriangleCut`).
pub(crate) struct Groups<'a> {
    /// `|C'_k| <L O>_k`, per colour channel.
    pub power: [&'a [[f32; LANES]]; 3],
    /// `<v_j>_k` of the corners `j`.
    pub vis: [&'a [[f32; LANES]]; 3],
    /// The cluster's direction `mu`, per axis.
    pub dir: [&'a [[f32; LANES]]; 3],
    /// With the cluster spread, `cos theta_p` of each cluster's five-point rule
    /// ([`relight_bake::cuts::light_cut::LightCut::spread_average`]), exactly 1 for a cluster
    /// evaluated at `mu` alone.
    pub ring_cos: Option<&'a [[f32; LANES]]>,
}

/// The fragment-constant part of the GGX conductor's sum ([`ggx`]).
#[derive(Clone, Copy)]
pub(crate) struct GgxFragment {
    /// Barycentric weights of the corners.
    pub b: [f32; 3],
    /// Unit shading normal.
    pub n: Vec3,
    /// Unit direction towards the eye, `n . v > 0`.
    pub v: Vec3,
    /// `alpha^2`, at least `MIN_ALPHA^2`.
    pub a2: f32,
}

/// `sum_k power_k (b . vis_k) F_k` for the GGX conductor of `Material::eval` without its
/// fragment-constant factors (the caller's `TriangleCut::ggx_sum`), where `F_k` is
/// [`ggx_term`] at the cluster's direction `mu_k`, or with the spread the five-point rule's
/// mean of it over `mu_k` and `mu_k cos theta_p +- sin theta_p s_k`, `+- sin theta_p t_k`
/// (`s_k, t_k` the `relight_sphere::warp::Frame` of `mu_k`, branch-free, so built in the
/// lanes): `LightCut::spread_average`'s directions.
pub(crate) fn ggx(g: &Groups<'_>, f: &GgxFragment) -> Vec3 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA (just checked).
        return unsafe { ggx_avx2(g, f) };
    }
    ggx_body(g, f)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn ggx_avx2(g: &Groups<'_>, f: &GgxFragment) -> Vec3 {
    ggx_body(g, f)
}

#[inline(always)]
fn ggx_body(g: &Groups<'_>, f: &GgxFragment) -> Vec3 {
    let [sum] = spread_sums(g, f.b, |x, y, z| [ggx_term(f, x, y, z)]);
    sum
}

/// The fragment-constant part of the GGX plastic's sums ([`plastic`]).
#[derive(Clone, Copy)]
pub(crate) struct PlasticFragment<'a> {
    /// The conductor's part (the specular lobe's `D G1`).
    pub ggx: GgxFragment,
    /// Relative index of refraction of the coating.
    pub ior: f32,
    /// `t(cos)` of `relight_scene::material::microfacet::PlasticTables`.
    pub transmittance: &'a [f32; TABLE_RES],
}

/// The two sums of the GGX plastic of `Material::eval` without their fragment-constant
/// factors, over the same clusters as [`ggx`]: the specular
/// `sum_k power_k (b . vis_k) F(v . h) G1(w) / s^2` ([`ggx_term`] times the Fresnel
/// reflectance of the coating, `microfacet::fresnel_dielectric`, [`fresnel_ratio`]) over the
/// same five-point rules, and the diffuse `sum_k power_k (b . vis_k) max(0, n . w) t(n . w)`
/// (the table's linear interpolation, `PlasticTables::transmittance`) at each cluster's
/// direction `mu_k` alone (`LightCut::spread_lobes`).
pub(crate) fn plastic(g: &Groups<'_>, f: &PlasticFragment<'_>) -> [Vec3; 2] {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA (just checked).
        return unsafe { plastic_avx2(g, f) };
    }
    plastic_body::<false>(g, f)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn plastic_avx2(g: &Groups<'_>, f: &PlasticFragment<'_>) -> [Vec3; 2] {
    plastic_body::<true>(g, f)
}

/// The plastic's sums; `GATHER` (only from [`plastic_avx2`]) looks the table up with AVX2
/// gathers.
#[inline(always)]
fn plastic_body<const GATHER: bool>(g: &Groups<'_>, f: &PlasticFragment<'_>) -> [Vec3; 2] {
    let (gf, eta) = (&f.ggx, f.ior);
    let n = gf.n;
    debug_assert!(
        eta > 1.0,
        "a plastic's coating has ior > 1 (Material::validate)"
    );
    let e1 = eta * eta - 1.0;
    let [spec] = spread_sums(g, gf.b, |x, y, z| {
        let g = ggx_ratio(gf, x, y, z);
        // The coating's Fresnel reflectance at `cos_i = v . h / |h|`: for unit `v` and `w`,
        // `v . h = 1 + v . w = |h|^2 / 2`, so `cos_i^2 = |h|^2 / 4`.
        let [num, den] = fresnel_ratio(0.25 * g.hh, e1);
        // The GGX term and the reflectance over one division ([`ggx_ratio`]).
        let y = g.num * num / (g.den * den);
        [if g.lit { y } else { 0.0 }]
    });
    // The diffuse lobe at each cluster's direction alone, spread or not
    // (`LightCut::spread_lobes`): `n . w`, then `max(0, n . w) t(n . w)` over the lanes (the
    // table's lookup, a gather).
    let t = f.transmittance;
    let diff = groups_sum_post(
        g,
        gf.b,
        |x, y, z| n.x * x + n.y * y + n.z * z,
        |co| cos_transmittance::<GATHER>(t, co),
    );
    [spec, diff]
}

/// The unpolarised Fresnel reflectance of a dielectric, `microfacet::fresnel_dielectric`,
/// at `c = cos_i >= 0` from outside (`eta > 1`, no total internal reflection) as `[num, den]`
/// with one square root and no division (the caller shares its division), from `c^2` and
/// `e1 = eta^2 - 1`. With `g = eta cos_t = sqrt(eta^2 - 1 + c^2)`, `rs = (c - g) / (c + g)`
/// and `(g - c)(g + c) = eta^2 - 1` give `rs^2 = e1^2 / Q^2`, `Q = (g + c)^2 = e1 + 2 c^2 +
/// 2 g c` (a sum of non-negative terms: no cancellation), and `rp^2 = rs^2 X^2` with
/// `X = (g c + c^2 - 1) / (g c - c^2 + 1)` (Cook and Torrance 1982's form), so
/// `F = e1^2 (N^2 + D^2) / (2 Q^2 D^2)`, `D = g c - c^2 + 1 >= 1 - c^2 + g c > 0`; only
/// `g c = sqrt(c^2 (e1 + c^2))` needs a root.
#[inline(always)]
fn fresnel_ratio(c2: f32, e1: f32) -> [f32; 2] {
    let gc = (c2 * (e1 + c2)).sqrt();
    let q = e1 + 2.0 * (c2 + gc);
    let (nn, dd) = (gc + c2 - 1.0, gc - c2 + 1.0);
    [e1 * e1 * (nn * nn + dd * dd), 2.0 * (q * q) * (dd * dd)]
}

/// `max(0, c) t(c)` for each cosine `c` of `co`, `t(c)` the linear interpolation of the
/// table `t` of `relight_scene::material::microfacet::PlasticTables::transmittance` (the
/// same arithmetic as its lookup, in the lanes). With `GATHER` (AVX2 builds only) its two
/// reads are AVX2 gathers, which the vectoriser does not emit on its own; the results are
/// the same bits.
#[inline(always)]
fn cos_transmittance<const GATHER: bool>(t: &[f32; TABLE_RES], co: &mut [f32; LANES]) {
    #[cfg(target_arch = "x86_64")]
    if GATHER {
        // SAFETY: `GATHER` is set only by `plastic_avx2`, run after the CPU's check.
        unsafe { cos_transmittance_avx2(t, co) };
        return;
    }
    for c in co.iter_mut() {
        let fi = c.clamp(0.0, 1.0) * (TABLE_RES - 1) as f32;
        let i = (fi as i32).clamp(0, TABLE_RES as i32 - 2) as usize;
        let w = fi - i as f32;
        let tc = t[i] * (1.0 - w) + t[i + 1] * w;
        *c = if *c > 0.0 { *c * tc } else { 0.0 };
    }
}

/// [`cos_transmittance`] over AVX2: the same operations in the same order (no fused
/// multiply-add), the table read by two gathers of in-range indices.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn cos_transmittance_avx2(t: &[f32; TABLE_RES], co: &mut [f32; LANES]) {
    use std::arch::x86_64::*;
    const _: () = assert!(LANES == 8);
    // SAFETY: `co` holds 8 floats; every gathered index is clamped to `0..=TABLE_RES - 2`,
    // so both reads (`i` and `i + 1`) stay inside `t`.
    unsafe {
        let c = _mm256_loadu_ps(co.as_ptr());
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        // `clamp(0, 1)` as `f32::clamp` (no NaN reaches it: unit directions).
        let fi = _mm256_mul_ps(
            _mm256_min_ps(_mm256_max_ps(c, zero), one),
            _mm256_set1_ps((TABLE_RES - 1) as f32),
        );
        let i = _mm256_min_epi32(
            _mm256_max_epi32(_mm256_cvttps_epi32(fi), _mm256_setzero_si256()),
            _mm256_set1_epi32(TABLE_RES as i32 - 2),
        );
        let w = _mm256_sub_ps(fi, _mm256_cvtepi32_ps(i));
        let t0 = _mm256_i32gather_ps::<4>(t.as_ptr(), i);
        let t1 = _mm256_i32gather_ps::<4>(t.as_ptr().add(1), i);
        let tc = _mm256_add_ps(
            _mm256_mul_ps(t0, _mm256_sub_ps(one, w)),
            _mm256_mul_ps(t1, w),
        );
        let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(c, zero);
        let y = _mm256_and_ps(_mm256_mul_ps(c, tc), positive);
        _mm256_storeu_ps(co.as_mut_ptr(), y);
    }
}

/// `G1(w) / s^2` of unit direction `w = (x, y, z)` (`h = v + w`),
/// `0` unless `n . w > 0` and `n . h > 0`: `c^2 = (n . h)^2 / |h|^2`,
/// `s = (1 - c^2) / a^2 + c^2` (`D = 1 / (pi a^2 s^2)`) and
/// `G1(w) = 2 / (1 + sqrt(1 + a^2 (1 - c_w^2) / c_w^2))`, `c_w = n . w` (height-separable
/// Smith, `relight_scene::material::microfacet`). Computed with one division and one square
/// root (the five of the definition dominated the lanes): with `t = |h|^2 - (n . h)^2
/// (1 - a^2) = a^2 |h|^2 s` and `q = c_w^2 + a^2 max(0, 1 - c_w^2) = c_w^2 (1 + tan^2)`,
/// `G1(w) = 2 c_w / (c_w + sqrt q)` and `G1 / s^2 = 2 c_w a^4 |h|^4 / ((c_w + sqrt q) t^2)`.
#[inline(always)]
fn ggx_term(f: &GgxFragment, x: f32, y: f32, z: f32) -> f32 {
    let g = ggx_ratio(f, x, y, z);
    let y = g.num / g.den;
    if g.lit {
        y
    } else {
        0.0
    }
}

/// [`ggx_term`] before its division and its mask ([`ggx_ratio`]).
struct GgxRatio {
    /// `2 c_w a^4 |h|^4`.
    num: f32,
    /// `(c_w + sqrt q) t^2`.
    den: f32,
    /// `|h|^2`.
    hh: f32,
    /// Whether the term counts: `n . w > 0` and `n . h > 0`.
    lit: bool,
}

/// [`ggx_term`]'s ratio, undivided, so that a caller multiplying it by another ratio
/// divides once (the plastic's Fresnel), with `|h|^2` and the mask.
#[inline(always)]
fn ggx_ratio(f: &GgxFragment, x: f32, y: f32, z: f32) -> GgxRatio {
    let (n, v, a2) = (f.n, f.v, f.a2);
    let h = [v.x + x, v.y + y, v.z + z];
    let hn = n.x * h[0] + n.y * h[1] + n.z * h[2];
    let hh = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
    let co = n.x * x + n.y * y + n.z * z;
    let co2 = co * co;
    let t = hh - hn * hn * (1.0 - a2);
    let q = co2 + a2 * (1.0 - co2).max(0.0);
    let a2hh = a2 * hh;
    GgxRatio {
        num: 2.0 * co * a2hh * a2hh,
        den: (co + q.sqrt()) * (t * t),
        hh,
        lit: co > 0.0 && hn > 0.0,
    }
}

/// `sum_k power_k (b . vis_k) term_k` for each of the `K` outputs of `term` (a function of a
/// unit direction), `term_k` at the cluster's direction or, where `g.ring_cos` is given, the
/// five-point rule's mean ([`ggx`]).
#[inline(always)]
fn spread_sums<const K: usize>(
    g: &Groups<'_>,
    b: [f32; 3],
    term: impl Fn(f32, f32, f32) -> [f32; K],
) -> [Vec3; K] {
    match g.ring_cos {
        None => groups_sum::<false, K>(g, &[], b, term),
        Some(c) => groups_sum::<true, K>(g, c, b, term),
    }
}

/// The four directions of the five-point rule around unit `mu = (mx, my, mz)` at
/// `cos theta_p = c` ([`relight_bake::cuts::light_cut::LightCut::spread_average`]):
/// `relight_sphere::warp::Frame::from_normal(mu)` (branch-free), then
/// `mu c +- s sin theta_p`, `mu c +- t sin theta_p`.
#[inline(always)]
fn ring(mx: f32, my: f32, mz: f32, c: f32) -> [(f32, f32, f32); 4] {
    let sn = (1.0 - c * c).max(0.0).sqrt();
    let sign = 1.0f32.copysign(mz);
    let a = -1.0 / (sign + mz);
    let bb = mx * my * a;
    let (sx, sy, sz) = (1.0 + sign * mx * mx * a, sign * bb, -sign * mx);
    let (tx, ty, tz) = (bb, sign + my * my * a, -my);
    let (cx, cy, cz) = (mx * c, my * c, mz * c);
    let (px, py, pz) = (sx * sn, sy * sn, sz * sn);
    let (qx, qy, qz) = (tx * sn, ty * sn, tz * sn);
    [
        (cx + px, cy + py, cz + pz),
        (cx - px, cy - py, cz - pz),
        (cx + qx, cy + qy, cz + qz),
        (cx - qx, cy - qy, cz - qz),
    ]
}

/// `term` at the four directions of the five-point rule around `mu` ([`ring`]). Indexed, not
/// `array::map`, whose closure is not inlined into the AVX2 build (6x slower frames).
#[inline(always)]
fn ring_terms<const K: usize>(
    term: &impl Fn(f32, f32, f32) -> [f32; K],
    mx: f32,
    my: f32,
    mz: f32,
    c: f32,
) -> [[f32; K]; 4] {
    let d = ring(mx, my, mz, c);
    [
        term(d[0].0, d[0].1, d[0].2),
        term(d[1].0, d[1].1, d[1].2),
        term(d[2].0, d[2].1, d[2].2),
        term(d[3].0, d[3].1, d[3].2),
    ]
}

/// `acc[k][ch] += power[ch] x[k]` over the lanes of group `i`.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn add_group<const K: usize>(
    acc: &mut [[[f32; LANES]; 3]; K],
    g: &Groups<'_>,
    i: usize,
    x: &[[f32; LANES]; K],
) {
    for k in 0..K {
        for ch in 0..3 {
            let p = &g.power[ch][i];
            for l in 0..LANES {
                acc[k][ch][l] += p[l] * x[k][l];
            }
        }
    }
}

// Indexed loops over parallel arrays: the shape the vectoriser handles.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn groups_sum<const SPREAD: bool, const K: usize>(
    g: &Groups<'_>,
    ring_cos: &[[f32; LANES]],
    b: [f32; 3],
    term: impl Fn(f32, f32, f32) -> [f32; K],
) -> [Vec3; K] {
    let groups = g.dir[0].len();
    let mut acc = [[[0.0f32; LANES]; 3]; K];
    for i in 0..groups {
        let (dx, dy, dz) = (&g.dir[0][i], &g.dir[1][i], &g.dir[2][i]);
        let (v0, v1, v2) = (&g.vis[0][i], &g.vis[1][i], &g.vis[2][i]);
        let rc = if SPREAD { &ring_cos[i] } else { &[1.0; LANES] };
        let mut x = [[0.0f32; LANES]; K];
        for l in 0..LANES {
            let (mx, my, mz) = (dx[l], dy[l], dz[l]);
            let mut y = term(mx, my, mz);
            if SPREAD {
                let c = rc[l];
                let r = ring_terms(&term, mx, my, mz, c);
                // One evaluation where the rule is off (`c == 1`: the ring is `mu` itself).
                for k in 0..K {
                    let ring = r[0][k] + r[1][k] + r[2][k] + r[3][k];
                    y[k] = if c < 1.0 { (y[k] + ring) * 0.2 } else { y[k] };
                }
            }
            let vis = b[0] * v0[l] + b[1] * v1[l] + b[2] * v2[l];
            for k in 0..K {
                x[k][l] = vis * y[k];
            }
        }
        add_group(&mut acc, g, i, &x);
    }
    acc.map(|a| Vec3::from_array(a.map(|a| a.iter().sum())))
}

/// `sum_k power_k (b . vis_k) post(term)_k` with `term` (one output) at each cluster's
/// direction alone and `post` applied to its lanes between evaluation and sum: two loops over
/// the lanes per group, so that a `post` the vectoriser cannot handle itself (the plastic's
/// table lookup, gathered explicitly) stays out of the first.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn groups_sum_post(
    g: &Groups<'_>,
    b: [f32; 3],
    term: impl Fn(f32, f32, f32) -> f32,
    post: impl Fn(&mut [f32; LANES]),
) -> Vec3 {
    let groups = g.dir[0].len();
    let mut acc = [[[0.0f32; LANES]; 3]; 1];
    for i in 0..groups {
        let (dx, dy, dz) = (&g.dir[0][i], &g.dir[1][i], &g.dir[2][i]);
        let (v0, v1, v2) = (&g.vis[0][i], &g.vis[1][i], &g.vis[2][i]);
        let mut y = [0.0f32; LANES];
        for l in 0..LANES {
            y[l] = term(dx[l], dy[l], dz[l]);
        }
        post(&mut y);
        let mut x = [[0.0f32; LANES]; 1];
        for l in 0..LANES {
            x[0][l] = (b[0] * v0[l] + b[1] * v1[l] + b[2] * v2[l]) * y[l];
        }
        add_group(&mut acc, g, i, &x);
    }
    Vec3::from_array(acc[0].map(|a| a.iter().sum()))
}

/// One triangle's merged clusters of the local-light bounce (`crate::shade_local`): each a
/// cluster of surface samples at its luminance-weighted position.
pub(crate) struct PointGroups<'a> {
    /// `|C'_k| <l>_k`, per colour channel.
    pub power: [&'a [[f32; LANES]]; 3],
    /// `<g_j>_k` of the corners `j`.
    pub vis: [&'a [[f32; LANES]]; 3],
    /// The cluster's position, per axis.
    pub pos: [&'a [[f32; LANES]]; 3],
}

/// `sum_k power_k (b . vis_k) max(0, n . w_k)` with `w_k` the unit direction from `x` to
/// cluster `k`'s position (no term where it is `x` itself): the local bounce's Lambert sum
/// over binary-visibility cuts without its `albedo / pi` (`crate::shade_local`).
pub(crate) fn lambert_points(g: &PointGroups<'_>, b: [f32; 3], n: Vec3, x: Vec3) -> Vec3 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has AVX2 and FMA (just checked).
        return unsafe { lambert_points_avx2(g, b, n, x) };
    }
    lambert_points_body(g, b, n, x)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn lambert_points_avx2(g: &PointGroups<'_>, b: [f32; 3], n: Vec3, x: Vec3) -> Vec3 {
    lambert_points_body(g, b, n, x)
}

#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn lambert_points_body(g: &PointGroups<'_>, b: [f32; 3], n: Vec3, x: Vec3) -> Vec3 {
    let groups = g.pos[0].len();
    let mut acc = [[0.0f32; LANES]; 3];
    for i in 0..groups {
        let (px, py, pz) = (&g.pos[0][i], &g.pos[1][i], &g.pos[2][i]);
        let (v0, v1, v2) = (&g.vis[0][i], &g.vis[1][i], &g.vis[2][i]);
        let mut y = [0.0f32; LANES];
        for l in 0..LANES {
            let (dx, dy, dz) = (px[l] - x.x, py[l] - x.y, pz[l] - x.z);
            let d2 = dx * dx + dy * dy + dz * dz;
            let c = (n.x * dx + n.y * dy + n.z * dz) / d2.sqrt();
            let c = if d2 > 0.0 && c > 0.0 { c } else { 0.0 };
            y[l] = (b[0] * v0[l] + b[1] * v1[l] + b[2] * v2[l]) * c;
        }
        for ch in 0..3 {
            let p = &g.power[ch][i];
            for l in 0..LANES {
                acc[ch][l] += p[l] * y[l];
            }
        }
    }
    Vec3::from_array(acc.map(|a| a.iter().sum()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::material::microfacet::PlasticTables;

    /// One array of lane groups per channel or axis.
    type Planes = [Vec<[f32; LANES]>; 3];

    /// Three groups of clusters with directions all over the sphere (some below the
    /// horizon), visibility in `[0, 1]` and rule angles from none to wide: power, visibility,
    /// direction, `cos theta_p`.
    fn data() -> (Planes, Planes, Planes, Vec<[f32; LANES]>) {
        let mut rng = 0x2545_f491_u32;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 17;
            rng ^= rng << 5;
            rng as f32 / u32::MAX as f32
        };
        let groups = 3;
        let fill = |f: &mut dyn FnMut() -> f32| {
            (0..groups)
                .map(|_| [0.0; LANES].map(|_| f()))
                .collect::<Vec<_>>()
        };
        let power = [(); 3].map(|_| fill(&mut || next() * 4.0));
        let vis = [(); 3].map(|_| fill(&mut &mut next));
        let mut dir: Planes = [(); 3].map(|_| vec![[0.0; LANES]; groups]);
        for (i, l) in (0..groups).flat_map(|i| (0..LANES).map(move |l| (i, l))) {
            let w = relight_sphere::warp::square_to_uniform_sphere(glam::Vec2::new(next(), next()));
            dir.iter_mut()
                .zip(w.to_array())
                .for_each(|(d, x)| d[i][l] = x);
        }
        let ring = fill(&mut || {
            let u = next();
            if u < 0.3 {
                1.0
            } else {
                1.0 - u
            }
        });
        (power, vis, dir, ring)
    }

    /// [`fresnel_ratio`] is `microfacet::fresnel_dielectric` up to f32 rounding, from normal
    /// to grazing incidence and over the coating indices `Material::validate` takes.
    #[test]
    fn one_root_fresnel_is_fresnel_dielectric() {
        use relight_scene::material::microfacet::fresnel_dielectric;
        for eta in [1.01f32, 1.1, 1.33, 1.5, 2.0, 2.5, 4.0] {
            for i in 0..=1000 {
                let c = i as f32 / 1000.0;
                let [num, den] = fresnel_ratio(c * c, eta * eta - 1.0);
                let (fast, slow) = (num / den, fresnel_dielectric(c, eta));
                assert!(
                    (fast - slow).abs() <= 2e-6 + 1e-5 * slow,
                    "eta {eta}, cos {c}: {fast} against {slow}"
                );
            }
        }
    }

    /// The AVX2 build gives the portable build's bits (Rust fuses no multiply-add itself).
    #[test]
    fn avx2_lanes_equal_the_portable_lanes_conductor_and_plastic() {
        #[cfg(target_arch = "x86_64")]
        {
            if !(std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")) {
                println!("skipped: this CPU has no AVX2 + FMA");
                return;
            }
            let (power, vis, dir, ring) = data();
            let f = GgxFragment {
                b: [0.2, 0.5, 0.3],
                n: Vec3::new(0.3, 0.9, 0.1).normalize(),
                v: Vec3::new(-0.2, 0.7, 0.6).normalize(),
                a2: 0.04,
            };
            for spread in [false, true] {
                let g = Groups {
                    power: power.each_ref().map(|x| x.as_slice()),
                    vis: vis.each_ref().map(|x| x.as_slice()),
                    dir: dir.each_ref().map(|x| x.as_slice()),
                    ring_cos: spread.then_some(ring.as_slice()),
                };
                // SAFETY: AVX2 and FMA checked above.
                let fast = unsafe { ggx_avx2(&g, &f) };
                assert_eq!(fast, ggx_body(&g, &f), "spread {spread}");
                assert!(fast.min_element() > 0.0, "{fast}");
                let tables = PlasticTables::get(0.2, 1.5);
                let p = PlasticFragment {
                    ggx: f,
                    ior: 1.5,
                    transmittance: &tables.external_transmittance,
                };
                // SAFETY: as above.
                let fast = unsafe { plastic_avx2(&g, &p) };
                assert_eq!(
                    fast,
                    plastic_body::<false>(&g, &p),
                    "plastic, spread {spread}"
                );
                assert!(fast[0].min_element() > 0.0 && fast[1].min_element() > 0.0);
            }
        }
    }
}
