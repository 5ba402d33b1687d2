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
//! * **Lookup** ([`Texture::lookup`]): mesh texture coordinates follow OBJ's convention: `v`
//!   grows upwards, so `(u, v) = (0, 0)` is the bottom-left corner of the image. (The glTF
//!   reader flips its downward `v` on load, so every mesh carries this convention.) A lookup
//!   first moves to glTF's image space `(s, t) = (u, 1 - v)` (`t` grows downwards from the
//!   top row), applies the texture's [`UvTransform`] there (`KHR_texture_transform`,
//!   defined in that space), and reads texel `(x, y)` (from the top-left), whose centre is at
//!   `s = (x + 0.5) / w`, `t = (y + 0.5) / h`. The [`Sampler`] says how: per axis, a texel
//!   index outside the image wraps ([`Wrap::Repeat`], the default), clamps to the edge
//!   ([`Wrap::ClampToEdge`]) or mirrors ([`Wrap::MirroredRepeat`]); magnification is
//!   bilinear between the four nearest texel centres ([`Filter::Linear`], the default) or
//!   the nearest texel ([`Filter::Nearest`]). Minification is bilinear too (no mip-maps).
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

/// What a lookup does with a texel index outside the image, along one axis (glTF's sampler
/// `wrapS` / `wrapT`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// Periodic: index `i` reads `i mod n`.
    #[default]
    Repeat,
    /// Index clamped to `[0, n - 1]`.
    ClampToEdge,
    /// Periodic over `2n`, the second half read backwards.
    MirroredRepeat,
}

impl Wrap {
    /// Index `i` brought into `[0, n)`.
    #[inline]
    fn index(self, i: i64, n: i64) -> i64 {
        match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                if m >= n {
                    2 * n - 1 - m
                } else {
                    m
                }
            }
        }
    }

    /// A continuous texel coordinate moved, without changing the texels it reads, into a
    /// bounded range (so huge coordinates stay exact enough and convert without overflow).
    #[inline]
    fn reduce(self, x: f32, n: usize) -> f32 {
        let n = n as f32;
        match self {
            Wrap::Repeat => x.rem_euclid(n),
            Wrap::ClampToEdge => x.clamp(-1.0, n),
            Wrap::MirroredRepeat => x.rem_euclid(2.0 * n),
        }
    }
}

/// How a lookup between texels is filtered (glTF's sampler `magFilter`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// Bilinear between the four nearest texel centres.
    #[default]
    Linear,
    /// The texel containing the point.
    Nearest,
}

/// How a texture is sampled: wrap per axis and filter (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    /// Wrap along `s` (the image's x).
    pub wrap_s: Wrap,
    /// Wrap along `t` (the image's y, downwards).
    pub wrap_t: Wrap,
    /// Filter (magnification and minification alike).
    pub filter: Filter,
}

/// `KHR_texture_transform` in glTF's image space `(s, t)` (module docs):
/// `(s', t') = T(offset) R(rotation) S(scale) (s, t)` with
/// `R = [[cos r, sin r], [-sin r, cos r]]`, i.e.
/// `s' = offset.x + cos r scale.x s + sin r scale.y t`,
/// `t' = offset.y - sin r scale.x s + cos r scale.y t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// Added last.
    pub offset: Vec2,
    /// Rotation in radians (counter-clockwise in the image as displayed, `t` downwards).
    pub rotation: f32,
    /// Applied first, per axis.
    pub scale: Vec2,
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform {
            offset: Vec2::ZERO,
            rotation: 0.0,
            scale: Vec2::ONE,
        }
    }
}

impl UvTransform {
    /// The transformed image-space coordinates `(s', t')` of `(s, t)`.
    #[inline]
    pub fn apply(&self, st: Vec2) -> Vec2 {
        let (sin, cos) = self.rotation.sin_cos();
        let p = st * self.scale;
        Vec2::new(
            self.offset.x + cos * p.x + sin * p.y,
            self.offset.y - sin * p.x + cos * p.y,
        )
    }
}

