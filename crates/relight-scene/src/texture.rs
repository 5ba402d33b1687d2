//! Texture images for material maps (Cheslack-Postava et al. 2008, sec. 4.2: per-pixel BRDF
//! parameters read from textures).
//!
//! Conventions, stated once:
//! * **Storage**: linear RGB texels, row-major from the top-left of the image, every channel
//!   finite and in `[0, 1]` (checked when loaded: a texel scales a reflectance, replaces a
//!   roughness or encodes a normal, so nothing outside that range has a meaning).
//! * **Decoding**: PNG colour maps (`diffuse`, `specular`) are sRGB-encoded and decoded with
//!   the exact sRGB curve ([`srgb_to_linear`]); PNG data maps (`roughness`, `normal`) are
//!   read as they are (value / 255 or / 65535). OpenEXR is linear whatever the map. A grey
//!   image gives three equal channels; an alpha channel is ignored.
//! * **Lookup** ([`Texture::lookup`]): bilinear between the four nearest texel centres,
//!   wrapping around every edge (repeat). Texture coordinates follow OBJ's convention: `v`
//!   grows upwards, so `(u, v) = (0, 0)` is the bottom-left corner of the image and texel
//!   `(x, y)` (from the top-left) has its centre at `u = (x + 0.5) / w`,
//!   `v = 1 - (y + 0.5) / h`. (The glTF reader flips its downward `v` on load, so every mesh
//!   carries this convention.)
//!
//! Loading reads through [`crate::io::files`] (regular files, bounded reads) and checks the
//! announced size against [`MAX_TEXTURE_SIDE`] and [`MAX_TEXTURE_PIXELS`] before allocating
//! any texel.

use crate::error::SceneError;
use crate::io::files;
use crate::Vec3;
use glam::Vec2;
use std::path::Path;

/// Largest side of a texture, in texels (16384).
pub const MAX_TEXTURE_SIDE: usize = 1 << 14;
/// Most texels of a texture (2^26 = 64 Mi texels, 768 MiB as linear RGB).
pub const MAX_TEXTURE_PIXELS: usize = 1 << 26;

/// How a texture's stored values become linear values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Colour: PNG is sRGB-decoded, EXR is linear.
    Colour,
    /// Data (roughness, normals): stored values are used as they are.
    Data,
}

/// A texture in memory (see the module docs for its conventions).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    texels: Vec<Vec3>,
}

/// The exact sRGB decoding curve (IEC 61966-2-1): `c / 12.92` up to `0.04045`, then
/// `((c + 0.055) / 1.055)^2.4`.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Texture {
    /// A texture of `width x height` texels (row-major from the top-left).
    ///
    /// # Errors
    /// A message when the size is empty, over the limits, does not match `texels`, or a texel
    /// is not finite and in `[0, 1]` (it names the first bad texel).
    pub fn new(width: usize, height: usize, texels: Vec<Vec3>) -> Result<Texture, String> {
        check_size(width, height)?;
        if texels.len() != width * height {
            return Err(format!(
                "{} texels for a {width} x {height} image",
                texels.len()
            ));
        }
        if let Some(i) = texels
            .iter()
            .position(|t| !(t.cmpge(Vec3::ZERO).all() && t.cmple(Vec3::ONE).all()))
        {
            return Err(format!(
                "texel ({}, {}) is {} (every channel must be finite and in [0, 1])",
                i % width,
                i / width,
                texels[i]
            ));
        }
        Ok(Texture {
            width,
            height,
            texels,
        })
    }

    /// A texture of one colour (1 x 1 texel).
    pub fn constant(c: Vec3) -> Result<Texture, String> {
        Texture::new(1, 1, vec![c])
    }

    /// Read a PNG (8 or 16 bits, grey or RGB, with or without alpha, palette) or OpenEXR
    /// texture, decoded as `encoding` says (module docs). The error names the file and the
    /// problem: missing, not a regular file, another format, too large, corrupt, or a texel
    /// out of range.
    pub fn read(path: &Path, encoding: Encoding) -> Result<Texture, SceneError> {
        let ext = crate::io::extension(path);
        let (w, h, texels) = match ext.as_str() {
            "png" => read_png(path, encoding)?,
            "exr" => read_exr_texture(path)?,
            _ => {
                return Err(SceneError::unsupported(
                    path,
                    format!("texture extension '{ext}' (expected png or exr)"),
                ))
            }
        };
        Texture::new(w, h, texels).map_err(|m| SceneError::malformed(path, m))
    }

    /// Width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Every texel, row-major from the top-left.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// Texel `(x, y)` from the top-left, coordinates wrapped into the image.
    #[inline]
    pub fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = x.rem_euclid(self.width as i64) as usize;
        let y = y.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width + x]
    }

    /// Bilinear lookup at `uv` (module docs: repeat wrap, `v` upwards). Non-finite
    /// coordinates read texel `(0, 0)`.
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Vec3 {
        // Continuous texel coordinates whose integer points are texel centres.
        let fx = uv.x * self.width as f32 - 0.5;
        let fy = (1.0 - uv.y) * self.height as f32 - 0.5;
        if !(fx.is_finite() && fy.is_finite()) {
            return self.texels[0];
        }
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        // Wrap before converting, so huge coordinates stay exact enough and never overflow.
        let (x0, y0) = (
            x0.rem_euclid(self.width as f32) as i64,
            y0.rem_euclid(self.height as f32) as i64,
        );
        let top = self.texel(x0, y0) * (1.0 - tx) + self.texel(x0 + 1, y0) * tx;
        let bottom = self.texel(x0, y0 + 1) * (1.0 - tx) + self.texel(x0 + 1, y0 + 1) * tx;
        top * (1.0 - ty) + bottom * ty
    }
}

