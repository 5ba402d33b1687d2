//! Image comparison: error metrics and error heat maps.
//!
//! Conventions: `a` is the image under test, `b` the reference (ground truth); both are linear
//! radiance of the same size. Luminance is Rec. 709 / sRGB relative luminance
//! `Y = 0.2126 R + 0.7152 G + 0.0722 B`. An optional mask (`true` = compared pixel, one entry per
//! pixel, row-major) restricts every metric to the selected pixels. Sums run in f64.

use crate::image::Image;
use glam::Vec3;

/// Rec. 709 relative luminance of a linear RGB value.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Error statistics of `a` against the reference `b` (see [`metrics`] for definitions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Root mean square error over all selected pixels and the three channels pooled:
    /// `sqrt(mean_{p,c} (a - b)^2)`.
    pub rmse: f64,
    /// Relative RMSE: `rmse / sqrt(mean_{p,c} b^2)` (channels pooled); `inf` when `b` is black
    /// and `a` is not, 0 when both are black.
    pub rel_rmse: f64,
    /// Peak signal-to-noise ratio in dB, `20 log10(peak / rmse)`, with the peak defined as the
    /// largest channel value of the reference over the selected pixels (HDR images have no fixed
    /// white). `inf` for identical images.
    pub psnr: f64,
    /// Mean over selected pixels of `|Y(a) - Y(b)|`: the "mean error" of the thesis' Table 5.1
    /// (absolute pixelwise luminous intensity difference).
    pub mean_abs_lum_err: f64,
    /// Population standard deviation over selected pixels of `|Y(a) - Y(b)|` (Table 5.1's
    /// "standard deviation").
    pub std_abs_lum_err: f64,
    /// Largest absolute per-channel difference over selected pixels.
    pub max_abs: f64,
    /// Number of pixels compared.
    pub pixels: usize,
}

/// Compare `a` against the reference `b`, over the pixels where `mask` is `true` (all pixels
/// when `None`). With no pixel selected every metric is NaN and `pixels` is 0.
///
/// # Panics
/// If the images differ in size or the mask length is not `width * height`.
pub fn metrics(a: &Image, b: &Image, mask: Option<&[bool]>) -> Metrics {
    assert!(
        a.width == b.width && a.height == b.height,
        "image sizes differ: {}x{} vs {}x{}",
        a.width,
        a.height,
        b.width,
        b.height
    );
    if let Some(m) = mask {
        assert_eq!(
            m.len(),
            a.pixels.len(),
            "mask length must be width * height"
        );
    }
    let (mut n, mut se, mut sb2, mut peak, mut max_abs) = (0usize, 0f64, 0f64, 0f64, 0f64);
    let (mut sl, mut sl2) = (0f64, 0f64);
    for (i, (&pa, &pb)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        n += 1;
        for c in 0..3 {
            let d = pa[c] as f64 - pb[c] as f64;
            se += d * d;
            sb2 += pb[c] as f64 * pb[c] as f64;
            max_abs = max_abs.max(d.abs());
        }
        peak = peak.max(pb.max_element() as f64);
        let dl = (luminance(pa) as f64 - luminance(pb) as f64).abs();
        sl += dl;
        sl2 += dl * dl;
    }
    if n == 0 {
        let nan = f64::NAN;
        return Metrics {
            rmse: nan,
            rel_rmse: nan,
            psnr: nan,
            mean_abs_lum_err: nan,
            std_abs_lum_err: nan,
            max_abs: nan,
            pixels: 0,
        };
    }
    let samples = (3 * n) as f64;
    let rmse = (se / samples).sqrt();
    let rms_b = (sb2 / samples).sqrt();
    let rel_rmse = if rmse == 0.0 { 0.0 } else { rmse / rms_b };
    let psnr = if rmse == 0.0 {
        f64::INFINITY
    } else {
        20.0 * (peak / rmse).log10()
    };
    let mean = sl / n as f64;
    let var = (sl2 / n as f64 - mean * mean).max(0.0);
    Metrics {
        rmse,
        rel_rmse,
        psnr,
        mean_abs_lum_err: mean,
        std_abs_lum_err: var.sqrt(),
        max_abs,
        pixels: n,
    }
}

