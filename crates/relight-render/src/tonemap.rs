//! Tone mapping of linear radiance to 8-bit sRGB.
//!
//! Conventions: input is linear Rec. 709 radiance (f32, any non-negative value); a [`ToneMap`]
//! maps each channel independently to display-linear `[0, 1]`; the sRGB opto-electronic
//! transfer function ([`srgb_oetf`], IEC 61966-2-1) then encodes it, and [`to_u8`] quantises
//! with round-to-nearest. Every PNG relight writes goes through [`ToneMap::to_srgb8`], so the
//! tone map named in a report fully defines its pixels. Negative and NaN inputs map to 0.

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