fn check_size(w: usize, h: usize) -> Result<(), String> {
    if w == 0 || h == 0 {
        return Err(format!("empty image ({w} x {h})"));
    }
    if w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE || w * h > MAX_TEXTURE_PIXELS {
        return Err(format!(
            "{w} x {h} texels exceed the texture limit ({MAX_TEXTURE_SIDE} per side, {MAX_TEXTURE_PIXELS} in all)"
        ));
    }
    Ok(())
}

/// Decode a PNG: its header's size is checked before the decoder allocates.
fn read_png(path: &Path, encoding: Encoding) -> Result<(usize, usize, Vec<Vec3>), SceneError> {
    let bytes = files::read_file(path, files::MAX_FILE_BYTES, "texture")?;
    let bad = |e: png::DecodingError| SceneError::malformed(path, format!("PNG: {e}"));
    // The decoder's own allocation cap: the largest accepted image at 16-bit RGBA.
    let limits = png::Limits {
        bytes: MAX_TEXTURE_PIXELS * 8,
    };
    let mut dec = png::Decoder::new_with_limits(std::io::Cursor::new(&bytes[..]), limits);
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(bad)?;
    let (w, h) = reader.info().size();
    check_size(w as usize, h as usize).map_err(|m| SceneError::too_large(path, m))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| SceneError::too_large(path, "PNG: output buffer size overflows"))?;
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(bad)?;
    let (w, h) = (frame.width as usize, frame.height as usize);
    let channels = frame.color_type.samples();
    let sixteen = frame.bit_depth == png::BitDepth::Sixteen;
    let sample = |i: usize| -> f32 {
        let v = if sixteen {
            u16::from_be_bytes([buf[2 * i], buf[2 * i + 1]]) as f32 / 65535.0
        } else {
            buf[i] as f32 / 255.0
        };
        match encoding {
            Encoding::Colour => srgb_to_linear(v),
            Encoding::Data => v,
        }
    };
    let stride = frame.line_size / if sixteen { 2 } else { 1 };
    let mut texels = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let i = y * stride + x * channels;
            texels.push(match channels {
                // Grey, grey + alpha.
                1 | 2 => Vec3::splat(sample(i)),
                // RGB, RGBA.
                _ => Vec3::new(sample(i), sample(i + 1), sample(i + 2)),
            });
        }
    }
    Ok((w, h, texels))
}

/// Decode an OpenEXR texture: its header's size is checked against the texture limits before
/// [`crate::io::image::read_exr`] decodes it.
fn read_exr_texture(path: &Path) -> Result<(usize, usize, Vec<Vec3>), SceneError> {
    let bytes = files::read_file(path, files::MAX_FILE_BYTES, "texture")?;
    let meta = std::panic::catch_unwind(|| {
        exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes[..]), false)
    })
    .map_err(|_| SceneError::malformed(path, "OpenEXR decoder failed on corrupt data"))?
    .map_err(|e| SceneError::malformed(path, format!("OpenEXR: {e}")))?;
    for header in &meta.headers {
        let (w, h) = (header.layer_size.0, header.layer_size.1);
        check_size(w, h).map_err(|m| SceneError::too_large(path, m))?;
    }
    crate::io::image::read_exr(path)
}

#[cfg(test)]
pub(crate) mod tests;
