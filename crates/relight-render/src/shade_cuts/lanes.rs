//! The per-fragment sums of `shade_cuts::triangle` (and of the local-light bounce,
//! `crate::shade_local`) over [`LANES`]-wide groups of merged clusters, written so the
//! compiler vectorises them: plain `f32` arithmetic on `[f32; LANES]` groups, no branch
//! (masks become selects), and one body compiled three times: for the portable target, with
//! AVX2 + FMA, and with AVX-512 (F + VL) as well, chosen at run time ([`Isa`]). The AVX-512
//! build still works on 8-lane (256-bit) groups; what it gains is 32 vector registers
//! instead of 16, so the five-point rule's terms of the glossy sums stay in registers
//! instead of spilling (the plastic's lanes 16 % faster on a Zen 4).
//! Rust never fuses a multiply and an add on its own, so the three builds give the same
//! bits. `RELIGHT_NO_AVX512=1` caps the choice at AVX2 and `RELIGHT_PORTABLE_KERNELS=1` at
//! the portable build (comparisons: `relight bench` as on a CPU without them).
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
/// (`s_k, t_k` the `relight_sphere::warp::Frame` of `mu_k`): `LightCut::spread_average`'s
/// directions. A term needs only `n . w` and `|v + w|^2` ([`ring_terms`]).
pub(crate) fn ggx(g: &Groups<'_>, f: &GgxFragment) -> Vec3 {
    match Isa::detect() {
        // SAFETY: the CPU has the build's features (`Isa::detect`).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { ggx_avx512(g, f) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { ggx_avx2(g, f) },
        _ => ggx_body(g, f),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn ggx_avx512(g: &Groups<'_>, f: &GgxFragment) -> Vec3 {
    ggx_body(g, f)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn ggx_avx2(g: &Groups<'_>, f: &GgxFragment) -> Vec3 {
    ggx_body(g, f)
}

#[inline(always)]
fn ggx_body(g: &Groups<'_>, f: &GgxFragment) -> Vec3 {
    let (a2, nv) = (f.a2, f.n.dot(f.v));
    let [sum] = spread_sums(g, f, |co, hh| [ggx_term(a2, nv, co, hh)]);
    // The terms' constant factor ([`ggx_ratio`]), once.
    sum * (2.0 * a2 * a2)
}

/// The vector build of the lanes this CPU runs (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Isa {
    /// AVX2, FMA, AVX-512F and AVX-512VL.
    Avx512,
    /// AVX2 and FMA.
    Avx2,
    /// The target's baseline.
    Portable,
}

impl Isa {
    /// The widest build this CPU runs, capped for comparisons by the environment:
    /// `RELIGHT_PORTABLE_KERNELS=1` (as `shade_sh`) gives the portable build,
    /// `RELIGHT_NO_AVX512=1` at most AVX2 (the frame of a CPU without AVX-512). Read once.
    #[inline]
    pub(crate) fn detect() -> Isa {
        static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *ISA.get_or_init(|| {
            let set = |name: &str| std::env::var_os(name).is_some_and(|v| v == "1");
            if set("RELIGHT_PORTABLE_KERNELS") {
                return Isa::Portable;
            }
            match Isa::of_cpu() {
                Isa::Avx512 if set("RELIGHT_NO_AVX512") => Isa::Avx2,
                isa => isa,
            }
        })
    }

    /// The widest build this CPU runs (`is_x86_feature_detected!`).
    fn of_cpu() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            use std::is_x86_feature_detected as has;
            if has!("avx2") && has!("fma") {
                return if has!("avx512f") && has!("avx512vl") {
                    Isa::Avx512
                } else {
                    Isa::Avx2
                };
            }
        }
        Isa::Portable
    }
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
    match Isa::detect() {
        // SAFETY: the CPU has the build's features (`Isa::detect`).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { plastic_avx512(g, f) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { plastic_avx2(g, f) },
        _ => plastic_body::<LOOKUP_LOADS>(g, f),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn plastic_avx512(g: &Groups<'_>, f: &PlasticFragment<'_>) -> [Vec3; 2] {
    plastic_body::<LOOKUP_PERMUTE>(g, f)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn plastic_avx2(g: &Groups<'_>, f: &PlasticFragment<'_>) -> [Vec3; 2] {
    plastic_body::<LOOKUP_GATHER>(g, f)
}

/// The plastic's sums; `LOOKUP` says how the transmittance table is read
/// ([`cos_transmittance`]).
#[inline(always)]
fn plastic_body<const LOOKUP: u8>(g: &Groups<'_>, f: &PlasticFragment<'_>) -> [Vec3; 2] {
    let (gf, eta) = (&f.ggx, f.ior);
    debug_assert!(
        eta > 1.0,
        "a plastic's coating has ior > 1 (Material::validate)"
    );
    let e1 = eta * eta - 1.0;
    let (a2, nv) = (gf.a2, gf.n.dot(gf.v));
    let t = f.transmittance;
    let [spec] = spread_sums(g, gf, |co, hh| {
        let g = ggx_ratio(a2, nv, co, hh);
        // The coating's Fresnel reflectance at `cos_i = v . h / |h|`: for unit `v` and
        // `w`, `v . h = 1 + v . w = |h|^2 / 2`, so `cos_i^2 = |h|^2 / 4`.
        let [num, den] = fresnel_ratio(0.25 * g.hh, e1);
        // The GGX term and the reflectance over one division ([`ggx_ratio`]).
        let y = g.num * num / (g.den * den);
        [if g.lit { y } else { 0.0 }]
    });
    // The terms' constant factors ([`ggx_ratio`], [`fresnel_ratio`]), once.
    let spec = spec * (a2 * a2 * e1 * e1);
    // The diffuse lobe at each cluster's direction alone, spread or not
    // (`LightCut::spread_lobes`): `n . w`, then `max(0, n . w) t(n . w)` over the lanes (the
    // table's lookup, a gather). A pass of its own: in the specular pass's loop, its lanes
    // spill (measured slower).
    let n = gf.n;
    let diff = groups_sum_post(
        g,
        gf.b,
        |x, y, z| n.x * x + n.y * y + n.z * z,
        |co| cos_transmittance::<LOOKUP>(t, co),
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
/// `g c = sqrt(c^2 (e1 + c^2))` needs a root. Without the constant factor `e1^2 / 2`
/// (the caller's, once per sum): `F = e1^2 / 2 num / den`.
#[inline(always)]
fn fresnel_ratio(c2: f32, e1: f32) -> [f32; 2] {
    let gc = (c2 * (e1 + c2)).sqrt();
    let q = e1 + 2.0 * (c2 + gc);
    let (nn, dd) = (gc + c2 - 1.0, gc - c2 + 1.0);
    let qd = q * dd;
    [nn * nn + dd * dd, qd * qd]
}

/// How [`cos_transmittance`] reads its table: the portable loop's loads.
const LOOKUP_LOADS: u8 = 0;
/// AVX2 gathers ([`cos_transmittance_avx2`]).
const LOOKUP_GATHER: u8 = 1;
/// AVX-512 two-table permutes ([`cos_transmittance_avx512`]).
const LOOKUP_PERMUTE: u8 = 2;

/// `max(0, c) t(c)` for each cosine `c` of `co`, `t(c)` the linear interpolation of the
/// table `t` of `relight_scene::material::microfacet::PlasticTables::transmittance` (the
/// same arithmetic as its lookup, in the lanes). The vectoriser does not emit the table's
/// reads on its own: with [`LOOKUP_GATHER`] (AVX2 builds) they are gathers, with
/// [`LOOKUP_PERMUTE`] (AVX-512 builds) permutes of the table held in registers (on a Zen 4
/// the gathers were a seventh of the plastic's lanes); the results are the same bits.
#[inline(always)]
fn cos_transmittance<const LOOKUP: u8>(t: &[f32; TABLE_RES], co: &mut [f32; LANES]) {
    #[cfg(target_arch = "x86_64")]
    match LOOKUP {
        // SAFETY: `LOOKUP_GATHER` is set only by `plastic_avx2` and `LOOKUP_PERMUTE` only by
        // `plastic_avx512`, each run after the CPU's check (`Isa::detect`).
        LOOKUP_GATHER => return unsafe { cos_transmittance_avx2(t, co) },
        // SAFETY: as above.
        LOOKUP_PERMUTE => return unsafe { cos_transmittance_avx512(t, co) },
        _ => {}
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
    // SAFETY: every index `read` gets is clamped to `0..=TABLE_RES - 2` (`lerp_x86`), so
    // both gathers (`i` and `i + 1`) stay inside `t`.
    unsafe {
        lerp_x86(co, |i| {
            (
                _mm256_i32gather_ps::<4>(t.as_ptr(), i),
                _mm256_i32gather_ps::<4>(t.as_ptr().add(1), i),
            )
        })
    }
}

/// [`cos_transmittance`] over AVX-512 (F + VL): the table's 64 entries in four registers,
/// `t[i]` and `t[i + 1]` each by two two-register permutes (`vpermt2ps`, indices `i mod 32`)
/// and a blend on `i >= 32`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
fn cos_transmittance_avx512(t: &[f32; TABLE_RES], co: &mut [f32; LANES]) {
    use std::arch::x86_64::*;
    const _: () = assert!(TABLE_RES == 64);
    // SAFETY: `t` holds 64 floats, read as four unaligned registers of 16.
    unsafe {
        let p = t.as_ptr();
        let (t0, t1, t2, t3) = (
            _mm512_loadu_ps(p),
            _mm512_loadu_ps(p.add(16)),
            _mm512_loadu_ps(p.add(32)),
            _mm512_loadu_ps(p.add(48)),
        );
        let read = |i: __m256i| {
            let i = _mm512_zextsi256_si512(i);
            let high = _mm512_cmpge_epi32_mask(i, _mm512_set1_epi32(32));
            let v = _mm512_mask_blend_ps(
                high,
                _mm512_permutex2var_ps(t0, i, t1),
                _mm512_permutex2var_ps(t2, i, t3),
            );
            _mm512_castps512_ps256(v)
        };
        lerp_x86(co, |i| {
            (read(i), read(_mm256_add_epi32(i, _mm256_set1_epi32(1))))
        })
    }
}

/// Eight `i32` and eight `f32` lanes of AVX2 ([`lerp_x86`]).
#[cfg(target_arch = "x86_64")]
type X86I = std::arch::x86_64::__m256i;
#[cfg(target_arch = "x86_64")]
type X86F = std::arch::x86_64::__m256;

/// The lanes of [`cos_transmittance`] over AVX2 with `read(i) = (t[i], t[i + 1])`: the
/// portable loop's operations in its order (no fused multiply-add), each index clamped to
/// `0..=TABLE_RES - 2`. Inlined into its callers, which have the features.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn lerp_x86(co: &mut [f32; LANES], read: impl Fn(X86I) -> (X86F, X86F)) {
    use std::arch::x86_64::*;
    const _: () = assert!(LANES == 8);
    // SAFETY: `co` holds 8 floats; the caller has AVX2.
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
        let (t0, t1) = read(i);
        let tc = _mm256_add_ps(
            _mm256_mul_ps(t0, _mm256_sub_ps(one, w)),
            _mm256_mul_ps(t1, w),
        );
        let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(c, zero);
        let y = _mm256_and_ps(_mm256_mul_ps(c, tc), positive);
        _mm256_storeu_ps(co.as_mut_ptr(), y);
    }
}

/// `G1(w) / s^2` of a unit direction `w` given by `c_w = n . w` and `|h|^2`
/// (`h = v + w`; `nv = n . v`), `0` unless `n . w > 0` and `n . h > 0`:
/// `c^2 = (n . h)^2 / |h|^2`, `s = (1 - c^2) / a^2 + c^2` (`D = 1 / (pi a^2 s^2)`) and
/// `G1(w) = 2 / (1 + sqrt(1 + a^2 (1 - c_w^2) / c_w^2))` (height-separable Smith,
/// `relight_scene::material::microfacet`). Computed with one division and one square root
/// (the five of the definition dominated the lanes): with `t = |h|^2 - (n . h)^2 (1 - a^2)
/// = a^2 |h|^2 s` and `q = c_w^2 + a^2 max(0, 1 - c_w^2) = c_w^2 (1 + tan^2)`,
/// `G1(w) = 2 c_w / (c_w + sqrt q)` and `G1 / s^2 = 2 c_w a^4 |h|^4 / ((c_w + sqrt q) t^2)`,
/// here without its constant factor `2 a^4` (the caller's, once per sum).
#[inline(always)]
fn ggx_term(a2: f32, nv: f32, co: f32, hh: f32) -> f32 {
    let g = ggx_ratio(a2, nv, co, hh);
    let y = g.num / g.den;
    if g.lit {
        y
    } else {
        0.0
    }
}

/// [`ggx_term`] before its division and its mask ([`ggx_ratio`]).
struct GgxRatio {
    /// `c_w |h|^4` (the term's `2 a^4` is the caller's).
    num: f32,
    /// `(c_w + sqrt q) t^2`.
    den: f32,
    /// `|h|^2`.
    hh: f32,
    /// Whether the term counts: `n . w > 0` and `n . h > 0`.
    lit: bool,
}

/// [`ggx_term`]'s ratio, undivided, so that a caller multiplying it by another ratio
/// divides once (the plastic's Fresnel), with `|h|^2` and the mask, from `c_w = n . w` and
/// `|h|^2`: `n . h = n . v + n . w` (a sum of positive terms where the term counts). `|h|^2`
/// is the caller's, from the vector `h` itself: from the dot products (`2 (1 + v . w)`) it
/// cancels at grazing angles, where `h` is short (2 % off at `n . v = 0.01`).
#[inline(always)]
fn ggx_ratio(a2: f32, nv: f32, co: f32, hh: f32) -> GgxRatio {
    let hn = nv + co;
    let co2 = co * co;
    let t = hh - hn * hn * (1.0 - a2);
    let q = co2 + a2 * (1.0 - co2).max(0.0);
    GgxRatio {
        num: co * hh * hh,
        den: (co + q.sqrt()) * (t * t),
        hh,
        lit: co > 0.0 && hn > 0.0,
    }
}

/// `sum_k power_k (b . vis_k) term_k` for each of the `K` outputs of `term` (a function of
/// `n . w` and `|v + w|^2` of a unit direction `w`), `term_k` at the cluster's direction
/// `mu_k` or, where `g.ring_cos` is given, the five-point rule's mean ([`ggx`]).
#[inline(always)]
fn spread_sums<const K: usize>(
    g: &Groups<'_>,
    f: &GgxFragment,
    term: impl Fn(f32, f32) -> [f32; K],
) -> [Vec3; K] {
    match g.ring_cos {
        None => groups_sum::<false, K>(g, &[], f, term),
        Some(c) => groups_sum::<true, K>(g, c, f, term),
    }
}

/// `term` at the four directions of the five-point rule around unit `mu = (mx, my, mz)` at
/// `cos theta_p = c` ([`relight_bake::cuts::light_cut::LightCut::spread_average`]),
/// `w = mu c +- p` and `mu c +- q` with `p = s sin theta_p`, `q = t sin theta_p`, `(s, t)` of
/// `relight_sphere::warp::Frame::from_normal(mu)` (branch-free), given `nm = n . mu`: each
/// `n . w = c nm +- n . p` (or `q`), and `h = u +- p` with `u = v + c mu`. Indexed, not
/// `array::map`, whose closure is not inlined into the AVX2 build (6x slower frames).
#[inline(always)]
fn ring_terms<const K: usize>(
    term: &impl Fn(f32, f32) -> [f32; K],
    f: &GgxFragment,
    (mx, my, mz): (f32, f32, f32),
    nm: f32,
    c: f32,
) -> [[f32; K]; 4] {
    let (n, v) = (f.n, f.v);
    let sn = (1.0 - c * c).max(0.0).sqrt();
    let sign = 1.0f32.copysign(mz);
    let a = -1.0 / (sign + mz);
    let bb = mx * my * a;
    let p = [
        (1.0 + sign * mx * mx * a) * sn,
        sign * bb * sn,
        -sign * mx * sn,
    ];
    let q = [bb * sn, (sign + my * my * a) * sn, -my * sn];
    let u = [v.x + mx * c, v.y + my * c, v.z + mz * c];
    let (np, nq, cn) = (
        n.x * p[0] + n.y * p[1] + n.z * p[2],
        n.x * q[0] + n.y * q[1] + n.z * q[2],
        c * nm,
    );
    // `|u + sign d|^2` for `d = p` or `q`.
    let hh = |d: [f32; 3], sign: f32| {
        let h = [u[0] + sign * d[0], u[1] + sign * d[1], u[2] + sign * d[2]];
        h[0] * h[0] + h[1] * h[1] + h[2] * h[2]
    };
    [
        term(cn + np, hh(p, 1.0)),
        term(cn - np, hh(p, -1.0)),
        term(cn + nq, hh(q, 1.0)),
        term(cn - nq, hh(q, -1.0)),
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

/// [`spread_sums`] for one kind of cluster list.
// Indexed loops over parallel arrays: the shape the vectoriser handles.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn groups_sum<const SPREAD: bool, const K: usize>(
    g: &Groups<'_>,
    ring_cos: &[[f32; LANES]],
    f: &GgxFragment,
    term: impl Fn(f32, f32) -> [f32; K],
) -> [Vec3; K] {
    let (b, n, v) = (f.b, f.n, f.v);
    let groups = g.dir[0].len();
    let mut acc = [[[0.0f32; LANES]; 3]; K];
    for i in 0..groups {
        let (dx, dy, dz) = (&g.dir[0][i], &g.dir[1][i], &g.dir[2][i]);
        let (v0, v1, v2) = (&g.vis[0][i], &g.vis[1][i], &g.vis[2][i]);
        let rc = if SPREAD { &ring_cos[i] } else { &[1.0; LANES] };
        let mut x = [[0.0f32; LANES]; K];
        for l in 0..LANES {
            let (mx, my, mz) = (dx[l], dy[l], dz[l]);
            let nm = n.x * mx + n.y * my + n.z * mz;
            let h = [v.x + mx, v.y + my, v.z + mz];
            let mut y = term(nm, h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
            if SPREAD {
                let c = rc[l];
                let r = ring_terms(&term, f, (mx, my, mz), nm, c);
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
                let e1 = eta * eta - 1.0;
                let [num, den] = fresnel_ratio(c * c, e1);
                let (fast, slow) = (0.5 * e1 * e1 * num / den, fresnel_dielectric(c, eta));
                assert!(
                    (fast - slow).abs() <= 2e-6 + 1e-5 * slow,
                    "eta {eta}, cos {c}: {fast} against {slow}"
                );
            }
        }
    }

    /// The AVX2 and AVX-512 builds give the portable build's bits (Rust fuses no
    /// multiply-add itself).
    #[test]
    fn vector_lanes_equal_the_portable_lanes_conductor_and_plastic() {
        #[cfg(target_arch = "x86_64")]
        {
            let isa = Isa::of_cpu();
            if isa == Isa::Portable {
                relight_testdata::skip_platform("avx2", "this CPU has no AVX2 + FMA");
                return;
            }
            if isa == Isa::Avx2 {
                relight_testdata::skip_platform(
                    "avx512",
                    "the AVX-512 build not checked: this CPU has no AVX-512F + VL",
                );
            }
            let (power, vis, dir, ring) = data();
            let f = GgxFragment {
                b: [0.2, 0.5, 0.3],
                n: Vec3::new(0.3, 0.9, 0.1).normalize(),
                v: Vec3::new(-0.2, 0.7, 0.6).normalize(),
                a2: 0.04,
            };
            let tables = PlasticTables::get(0.2, 1.5);
            let p = PlasticFragment {
                ggx: f,
                ior: 1.5,
                transmittance: &tables.external_transmittance,
            };
            for spread in [false, true] {
                let g = Groups {
                    power: power.each_ref().map(|x| x.as_slice()),
                    vis: vis.each_ref().map(|x| x.as_slice()),
                    dir: dir.each_ref().map(|x| x.as_slice()),
                    ring_cos: spread.then_some(ring.as_slice()),
                };
                let (slow, slow_plastic) = (ggx_body(&g, &f), plastic_body::<LOOKUP_LOADS>(&g, &p));
                assert!(slow.min_element() > 0.0, "{slow}");
                assert!(slow_plastic[0].min_element() > 0.0 && slow_plastic[1].min_element() > 0.0);
                // SAFETY: AVX2 and FMA checked above (`Isa::of_cpu`).
                let fast = unsafe { (ggx_avx2(&g, &f), plastic_avx2(&g, &p)) };
                assert_eq!(fast, (slow, slow_plastic), "AVX2, spread {spread}");
                if isa == Isa::Avx512 {
                    // SAFETY: AVX-512F and VL checked above.
                    let fast = unsafe { (ggx_avx512(&g, &f), plastic_avx512(&g, &p)) };
                    assert_eq!(fast, (slow, slow_plastic), "AVX-512, spread {spread}");
                }
            }
        }
    }
}
