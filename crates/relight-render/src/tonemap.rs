//! Tone mapping of linear radiance to 8-bit sRGB.
//!
//! Conventions: input is linear Rec. 709 radiance (f32, any non-negative value); a [`ToneMap`]
//! maps each channel independently to display-linear `[0, 1]`; the sRGB opto-electronic
//! transfer function ([`srgb_oetf`], IEC 61966-2-1) then encodes it, and [`to_u8`] quantises
//! with round-to-nearest. Every PNG relight writes goes through [`ToneMap::to_srgb8`], so the
//! tone map named in a report fully defines its pixels. Negative and NaN inputs map to 0.
//!
//! # Automatic exposure
//! A PNG written without a user's tone map is exposed by [`ToneMap::auto`], the one rule that
//! `relight render`, `relight reference`, the demo and the viewer's initial exposure share:
//! the frame's log-average luminance (Reinhard et al. 2002, "Photographic Tone Reproduction
//! for Digital Images", eq. 1) is mapped to the key [`KEY`] = 0.18, the paper's middle grey
//! (eq. 2), and the scaled radiance goes through the paper's global operator `L / (1 + L)`
//! (eq. 3, per channel, [`ToneMap::Reinhard`]). The operator rather than a clip: exposed for
//! the log-average and clipped, the path-traced frames of the example scenes have up to 21 %
//! of their lit pixels clipped (`examples/sg_spot.json` 21 %, `sg_teapot_dawn.json` 12 %,
//! `sky_spheres.json` 0.9 %); through `L / (1 + L)` none is clipped and none is black, and the
//! sky with a sun reads as well. Scaling the radiance leaves the picture unchanged.

use crate::image::Image;
use glam::Vec3;

/// A per-channel tone curve from linear radiance to display-linear `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ToneMap {
    /// `y = clamp(exposure * c, 0, 1)`: radiance `1 / exposure` is display white.
    Linear {
        /// Linear multiplier applied before clamping (1 = identity).
        exposure: f32,
    },
    /// Reinhard et al. 2002 global operator per channel: `x = exposure * c`, `y = x / (1 + x)`.
    Reinhard {
        /// Linear multiplier applied before the curve.
        exposure: f32,
    },
    /// The thesis' exponential map (ch. 4.4): `y = 1 - exp(-gamma * c)`; `gamma` is the
    /// user-controlled exposure.
    Exponential {
        /// Exposure `gamma` (> 0).
        gamma: f32,
    },
}

impl Default for ToneMap {
    /// `Linear { exposure: 1 }`.
    fn default() -> Self {
        ToneMap::Linear { exposure: 1.0 }
    }
}

/// The key of [`ToneMap::auto`]: the log-average luminance of a frame is displayed as this
/// value before the curve (Reinhard et al. 2002, eq. 2; 0.18 is the paper's "normal key",
/// middle grey).
pub const KEY: f32 = 0.18;

/// The log-average ("geometric mean") luminance of the lit pixels of `img`, Reinhard et al.
/// 2002 eq. 1: `exp(mean(log(delta + L)))` over the pixels whose Rec. 709 luminance `L` is
/// finite and positive. Black pixels (a frame's background, an object in full shadow),
/// negative, NaN and infinite ones are left out: the exposure is that of what the camera sees
/// lit. `delta` is `1e-4` times the pixels' arithmetic mean luminance, so that scaling the
/// image scales the result by the same factor (the paper's `delta` is an absolute small
/// number, which would not be scale-invariant), and so that a few pixels with tiny but
/// positive values cannot drag the mean of logs down without bound. `None` when no pixel is
/// lit.
pub fn log_average_luminance(img: &Image) -> Option<f32> {
    let lit = || {
        img.pixels
            .iter()
            .map(|&c| crate::compare::luminance(c))
            .filter(|l| l.is_finite() && *l > 0.0)
            .map(f64::from)
    };
    let (sum, n) = lit().fold((0.0f64, 0usize), |(s, n), l| (s + l, n + 1));
    if n == 0 || !sum.is_finite() {
        return None;
    }
    let delta = 1e-4 * sum / n as f64;
    let mean_log = lit().map(|l| (delta + l).ln()).sum::<f64>() / n as f64;
    let avg = mean_log.exp() as f32;
    (avg.is_finite() && avg > 0.0).then_some(avg)
}