/// The encoded image formats [`Texture::decode`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// PNG (8 or 16 bits; grey, RGB, palette, with or without alpha).
    Png,
    /// JPEG (baseline or progressive; grey or colour).
    Jpeg,
}

impl ImageFormat {
    /// The format of encoded bytes from their signature, or a message naming what they are
    /// (KTX2, WebP) or that they are unknown.
    pub fn sniff(bytes: &[u8]) -> Result<ImageFormat, String> {
        if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            Ok(ImageFormat::Png)
        } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Ok(ImageFormat::Jpeg)
        } else if bytes.starts_with(b"\xABKTX 20\xBB") {
            Err("KTX2 image: unsupported (PNG and JPEG are read)".into())
        } else if bytes.len() >= 12 && &bytes[..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
            Err("WebP image: unsupported (PNG and JPEG are read)".into())
        } else {
            Err("not a PNG or JPEG image (unknown signature)".into())
        }
    }
}

/// A texture in memory (see the module docs for its conventions).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    texels: Vec<Vec3>,
    sampler: Sampler,
    transform: Option<UvTransform>,
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
            sampler: Sampler::default(),
            transform: None,
        })
    }

    /// Decode an encoded PNG or JPEG image held in memory (a glTF image), as `encoding` says
    /// (module docs; JPEG is 8-bit like PNG). The size is checked against
    /// [`MAX_TEXTURE_SIDE`] and [`MAX_TEXTURE_PIXELS`] from the header, before any texel is
    /// allocated.
    ///
    /// # Errors
    /// A message naming the problem: unknown or unsupported format, corrupt data, too large.
    pub fn decode(bytes: &[u8], encoding: Encoding) -> Result<Texture, String> {
        let (w, h, texels) = match ImageFormat::sniff(bytes)? {
            ImageFormat::Png => decode_png(bytes, encoding)?,
            ImageFormat::Jpeg => decode_jpeg(bytes, encoding)?,
        };
        Texture::new(w, h, texels)
    }

    /// This texture sampled with `sampler`.
    pub fn with_sampler(mut self, sampler: Sampler) -> Texture {
        self.sampler = sampler;
        self
    }

    /// This texture looked up through `transform` (module docs); `None` for none.
    pub fn with_transform(mut self, transform: Option<UvTransform>) -> Texture {
        self.transform = transform;
        self
    }

    /// The sampler.
    pub fn sampler(&self) -> Sampler {
        self.sampler
    }

    /// The texture-coordinate transform, if any.
    pub fn transform(&self) -> Option<UvTransform> {
        self.transform
    }

    /// The same sampler and transform over texels `f(texel)` (for a map derived from
    /// another, e.g. a roughness channel remapped).
    ///
    /// # Errors
    /// A message when a new texel is not finite and in `[0, 1]`.
    pub fn map_texels(&self, f: impl Fn(Vec3) -> Vec3) -> Result<Texture, String> {
        let t = Texture::new(
            self.width,
            self.height,
            self.texels.iter().map(|&c| f(c)).collect(),
        )?;
        Ok(t.with_sampler(self.sampler).with_transform(self.transform))
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

    /// Texel `(x, y)` from the top-left, coordinates wrapped into the image as the sampler
    /// says.
    #[inline]
    pub fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = self.sampler.wrap_s.index(x, self.width as i64) as usize;
        let y = self.sampler.wrap_t.index(y, self.height as i64) as usize;
        self.texels[y * self.width + x]
    }

    /// Filtered lookup at mesh texture coordinates `uv` (module docs: `v` upwards, then the
    /// transform, wrap and filter). Non-finite coordinates read texel `(0, 0)`.
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Vec3 {
        let st = Vec2::new(uv.x, 1.0 - uv.y);
        let st = self.transform.map_or(st, |t| t.apply(st));
        let (w, h) = (self.width as f32, self.height as f32);
        let Sampler {
            wrap_s,
            wrap_t,
            filter,
        } = self.sampler;
        if filter == Filter::Nearest {
            let (fx, fy) = (st.x * w, st.y * h);
            if !(fx.is_finite() && fy.is_finite()) {
                return self.texels[0];
            }
            let x = wrap_s.reduce(fx, self.width).floor() as i64;
            let y = wrap_t.reduce(fy, self.height).floor() as i64;
            return self.texel(x, y);
        }
        // Continuous texel coordinates whose integer points are texel centres.
        let fx = st.x * w - 0.5;
        let fy = st.y * h - 0.5;
        if !(fx.is_finite() && fy.is_finite()) {
            return self.texels[0];
        }
        // Reduce before taking the fraction, so huge coordinates stay exact enough and
        // never overflow.
        let (fx, fy) = (
            wrap_s.reduce(fx, self.width),
            wrap_t.reduce(fy, self.height),
        );
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
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

/// Read a PNG file (see [`decode_png`]).
fn read_png(path: &Path, encoding: Encoding) -> Result<(usize, usize, Vec<Vec3>), SceneError> {
    let bytes = files::read_file(path, files::MAX_FILE_BYTES, "texture")?;
    decode_png(&bytes, encoding).map_err(|m| {
        if m.contains("exceed the texture limit") {
            SceneError::too_large(path, m)
        } else {
            SceneError::malformed(path, m)
        }
    })
}

/// Decode a PNG: its header's size is checked before the decoder allocates.
fn decode_png(bytes: &[u8], encoding: Encoding) -> Result<(usize, usize, Vec<Vec3>), String> {
    let bad = |e: png::DecodingError| format!("PNG: {e}");
    // The decoder's own allocation cap: the largest accepted image at 16-bit RGBA.
    let limits = png::Limits {
        bytes: MAX_TEXTURE_PIXELS * 8,
    };
    let mut dec = png::Decoder::new_with_limits(std::io::Cursor::new(bytes), limits);
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(bad)?;
    let (w, h) = reader.info().size();
    check_size(w as usize, h as usize)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| "PNG: output buffer size overflows".to_string())?;
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

/// Decode a JPEG (8 bits per channel, grey or colour): its header's size is checked before
/// the decoder allocates.
fn decode_jpeg(bytes: &[u8], encoding: Encoding) -> Result<(usize, usize, Vec<Vec3>), String> {
    use zune_jpeg::zune_core::{
        bytestream::ZCursor, colorspace::ColorSpace, options::DecoderOptions,
    };
    let options = DecoderOptions::default()
        .set_max_width(MAX_TEXTURE_SIDE)
        .set_max_height(MAX_TEXTURE_SIDE)
        .jpeg_set_out_colorspace(ColorSpace::RGB);
    let mut dec = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let bad = |e: zune_jpeg::errors::DecodeErrors| {
        let m = format!("JPEG: {e:?}");
        if m.contains("width") || m.contains("height") {
            format!("{m}: exceeds the texture limit ({MAX_TEXTURE_SIDE} per side)")
        } else {
            m
        }
    };
    dec.decode_headers().map_err(bad)?;
    let (w, h) = dec
        .dimensions()
        .ok_or_else(|| "JPEG: no frame header".to_string())?;
    check_size(w, h)?;
    let rgb = dec.decode().map_err(bad)?;
    if rgb.len() != w * h * 3 {
        return Err(format!(
            "JPEG: decoded {} bytes for a {w} x {h} RGB image",
            rgb.len()
        ));
    }
    let f = |v: u8| {
        let v = v as f32 / 255.0;
        match encoding {
            Encoding::Colour => srgb_to_linear(v),
            Encoding::Data => v,
        }
    };
    let texels = rgb
        .chunks_exact(3)
        .map(|c| Vec3::new(f(c[0]), f(c[1]), f(c[2])))
        .collect();
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