/// The default full scale of [`heatmap`]: a quarter of the reference's mean luminance (at least
/// `1e-6`). An error of this size maps to the top of the ramp; use it for the legend.
pub fn heatmap_scale(b: &Image) -> f32 {
    let mean =
        b.pixels.iter().map(|&c| luminance(c) as f64).sum::<f64>() / b.pixels.len().max(1) as f64;
    (0.25 * mean).max(1e-6) as f32
}

/// Absolute luminance error `|Y(a) - Y(b)|` per pixel, divided by [`heatmap_scale`]`(b)` and
/// mapped through [`error_ramp`]: black-purple = no error, yellow-white = 25 % of the
/// reference's mean luminance or more. One scale per reference, so heat maps of several
/// methods against the same reference are directly comparable. Row-major, row 0 at the top.
pub fn heatmap(a: &Image, b: &Image) -> Vec<[u8; 3]> {
    heatmap_with_scale(a, b, heatmap_scale(b))
}

/// As [`heatmap`] with an explicit full scale (the luminance error shown at the top of the ramp).
///
/// # Panics
/// If the images differ in size; debug builds also if `full_scale <= 0`.
pub fn heatmap_with_scale(a: &Image, b: &Image, full_scale: f32) -> Vec<[u8; 3]> {
    assert!(
        a.width == b.width && a.height == b.height,
        "image sizes differ"
    );
    debug_assert!(full_scale > 0.0, "heat map full scale must be positive");
    let lut = ramp_lut();
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(&pa, &pb)| {
            let t = ((luminance(pa) - luminance(pb)).abs() / full_scale).clamp(0.0, 1.0);
            // NaN compares false in clamp's output path: treat as full error.
            let t = if t.is_nan() { 1.0 } else { t };
            lut[(t * 255.0 + 0.5) as usize]
        })
        .collect()
}

/// The error colour ramp at `t` in `[0, 1]`, 8-bit sRGB.
///
/// Built in CIELAB (D65) so that it is perceptually ordered: lightness `L*` rises linearly
/// from 8 to 96, hue turns from purple (310 deg) through blue, teal and green to yellow
/// (95 deg), chroma grows from 35 to 75 and is reduced where needed to stay inside the sRGB
/// gamut. Equal steps in `t` are therefore near-equal steps in perceived lightness, and the
/// ramp stays readable in greyscale.
pub fn error_ramp(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0) as f64;
    let l = 8.0 + 88.0 * t;
    let hue = (310.0 - 215.0 * t).to_radians();
    let mut chroma = 35.0 + 40.0 * t;
    // Shrink chroma until the colour fits in the sRGB gamut (always true at chroma 0).
    let rgb = loop {
        let rgb = lab_to_linear_srgb(l, chroma * hue.cos(), chroma * hue.sin());
        if rgb.iter().all(|&c| (-1e-9..=1.0 + 1e-9).contains(&c)) || chroma <= 0.0 {
            break rgb;
        }
        chroma -= 0.5;
    };
    rgb.map(|c| crate::tonemap::to_u8(crate::tonemap::srgb_oetf(c as f32)))
}

/// 256-entry table of [`error_ramp`].
fn ramp_lut() -> Vec<[u8; 3]> {
    (0..256).map(|i| error_ramp(i as f32 / 255.0)).collect()
}

/// CIELAB (D65 white) to linear sRGB (unclamped).
fn lab_to_linear_srgb(l: f64, a: f64, b: f64) -> [f64; 3] {
    // CIE 1976 inverse companding.
    let finv = |t: f64| {
        const D: f64 = 6.0 / 29.0;
        if t > D {
            t * t * t
        } else {
            3.0 * D * D * (t - 4.0 / 29.0)
        }
    };
    let fy = (l + 16.0) / 116.0;
    let (x, y, z) = (
        0.950_47 * finv(fy + a / 500.0),
        finv(fy),
        1.088_83 * finv(fy - b / 200.0),
    );
    // XYZ (D65) to linear sRGB primaries.
    [
        3.240_454_2 * x - 1.537_138_5 * y - 0.498_531_4 * z,
        -0.969_266_0 * x + 1.876_010_8 * y + 0.041_556_0 * z,
        0.055_643_4 * x - 0.204_025_9 * y + 1.057_225_2 * z,
    ]
}