/// The automatic exposure of an image and what it was computed from ([`ToneMap::auto`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoExposure {
    /// The log-average luminance of the lit pixels (`None`: no pixel is lit).
    pub log_average: Option<f32>,
    /// The tone map: Reinhard's `L / (1 + L)` of the radiance times `KEY / log_average`.
    pub tonemap: ToneMap,
}

impl AutoExposure {
    /// The automatic exposure of `img`.
    pub fn of(img: &Image) -> AutoExposure {
        let log_average = log_average_luminance(img);
        AutoExposure {
            log_average,
            tonemap: ToneMap::Reinhard {
                exposure: log_average.map_or(1.0, |avg| KEY / avg),
            },
        }
    }
}

impl std::fmt::Display for AutoExposure {
    /// `reinhard:5.29 (automatic exposure: key 0.18 over log-average luminance 0.034)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.log_average {
            Some(avg) => write!(
                f,
                "{} (automatic exposure: key {KEY} over log-average luminance {})",
                self.tonemap,
                significant(avg, 3)
            ),
            None => write!(f, "{} (automatic exposure: no pixel is lit)", self.tonemap),
        }
    }
}

/// A tone map that does not parse: the text and what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("tone map '{text}': {problem} (linear[:EXPOSURE], reinhard[:EXPOSURE], exp[:GAMMA])")]
pub struct ToneMapParseError {
    /// The text given.
    pub text: String,
    /// What is wrong with it.
    pub problem: String,
}

impl std::str::FromStr for ToneMap {
    type Err = ToneMapParseError;

    /// `linear[:EXPOSURE]`, `reinhard[:EXPOSURE]`, `exp[:GAMMA]` (the thesis'
    /// `1 - exp(-gamma c)`); the number is finite and positive, default 1.
    fn from_str(s: &str) -> Result<ToneMap, ToneMapParseError> {
        let err = |problem: String| ToneMapParseError {
            text: s.into(),
            problem,
        };
        let (name, val) = s.split_once(':').map_or((s, None), |(n, v)| (n, Some(v)));
        let v = match val {
            Some(v) => v
                .parse::<f32>()
                .ok()
                .filter(|x| x.is_finite() && *x > 0.0)
                .ok_or_else(|| err(format!("'{v}' is not a positive number")))?,
            None => 1.0,
        };
        Ok(match name {
            "linear" => ToneMap::Linear { exposure: v },
            "reinhard" => ToneMap::Reinhard { exposure: v },
            "exp" | "exponential" => ToneMap::Exponential { gamma: v },
            _ => return Err(err(format!("unknown tone map '{name}'"))),
        })
    }
}

impl ToneMap {
    /// The automatic exposure of `img` (see the module docs): [`ToneMap::Reinhard`] with
    /// exposure `KEY / L_avg`, `L_avg` the [`log_average_luminance`]; `Reinhard { exposure: 1 }`
    /// for an image with no lit pixel.
    pub fn auto(img: &Image) -> ToneMap {
        AutoExposure::of(img).tonemap
    }

    /// This tone map with its exposure (or `gamma`) multiplied by `gain`: the viewer's
    /// exposure control, `2^EV` times the automatic exposure.
    pub fn with_gain(self, gain: f32) -> ToneMap {
        match self {
            ToneMap::Linear { exposure } => ToneMap::Linear {
                exposure: exposure * gain,
            },
            ToneMap::Reinhard { exposure } => ToneMap::Reinhard {
                exposure: exposure * gain,
            },
            ToneMap::Exponential { gamma } => ToneMap::Exponential {
                gamma: gamma * gain,
            },
        }
    }

