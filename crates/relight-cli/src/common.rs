//! Helpers shared by the subcommands: image IO by extension, tone-map parsing, progress bars.

use anyhow::{bail, Context, Result};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::io::image as imgio;
use std::path::Path;

/// Parse a tone map: `linear[:EXPOSURE]`, `reinhard[:EXPOSURE]`, `exp[:GAMMA]` (the thesis'
/// `1 - exp(-gamma c)`).
pub fn parse_tonemap(s: &str) -> Result<ToneMap> {
    let (name, val) = match s.split_once(':') {
        Some((n, v)) => (n, Some(v)),
        None => (s, None),
    };
    let v = match val {
        Some(v) => v
            .parse::<f32>()
            .ok()
            .filter(|x| x.is_finite() && *x > 0.0)
            .with_context(|| format!("tone map '{s}': '{v}' is not a positive number"))?,
        None => 1.0,
    };
    Ok(match name {
        "linear" => ToneMap::Linear { exposure: v },
        "reinhard" => ToneMap::Reinhard { exposure: v },
        "exp" | "exponential" => ToneMap::Exponential { gamma: v },
        _ => bail!("unknown tone map '{name}' (linear, reinhard, exp)"),
    })
}

/// Describe a tone map for reports.
pub fn describe_tonemap(t: &ToneMap) -> String {
    match t {
        ToneMap::Linear { exposure } => format!("linear, clamp({exposure} c), then sRGB"),
        ToneMap::Reinhard { exposure } => format!("Reinhard x/(1+x), x = {exposure} c, then sRGB"),
        ToneMap::Exponential { gamma } => {
            format!("exponential 1 - exp(-{gamma} c) (thesis 4.4), then sRGB")
        }
    }
}

/// Write an image by extension: `.exr` (linear float), `.hdr` (linear RGBE), `.png`
/// (tone-mapped sRGB). Writes are atomic.
pub fn write_image(path: &Path, img: &Image, tm: &ToneMap) -> Result<()> {
    let ext = ext_of(path);
    match ext.as_str() {
        "exr" => imgio::write_exr(path, img.width, img.height, &img.pixels)?,
        "hdr" => imgio::write_hdr(path, img.width, img.height, &img.pixels)?,
        "png" => imgio::write_png_srgb8(path, img.width, img.height, &tm.to_srgb8(img))?,
        _ => bail!(
            "{}: unknown image extension '{ext}' (exr, hdr, png)",
            path.display()
        ),
    }
    Ok(())
}

/// Read an `.exr` or `.hdr` image.
pub fn read_image(path: &Path) -> Result<Image> {
    let (w, h, px) = imgio::read_image(path)?;
    Ok(Image {
        width: w,
        height: h,
        pixels: px,
    })
}

/// Lower-case extension of a path ("" when none).
pub fn ext_of(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tonemaps_parse() {
        assert_eq!(
            parse_tonemap("exp:2").unwrap(),
            ToneMap::Exponential { gamma: 2.0 }
        );
        assert_eq!(
            parse_tonemap("linear").unwrap(),
            ToneMap::Linear { exposure: 1.0 }
        );
        assert!(parse_tonemap("exp:-1").is_err());
        assert!(parse_tonemap("foo").is_err());
    }
}