/// Test support: assert `fast` equals `slow` pixel by pixel up to f32 rounding, `1e-5` of
/// `slow`'s peak (the same terms summed in another order), and that `slow` is not black;
/// `what` names the case in the failure.
#[cfg(test)]
pub(crate) fn assert_same_up_to_rounding(fast: &Image, slow: &Image, what: &str) {
    let peak = slow
        .pixels
        .iter()
        .map(|p| p.max_element())
        .fold(0.0, f32::max);
    assert!(peak > 0.0, "{what}: a black image");
    for (p, q) in fast.pixels.iter().zip(&slow.pixels) {
        assert!(
            (*p - *q).abs().max_element() <= 1e-5 * peak,
            "{what}: {p} vs {q}"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: usize, h: usize) -> Image {
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                img.set(x, y, Vec3::new(x as f32 * 0.1, y as f32 * 0.2, 0.5));
            }
        }
        img
    }

    #[test]
    fn identical_images_have_zero_error() {
        let a = gradient(8, 5);
        let m = metrics(&a, &a, None);
        assert_eq!(m.rmse, 0.0);
        assert_eq!(m.rel_rmse, 0.0);
        assert_eq!(m.psnr, f64::INFINITY);
        assert_eq!(m.mean_abs_lum_err, 0.0);
        assert_eq!(m.std_abs_lum_err, 0.0);
        assert_eq!(m.max_abs, 0.0);
        assert_eq!(m.pixels, 40);
    }

    #[test]
    fn constant_offset_has_known_metrics() {
        let b = Image {
            width: 4,
            height: 4,
            pixels: vec![Vec3::splat(2.0); 16],
        };
        let a = Image {
            width: 4,
            height: 4,
            pixels: vec![Vec3::new(2.5, 2.5, 2.5); 16],
        };
        let m = metrics(&a, &b, None);
        // 1e-12: exact f64 arithmetic on small binary fractions.
        assert!((m.rmse - 0.5).abs() < 1e-12);
        assert!((m.rel_rmse - 0.25).abs() < 1e-12);
        assert!((m.psnr - 20.0 * (2.0f64 / 0.5).log10()).abs() < 1e-9);
        // Luminance weights sum to 1, so the luminance error is the offset (f32 weights: 1e-6).
        assert!((m.mean_abs_lum_err - 0.5).abs() < 1e-6);
        assert!(m.std_abs_lum_err < 1e-6);
        assert!((m.max_abs - 0.5).abs() < 1e-12);
    }

    #[test]
    fn mask_restricts_the_comparison() {
        let b = Image::new(2, 1);
        let mut a = Image::new(2, 1);
        a.set(1, 0, Vec3::splat(1.0));
        let m = metrics(&a, &b, Some(&[true, false]));
        assert_eq!((m.rmse, m.pixels), (0.0, 1));
        let m = metrics(&a, &b, Some(&[false, true]));
        assert_eq!(m.rmse, 1.0);
        assert_eq!(m.rel_rmse, f64::INFINITY);
        assert!(metrics(&a, &b, Some(&[false, false])).rmse.is_nan());
        // One pixel off by 1 of two: mean |dY| = 0.5, std = 0.5.
        let m = metrics(&a, &b, None);
        assert!((m.mean_abs_lum_err - 0.5).abs() < 1e-6 && (m.std_abs_lum_err - 0.5).abs() < 1e-6);
    }

    #[test]
    fn ramp_is_monotone_in_lightness_and_heatmap_uses_it() {
        let mut prev = -1.0;
        for i in 0..=255 {
            let [r, g, bb] = error_ramp(i as f32 / 255.0);
            let lin = |v: u8| crate::tonemap::srgb_eotf(v as f32 / 255.0);
            let y = luminance(Vec3::new(lin(r), lin(g), lin(bb)));
            // 2e-3: 8-bit quantisation can make neighbouring entries tie or dip very slightly.
            assert!(y >= prev - 2e-3, "ramp luminance dips at {i}");
            prev = y;
        }
        let b = gradient(4, 4);
        let hm = heatmap(&b, &b);
        assert!(hm.iter().all(|&p| p == error_ramp(0.0)));
        let mut a = b.clone();
        a.pixels[3] += Vec3::splat(100.0);
        assert_eq!(heatmap(&a, &b)[3], error_ramp(1.0));
    }
}