    /// Map one linear channel value to display-linear `[0, 1]` (monotone non-decreasing in `c`).
    #[inline]
    pub fn map(&self, c: f32) -> f32 {
        // `max` also turns NaN into 0.
        let c = c.max(0.0);
        let y = match *self {
            ToneMap::Linear { exposure } => exposure * c,
            ToneMap::Reinhard { exposure } => {
                let x = exposure * c;
                if x.is_infinite() {
                    1.0
                } else {
                    x / (1.0 + x)
                }
            }
            ToneMap::Exponential { gamma } => 1.0 - (-gamma * c).exp(),
        };
        y.clamp(0.0, 1.0)
    }

    /// Map an RGB value channel by channel.
    #[inline]
    pub fn map_rgb(&self, c: Vec3) -> Vec3 {
        Vec3::new(self.map(c.x), self.map(c.y), self.map(c.z))
    }

    /// Tone map and sRGB-encode one pixel to 8 bits per channel.
    #[inline]
    pub fn pixel_srgb8(&self, c: Vec3) -> [u8; 3] {
        let m = self.map_rgb(c);
        [
            to_u8(srgb_oetf(m.x)),
            to_u8(srgb_oetf(m.y)),
            to_u8(srgb_oetf(m.z)),
        ]
    }

    /// Tone map and sRGB-encode a whole image (row-major, row 0 at the top, as [`Image`]).
    pub fn to_srgb8(&self, img: &Image) -> Vec<[u8; 3]> {
        img.pixels.iter().map(|&c| self.pixel_srgb8(c)).collect()
    }
}

impl std::fmt::Display for ToneMap {
    /// The text `--tonemap` parses back to this tone map (`reinhard:5.23`), to 4 significant
    /// figures.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (name, v) = match *self {
            ToneMap::Linear { exposure } => ("linear", exposure),
            ToneMap::Reinhard { exposure } => ("reinhard", exposure),
            ToneMap::Exponential { gamma } => ("exp", gamma),
        };
        write!(f, "{name}:{}", significant(v, 4))
    }
}

/// `v` rounded to `digits` significant figures, printed without trailing zeros.
fn significant(v: f32, digits: i32) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    let decimals = (digits - 1 - mag).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Fractions of an 8-bit picture's pixels that are clipped (some channel at 255) and black
/// (every channel at most 2, below what a display shows apart from black), among the pixels
/// where `mask` is set (all of them when `mask` is `None`): how much of a picture is
/// unreadable. `(0, 0)` for an empty selection.
pub fn clipped_and_black(px: &[[u8; 3]], mask: Option<&[bool]>) -> (f64, f64) {
    let (mut n, mut clipped, mut black) = (0usize, 0usize, 0usize);
    for (i, p) in px.iter().enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        n += 1;
        clipped += usize::from(p.contains(&255));
        black += usize::from(p.iter().all(|&c| c <= 2));
    }
    if n == 0 {
        return (0.0, 0.0);
    }
    (clipped as f64 / n as f64, black as f64 / n as f64)
}

