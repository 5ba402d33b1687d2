//! AVX2 + FMA kernel for single-channel SH relighting, chosen at run time
//! (`is_x86_feature_detected!`) by `shade_sh::vertex_radiance`.
//!
//! Per vertex, `n^2` transfer floats are read 8 at a time and multiplied into three
//! zero-padded light planes (red, green, blue) with fused multiply-adds, then each 8-lane
//! accumulator is summed horizontally. The loads of the last 8-float group run past the
//! vertex's own `n^2` floats into the next vertex's, where they meet the planes' zero padding:
//! they add `0 * t = 0` (transfer is finite: `ShTransfer::validate`). A vertex whose padded
//! read would leave its work slice falls back to the portable kernel.

use glam::{Vec3, Vec3A};
use std::arch::x86_64::*;

/// The light as three channel planes, each zero-padded to a multiple of 8 floats.
pub(super) struct Planes {
    r: Vec<f32>,
    g: Vec<f32>,
    b: Vec<f32>,
    groups: usize,
}

impl Planes {
    /// Planes of the first `light.len()` coefficients.
    pub(super) fn new(light: &[Vec3]) -> Self {
        let groups = light.len().div_ceil(8);
        let plane = |c: usize| {
            let mut p: Vec<f32> = light.iter().map(|l| l[c]).collect();
            p.resize(8 * groups, 0.0);
            p
        };
        Planes {
            r: plane(0),
            g: plane(1),
            b: plane(2),
            groups,
        }
    }

    /// Floats read per vertex (the padded length).
    pub(super) fn padded_len(&self) -> usize {
        8 * self.groups
    }
}

/// Whether this CPU runs the kernel.
pub(super) fn available() -> bool {
    is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn hsum(x: __m256) -> f32 {
    let s = _mm_add_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps::<1>(x));
    let s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    let s = _mm_add_ss(s, _mm_shuffle_ps::<0b01>(s, s));
    _mm_cvtss_f32(s)
}

/// `sum_i t_i L_i` (RGB) for the vertex whose transfer starts at `t`, reading
/// `planes.padded_len()` floats.
///
/// # Safety
/// `t` must point to at least `planes.padded_len()` readable, finite floats, and the CPU must
/// support AVX2 and FMA ([`available`]).
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn dot(t: *const f32, planes: &Planes) -> Vec3A {
    let (mut r, mut g, mut b) = (
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
        _mm256_setzero_ps(),
    );
    for k in 0..planes.groups {
        // SAFETY: k < groups, so 8k + 8 <= padded_len, within `t` (caller) and the planes.
        unsafe {
            let x = _mm256_loadu_ps(t.add(8 * k));
            r = _mm256_fmadd_ps(x, _mm256_loadu_ps(planes.r.as_ptr().add(8 * k)), r);
            g = _mm256_fmadd_ps(x, _mm256_loadu_ps(planes.g.as_ptr().add(8 * k)), g);
            b = _mm256_fmadd_ps(x, _mm256_loadu_ps(planes.b.as_ptr().add(8 * k)), b);
        }
    }
    Vec3A::new(hsum(r), hsum(g), hsum(b))
}

/// Shade the vertices of one work slice: `data` holds `out.len()` vertices of `stride`
/// floats, `albedo` (if any) one value per vertex; `portable(t)` shades a vertex whose padded
/// read would leave `data`.
///
/// # Safety
/// The CPU must support AVX2 and FMA ([`available`]); `data` must be finite.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn shade_slice(
    data: &[f32],
    stride: usize,
    planes: &Planes,
    albedo: Option<&[Vec3]>,
    out: &mut [Vec3],
    portable: impl Fn(&[f32]) -> Vec3A,
) {
    debug_assert_eq!(data.len(), out.len() * stride);
    let need = planes.padded_len();
    for (v, o) in out.iter_mut().enumerate() {
        let base = v * stride;
        let sum = if base + need <= data.len() {
            // SAFETY: `need` floats from `base` are inside `data`; the CPU check is the
            // caller's (this function's own contract).
            unsafe { dot(data.as_ptr().add(base), planes) }
        } else {
            portable(&data[base..base + stride])
        };
        let rho = albedo.map_or(Vec3::ONE, |a| a[v]);
        *o = rho * Vec3::from(sum);
    }
}