/// The sRGB OETF (IEC 61966-2-1): `12.92 x` for `x <= 0.0031308`, else
/// `1.055 x^(1/2.4) - 0.055`; input clamped to `[0, 1]`.
#[inline]
pub fn srgb_oetf(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse of [`srgb_oetf`] (the sRGB EOTF), for reading 8-bit images back to linear.
#[inline]
pub fn srgb_eotf(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Quantise `[0, 1]` to 8 bits, round to nearest (out-of-range values clamp).
#[inline]
pub fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAPS: [ToneMap; 3] = [
        ToneMap::Linear { exposure: 0.7 },
        ToneMap::Reinhard { exposure: 2.0 },
        ToneMap::Exponential { gamma: 1.5 },
    ];

    #[test]
    fn tone_maps_are_monotone_and_bounded() {
        for tm in MAPS {
            let mut prev = -1.0f32;
            for i in 0..2000 {
                let c = i as f32 * 0.01;
                let y = tm.map(c);
                assert!((0.0..=1.0).contains(&y), "{tm:?} {c} -> {y}");
                assert!(y >= prev, "{tm:?} not monotone at {c}");
                prev = y;
            }
            assert_eq!(tm.map(0.0), 0.0);
            assert_eq!(tm.map(-3.0), 0.0);
            assert_eq!(tm.map(f32::NAN), 0.0);
            assert!(tm.map(f32::INFINITY) <= 1.0);
        }
    }

    #[test]
    fn exponential_matches_thesis_formula() {
        let gamma = 0.8f32;
        let tm = ToneMap::Exponential { gamma };
        for &c in &[0.0f32, 0.1, 0.5, 1.0, 3.0, 10.0] {
            // 1e-6: f32 rounding of exp near 1.
            assert!((tm.map(c) - (1.0 - (-gamma * c).exp())).abs() < 1e-6);
        }
    }

    #[test]
    fn linear_and_reinhard_match_their_formulas() {
        assert_eq!(ToneMap::Linear { exposure: 2.0 }.map(0.25), 0.5);
        assert_eq!(ToneMap::Linear { exposure: 2.0 }.map(0.75), 1.0);
        assert!((ToneMap::Reinhard { exposure: 1.0 }.map(1.0) - 0.5).abs() < 1e-7);
    }

    #[test]
    fn srgb_round_trips_and_hits_known_codes() {
        for i in 0..=100 {
            let x = i as f32 / 100.0;
            // 1e-5: f32 powf round trip.
            assert!((srgb_eotf(srgb_oetf(x)) - x).abs() < 1e-5);
        }
        // Display-linear 0.5 is sRGB code 188 (0.7354 * 255 = 187.5 -> 188).
        assert_eq!(to_u8(srgb_oetf(0.5)), 188);
        assert_eq!(
            ToneMap::default().pixel_srgb8(Vec3::new(0.0, 1.0, 5.0)),
            [0, 255, 255]
        );
        // Monotone over the 8-bit encoding too.
        let mut prev = 0u8;
        for i in 0..=1000 {
            let v = to_u8(srgb_oetf(i as f32 / 1000.0));
            assert!(v >= prev);
            prev = v;
        }
    }

    fn image(pixels: Vec<Vec3>) -> Image {
        Image {
            width: pixels.len(),
            height: 1,
            pixels,
        }
    }

    #[test]
    fn log_average_is_the_geometric_mean_of_the_lit_pixels() {
        // Half the pixels at luminance a, half at b: eq. 1 is sqrt(a b) up to delta, which is
        // 1e-4 of the arithmetic mean (a + b) / 2 and moves each log by at most
        // delta / min(a, b) = 1e-4 * 50.5 / 1 = 5.05e-3 relative: 6e-3 bounds it.
        let (a, b) = (1.0f32, 100.0f32);
        let mut px = vec![Vec3::splat(a); 50];
        px.extend(vec![Vec3::splat(b); 50]);
        let avg = log_average_luminance(&image(px.clone())).unwrap();
        assert!((avg / (a * b).sqrt() - 1.0).abs() < 6e-3, "{avg}");
        // Black, negative, NaN and infinite pixels are left out, whatever their number.
        let mut dirty = px.clone();
        dirty.extend(vec![Vec3::ZERO; 500]);
        dirty.extend([
            Vec3::splat(f32::NAN),
            Vec3::splat(-4.0),
            Vec3::new(f32::INFINITY, 0.0, 0.0),
        ]);
        assert_eq!(log_average_luminance(&image(dirty)), Some(avg));
        // Nothing lit: no average, and the automatic map is the unit Reinhard curve.
        let dark = image(vec![Vec3::ZERO, Vec3::splat(f32::NAN)]);
        assert_eq!(log_average_luminance(&dark), None);
        assert_eq!(ToneMap::auto(&dark), ToneMap::Reinhard { exposure: 1.0 });
        // Tiny positive pixels cannot drag the average without bound: delta floors each log
        // at ln(1e-4 * 50.5), so one pixel in 101 at 1e-30 lowers the mean log by at most
        // (ln 10 - ln 5.05e-3) / 101 = 0.075, a factor 1.078 (without delta: 0.68, a factor 2).
        let mut tiny = px;
        tiny.push(Vec3::splat(1e-30));
        let t = log_average_luminance(&image(tiny)).unwrap();
        assert!(t < avg && t > avg / 1.12, "{t} against {avg}");
    }

    #[test]
    fn a_constant_image_is_displayed_at_the_key() {
        for c in [1e-3f32, 0.18, 1.0, 250.0] {
            let img = image(vec![Vec3::splat(c); 16]);
            let tm = ToneMap::auto(&img);
            // Scaled to the key (eq. 2), then L / (1 + L) (eq. 3); 2e-4: delta is 1e-4 of the
            // mean, plus f32 rounding.
            let want = KEY / (1.0 + KEY);
            assert!((tm.map(c) - want).abs() < 2e-4 * want, "{c}: {}", tm.map(c));
        }
    }

    #[test]
    fn scaling_the_radiance_leaves_the_picture_unchanged() {
        // A sky-like frame: a ramp over five decades, black background, one sun glint.
        let mut px: Vec<Vec3> = (0..400)
            .map(|i| {
                let l = 10f32.powf(i as f32 / 80.0 - 2.0);
                Vec3::new(l, 0.8 * l, 0.6 * l)
            })
            .collect();
        px.extend(vec![Vec3::ZERO; 200]);
        px.push(Vec3::splat(5e4));
        let img = image(px);
        let base = ToneMap::auto(&img).to_srgb8(&img);
        for k in [1e-3f32, 0.37, 64.0, 1e3] {
            let scaled = image(img.pixels.iter().map(|&c| c * k).collect());
            let px = ToneMap::auto(&scaled).to_srgb8(&scaled);
            // The exposure scales by 1/k exactly up to f32 rounding of the sums and products
            // (relative 1e-6), which can move a value across a rounding boundary of the 8-bit
            // code: at most one code.
            for (a, b) in base.iter().zip(&px) {
                for ch in 0..3 {
                    assert!(a[ch].abs_diff(b[ch]) <= 1, "x{k}: {a:?} {b:?}");
                }
            }
        }
    }

    #[test]
    fn tone_maps_print_as_they_parse() {
        for tm in MAPS
            .into_iter()
            .chain([ToneMap::Reinhard { exposure: 12.3456 }])
        {
            let back: ToneMap = tm.to_string().parse().unwrap();
            // 4 significant figures.
            let (a, b) = (tm.with_gain(1.0), back);
            assert_eq!(std::mem::discriminant(&a), std::mem::discriminant(&b));
            let ratio = |t: ToneMap| match t {
                ToneMap::Linear { exposure } | ToneMap::Reinhard { exposure } => exposure,
                ToneMap::Exponential { gamma } => gamma,
            };
            assert!((ratio(a) / ratio(b) - 1.0).abs() < 5e-4, "{a} {b}");
        }
        assert_eq!(
            ToneMap::Reinhard { exposure: 12.3456 }.to_string(),
            "reinhard:12.35"
        );
        assert_eq!(
            ToneMap::Linear { exposure: 2.0 }.with_gain(0.5),
            ToneMap::Linear { exposure: 1.0 }
        );
    }

    #[test]
    fn clipped_and_black_fractions_count_the_selected_pixels() {
        let px = [[255, 0, 0], [0, 0, 0], [2, 1, 0], [128, 128, 128]];
        assert_eq!(clipped_and_black(&px, None), (0.25, 0.5));
        let mask = [true, false, false, true];
        assert_eq!(clipped_and_black(&px, Some(&mask)), (0.5, 0.0));
        assert_eq!(clipped_and_black(&px, Some(&[false; 4])), (0.0, 0.0));
    }

    #[test]
    fn tone_maps_parse_or_say_why_not() {
        assert_eq!(
            "exp:2".parse::<ToneMap>().unwrap(),
            ToneMap::Exponential { gamma: 2.0 }
        );
        assert_eq!(
            "linear".parse::<ToneMap>().unwrap(),
            ToneMap::Linear { exposure: 1.0 }
        );
        for bad in ["exp:-1", "exp:inf", "foo", "reinhard:x"] {
            let e = bad.parse::<ToneMap>().unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
