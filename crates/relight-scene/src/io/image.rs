//! Images: Radiance RGBE `.hdr` (read RLE and flat, write RLE), OpenEXR (read any layout the
//! `exr` crate decodes, write float RGB) and 8-bit sRGB PNG (write).
//!
//! Pixels are row-major from the top-left, linear RGB `Vec3`.
//!
//! RGBE decoding follows Ward's Radiance format as implemented by Walter's `rgbe.c` (the
//! reader Mitsuba 3 uses): a texel `(r, g, b, e)` with `e != 0` is `(r, g, b) * 2^(e - 136)`,
//! so relight and Mitsuba see the same values. The `EXPOSURE` header is ignored (as Mitsuba
//! does). Encoding rounds to nearest: relative error at most 2^-8 of the largest channel.
//!
//! # Limits on reading
//! Image files are read through [`super::files`] (regular files of at most 4 GiB). What a
//! header announces is checked before any pixel buffer is allocated:
//! * at most [`MAX_SIDE`] pixels per side and [`MAX_PIXELS`] pixels in all;
//! * at least the bytes the announced size needs in the file's encoding (truncation);
//! * an **expansion limit**: the memory decoding takes (16 bytes per pixel for RGBE: the
//!   4-byte texels and the 12-byte `Vec3`; for OpenEXR the channel samples plus 24 bytes) may
//!   exceed [`FREE_DECODE_BYTES`] (256 MiB) only up to [`MAX_EXPANSION`] (64) times the
//!   file's size. Uncompressed RGBE is 4 bytes per pixel (expansion 4); run-length encoding of
//!   photographs rarely gains a factor of 2 and large flat areas a few more, so real images
//!   stay far below 64, while Radiance's old-style run codes let 232 KB announce a
//!   23170 x 11585 image (4 GB decoded, an expansion of 18000) — refused.
//!
//! relight reads no PNG (it only writes them); a PNG reader would need the same checks.

use super::{extension, read_bytes, write_atomic};
use crate::error::SceneError;
use crate::Vec3;
use std::path::Path;

/// Largest image relight reads: 2^28 pixels (3 GiB as `Vec3`), and at most 65536 per side.
pub const MAX_PIXELS: usize = 1 << 28;
/// Largest side length accepted.
pub const MAX_SIDE: usize = 1 << 16;
/// Decoding memory always allowed, whatever the file's size (256 MiB: a 4096 x 4096 RGBE).
pub const FREE_DECODE_BYTES: u64 = 256 << 20;
/// Largest ratio of decoding memory to file size beyond [`FREE_DECODE_BYTES`] (module docs).
pub const MAX_EXPANSION: u64 = 64;

/// Refuse a `w x h` image whose decoding takes `bytes_per_pixel` per pixel when that is more
/// than [`FREE_DECODE_BYTES`] and more than [`MAX_EXPANSION`] times `file_bytes`.
fn check_expansion(
    path: &Path,
    w: usize,
    h: usize,
    bytes_per_pixel: u64,
    file_bytes: u64,
) -> Result<(), SceneError> {
    let decoded = (w as u64)
        .saturating_mul(h as u64)
        .saturating_mul(bytes_per_pixel);
    if decoded <= FREE_DECODE_BYTES || decoded / MAX_EXPANSION <= file_bytes {
        return Ok(());
    }
    Err(SceneError::too_large(
        path,
        format!(
            "a {w}x{h} image would take {} MiB to decode from a file of {file_bytes} bytes \
             ({}x its size; relight allows {MAX_EXPANSION}x beyond {} MiB): the file is \
             corrupt or a decompression bomb",
            decoded >> 20,
            decoded / file_bytes.max(1),
            FREE_DECODE_BYTES >> 20
        ),
    ))
}

/// Read a `.hdr` or `.exr` image (dispatch on the extension) as `(width, height, pixels)`.
pub fn read_image(path: &Path) -> Result<(usize, usize, Vec<Vec3>), SceneError> {
    match extension(path).as_str() {
        "hdr" | "pic" | "rgbe" => read_hdr(path),
        "exr" => read_exr(path),
        e => Err(SceneError::unsupported(
            path,
            format!("image extension '{e}' (expected hdr or exr)"),
        )),
    }
}

fn check_size(path: &Path, w: usize, h: usize) -> Result<(), SceneError> {
    if w == 0 || h == 0 {
        return Err(SceneError::malformed(
            path,
            format!("image size {w}x{h} is empty"),
        ));
    }
    if w > MAX_SIDE || h > MAX_SIDE || w.saturating_mul(h) > MAX_PIXELS {
        return Err(SceneError::too_large(
            path,
            format!(
                "image size {w}x{h} exceeds the limit ({MAX_SIDE} per side, {MAX_PIXELS} pixels)"
            ),
        ));
    }
    Ok(())
}

// ----------------------------------------------------------------------------------------
// Radiance HDR

/// Read a Radiance RGBE file (new-style RLE, old-style RLE and flat scanlines;
/// `-Y H +X W` and the other non-transposed orientations).
pub fn read_hdr(path: &Path) -> Result<(usize, usize, Vec<Vec3>), SceneError> {
    let bytes = read_bytes(path)?;
    decode_hdr(path, &bytes)
}

fn decode_hdr(path: &Path, bytes: &[u8]) -> Result<(usize, usize, Vec<Vec3>), SceneError> {
    let mut pos = 0usize;
    let mut line_no = 0usize;
    let mut next_line = |pos: &mut usize| -> Option<(usize, String)> {
        if *pos >= bytes.len() {
            return None;
        }
        let rest = &bytes[*pos..];
        let end = rest.iter().position(|&b| b == b'\n')?;
        *pos += end + 1;
        line_no += 1;
        Some((
            line_no,
            String::from_utf8_lossy(&rest[..end])
                .trim_end_matches('\r')
                .to_string(),
        ))
    };
    let (_, magic) = next_line(&mut pos)
        .ok_or_else(|| SceneError::malformed(path, "empty or truncated header"))?;
    if !(magic.starts_with("#?RADIANCE") || magic.starts_with("#?RGBE") || magic.starts_with("#?"))
    {
        return Err(SceneError::malformed_at(
            path,
            1,
            "not a Radiance HDR file (no '#?' signature)",
        ));
    }
    loop {
        let (n, line) = next_line(&mut pos)
            .ok_or_else(|| SceneError::malformed(path, "truncated header (no blank line)"))?;
        if line.is_empty() {
            break;
        }
        if let Some(fmt) = line.strip_prefix("FORMAT=") {
            if fmt.trim() != "32-bit_rle_rgbe" {
                return Err(SceneError::unsupported(
                    path,
                    format!("line {n}: FORMAT={fmt} (only 32-bit_rle_rgbe)"),
                ));
            }
        }
    }
    let (n, res) = next_line(&mut pos)
        .ok_or_else(|| SceneError::malformed(path, "missing resolution line"))?;
    let t: Vec<&str> = res.split_whitespace().collect();
    let bad_res = || SceneError::malformed_at(path, n, format!("bad resolution line '{res}'"));
    if t.len() != 4 {
        return Err(bad_res());
    }
    let (flip_y, flip_x) = match (t[0], t[2]) {
        ("-Y", "+X") => (false, false),
        ("+Y", "+X") => (true, false),
        ("-Y", "-X") => (false, true),
        ("+Y", "-X") => (true, true),
        _ => {
            return Err(SceneError::unsupported(
                path,
                format!("line {n}: orientation '{res}' (transposed images)"),
            ))
        }
    };
    let h: usize = t[1].parse().map_err(|_| bad_res())?;
    let w: usize = t[3].parse().map_err(|_| bad_res())?;
    check_size(path, w, h)?;
    // A new-style RLE scanline takes at least 4 + 4 * 2 * ceil(w / 127) bytes; flat data with
    // old-style run codes at least 4 bytes per 255 * 128 pixels. A file too small for its
    // announced size is refused before allocating.
    let rle = (8..0x8000).contains(&w) && bytes[pos..].starts_with(&[2, 2]);
    let per_line = if rle {
        4 + 8 * w.div_ceil(127)
    } else {
        4 * w.div_ceil(128 * 255)
    };
    let min_bytes = h.saturating_mul(per_line);
    if bytes.len() - pos < min_bytes {
        return Err(SceneError::malformed(
            path,
            format!(
                "truncated: {w}x{h} needs more than {} bytes of pixels",
                bytes.len() - pos
            ),
        ));
    }
    // RGBE texels + Vec3 pixels.
    check_expansion(path, w, h, 4 + 12, bytes.len() as u64)?;
    let mut rgbe = vec![[0u8; 4]; w * h];
    let data = &bytes[pos..];
    let mut cur = 0usize;
    for y in 0..h {
        let row = &mut rgbe[y * w..(y + 1) * w];
        cur = decode_scanline(data, cur, row)
            .map_err(|m| SceneError::malformed(path, format!("scanline {y}: {m}")))?;
    }
    let mut px = vec![Vec3::ZERO; w * h];
    for y in 0..h {
        for x in 0..w {
            let sy = if flip_y { h - 1 - y } else { y };
            let sx = if flip_x { w - 1 - x } else { x };
            px[y * w + x] = rgbe_to_rgb(rgbe[sy * w + sx]);
        }
    }
    Ok((w, h, px))
}

/// Decode one scanline starting at `cur`; returns the position after it.
fn decode_scanline(data: &[u8], mut cur: usize, row: &mut [[u8; 4]]) -> Result<usize, String> {
    let w = row.len();
    let take = |cur: usize, n: usize| -> Result<&[u8], String> {
        data.get(cur..cur + n)
            .ok_or_else(|| "truncated pixel data".to_string())
    };
    let head = take(cur, 4)?;
    if (8..0x8000).contains(&w) && head[0] == 2 && head[1] == 2 && head[2] & 0x80 == 0 {
        // New-style RLE: four channel planes, each a sequence of runs and dumps.
        let len = ((head[2] as usize) << 8) | head[3] as usize;
        if len != w {
            return Err(format!("RLE length {len} does not match width {w}"));
        }
        cur += 4;
        for c in 0..4 {
            let mut x = 0;
            while x < w {
                let code = *take(cur, 1)?.first().ok_or("truncated")? as usize;
                cur += 1;
                if code > 128 {
                    let n = code - 128;
                    let v = take(cur, 1)?[0];
                    cur += 1;
                    if x + n > w {
                        return Err("RLE run overruns the scanline".into());
                    }
                    row[x..x + n].iter_mut().for_each(|p| p[c] = v);
                    x += n;
                } else {
                    let n = code;
                    if n == 0 || x + n > w {
                        return Err("bad RLE dump length".into());
                    }
                    let src = take(cur, n)?;
                    cur += n;
                    for (p, &v) in row[x..x + n].iter_mut().zip(src) {
                        p[c] = v;
                    }
                    x += n;
                }
            }
        }
        return Ok(cur);
    }
    // Flat pixels, possibly with old-style run codes (1, 1, 1, count) repeating the previous.
    let mut x = 0;
    let mut shift = 0u32;
    while x < w {
        let p = take(cur, 4)?;
        cur += 4;
        if p[0] == 1 && p[1] == 1 && p[2] == 1 {
            if x == 0 {
                return Err("old-style run at the start of a scanline".into());
            }
            let n = (p[3] as usize).checked_shl(shift).unwrap_or(usize::MAX);
            if n > w - x {
                return Err("old-style run overruns the scanline".into());
            }
            let prev = row[x - 1];
            row[x..x + n].iter_mut().for_each(|q| *q = prev);
            x += n;
            shift += 8;
        } else {
            row[x] = [p[0], p[1], p[2], p[3]];
            x += 1;
            shift = 0;
        }
    }
    Ok(cur)
}

/// RGBE texel to linear RGB (Walter's `rgbe2float`, as Mitsuba).
pub fn rgbe_to_rgb(p: [u8; 4]) -> Vec3 {
    if p[3] == 0 {
        return Vec3::ZERO;
    }
    let f = (2.0f64).powi(p[3] as i32 - 136) as f32;
    Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) * f
}

/// Linear RGB to RGBE, rounding to nearest (negatives and NaN become 0).
pub fn rgb_to_rgbe(c: Vec3) -> [u8; 4] {
    let c = Vec3::new(c.x.max(0.0), c.y.max(0.0), c.z.max(0.0)); // max() maps NaN to 0
    let m = c.max_element();
    if m.is_nan() || m < 1e-32 {
        return [0; 4];
    }
    let m = m.min(f32::MAX) as f64;
    let mut e = m.log2().floor() as i32 + 1; // m in [2^(e-1), 2^e)
    let mut scale = (2.0f64).powi(8 - e);
    if (m * scale + 0.5).floor() >= 256.0 {
        e += 1;
        scale *= 0.5;
    }
    if e + 128 > 255 {
        return [255, 255, 255, 255];
    }
    if e + 128 < 1 {
        return [0; 4];
    }
    let q = |v: f32| ((v as f64 * scale + 0.5).floor()).clamp(0.0, 255.0) as u8;
    [q(c.x), q(c.y), q(c.z), (e + 128) as u8]
}

/// Write a Radiance `.hdr` (new-style RLE scanlines), atomically. RGBE cannot store negative
/// values: they are written as 0; NaN and infinite values are refused.
pub fn write_hdr(path: &Path, w: usize, h: usize, px: &[Vec3]) -> Result<(), SceneError> {
    check_write(path, w, h, px)?;
    let mut out = Vec::with_capacity(w * h * 4 + 128);
    out.extend_from_slice(
        format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n").as_bytes(),
    );
    let mut planes = [vec![0u8; w], vec![0u8; w], vec![0u8; w], vec![0u8; w]];
    for y in 0..h {
        let row: Vec<[u8; 4]> = px[y * w..(y + 1) * w]
            .iter()
            .map(|&c| rgb_to_rgbe(c))
            .collect();
        if !(8..0x8000).contains(&w) {
            row.iter().for_each(|p| out.extend_from_slice(p));
            continue;
        }
        out.extend_from_slice(&[2, 2, (w >> 8) as u8, (w & 0xff) as u8]);
        for c in 0..4 {
            for (x, p) in row.iter().enumerate() {
                planes[c][x] = p[c];
            }
            encode_rle_plane(&planes[c], &mut out);
        }
    }
    write_atomic(path, |tmp| {
        std::fs::write(tmp, &out).map_err(|e| SceneError::io(path, e))
    })
}

/// Encode one channel plane as runs (> 128: repeat) and dumps (<= 128: literal).
fn encode_rle_plane(p: &[u8], out: &mut Vec<u8>) {
    let mut i = 0;
    while i < p.len() {
        let mut run = 1;
        while i + run < p.len() && run < 127 && p[i + run] == p[i] {
            run += 1;
        }
        if run >= 3 {
            out.extend_from_slice(&[128 + run as u8, p[i]]);
            i += run;
            continue;
        }
        // Literal dump up to the next run of 3 (or 128 bytes).
        let start = i;
        while i < p.len() && i - start < 128 {
            if i + 2 < p.len() && p[i] == p[i + 1] && p[i] == p[i + 2] {
                break;
            }
            i += 1;
        }
        out.push((i - start) as u8);
        out.extend_from_slice(&p[start..i]);
    }
}

fn check_write(path: &Path, w: usize, h: usize, px: &[Vec3]) -> Result<(), SceneError> {
    check_size(path, w, h)?;
    if px.len() != w * h {
        return Err(SceneError::malformed(
            path,
            format!("{} pixels given for a {w}x{h} image", px.len()),
        ));
    }
    if let Some(i) = px.iter().position(|c| !c.is_finite()) {
        return Err(SceneError::malformed(
            path,
            format!("pixel (x {}, y {}) is not finite: {}", i % w, i / w, px[i]),
        ));
    }
    Ok(())
}

// ----------------------------------------------------------------------------------------
// OpenEXR

/// Read an OpenEXR file: first valid layer, largest resolution level, scanline or tiled, any
/// compression and sample type the `exr` crate decodes. Channels `R, G, B` (alpha ignored) or
/// a single luminance `Y` (replicated to RGB). Layer prefixes (`name.R`) are accepted.
pub fn read_exr(path: &Path) -> Result<(usize, usize, Vec<Vec3>), SceneError> {
    use exr::prelude::*;
    let fail = |e: exr::error::Error| SceneError::malformed(path, format!("OpenEXR: {e}"));
    // One open, through the regular-file and size checks; then check announced sizes before
    // decoding anything.
    let bytes = read_bytes(path)?;
    let meta = catch(path, || {
        exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes[..]), false)
    })?
    .map_err(fail)?;
    let header = meta
        .headers
        .iter()
        .find(|h| !h.deep)
        .ok_or_else(|| SceneError::unsupported(path, "only deep-data layers"))?;
    let (w, h) = (header.layer_size.0, header.layer_size.1);
    check_size(path, w, h)?;
    // The decoder's samples, relight's f32 planes and Vec3 pixels.
    let sample_bytes: u64 = header
        .channels
        .list
        .iter()
        .map(|c| c.sample_type.bytes_per_sample() as u64)
        .sum();
    check_expansion(path, w, h, sample_bytes + 24, bytes.len() as u64)?;
    if header
        .channels
        .list
        .iter()
        .any(|c| c.sampling != Vec2(1, 1))
    {
        return Err(SceneError::unsupported(
            path,
            "subsampled channels (chroma subsampling)",
        ));
    }
    let image = catch(path, || {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(&bytes[..]))
    })?
    .map_err(fail)?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.0, layer.size.1);
    check_size(path, w, h)?;
    let channels = &layer.channel_data.list;
    let find = |name: &str| {
        channels.iter().find(|c| {
            let s = c.name.to_string();
            s == name || s.rsplit('.').next() == Some(name)
        })
    };
    let to_f32 =
        |c: &AnyChannel<FlatSamples>| -> Vec<f32> { c.sample_data.values_as_f32().collect() };
    let planes: [Vec<f32>; 3] = match (find("R"), find("G"), find("B"), find("Y")) {
        (Some(r), Some(g), Some(b), _) => [to_f32(r), to_f32(g), to_f32(b)],
        (_, _, _, Some(y)) => {
            let y = to_f32(y);
            [y.clone(), y.clone(), y]
        }
        _ => {
            let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
            return Err(SceneError::unsupported(
                path,
                format!("channels {names:?} (need R, G, B or Y)"),
            ));
        }
    };
    if planes.iter().any(|p| p.len() != w * h) {
        return Err(SceneError::malformed(
            path,
            "channel sample count does not match the image size",
        ));
    }
    let px = (0..w * h)
        .map(|i| Vec3::new(planes[0][i], planes[1][i], planes[2][i]))
        .collect();
    Ok((w, h, px))
}

/// Run a decoder, turning a panic inside it into an error (defence in depth: the decoders
/// are third-party code fed with untrusted bytes).
fn catch<T>(path: &Path, f: impl FnOnce() -> T) -> Result<T, SceneError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
        .map_err(|_| SceneError::malformed(path, "OpenEXR decoder failed on corrupt data"))
}

/// Write a float (f32) RGB OpenEXR, atomically. NaN and infinite values are refused.
pub fn write_exr(path: &Path, w: usize, h: usize, px: &[Vec3]) -> Result<(), SceneError> {
    use exr::prelude::*;
    check_write(path, w, h, px)?;
    write_atomic(path, |tmp| {
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let c = px[y * w + x];
            (c.x, c.y, c.z)
        });
        let mut layer = Layer::new(
            (w, h),
            LayerAttributes::default(),
            Encoding::SMALL_LOSSLESS,
            channels,
        );
        layer.encoding.compression = Compression::ZIP16;
        Image::from_layer(layer)
            .write()
            .non_parallel()
            .to_file(tmp)
            .map_err(|e| SceneError::malformed(path, format!("OpenEXR write: {e}")))
    })
}

// ----------------------------------------------------------------------------------------
// PNG

/// Write an 8-bit sRGB PNG (pixels already tone-mapped and sRGB-encoded by the caller; the
/// file carries an `sRGB` chunk), atomically.
pub fn write_png_srgb8(path: &Path, w: usize, h: usize, px: &[[u8; 3]]) -> Result<(), SceneError> {
    check_size(path, w, h)?;
    if px.len() != w * h {
        return Err(SceneError::malformed(
            path,
            format!("{} pixels given for a {w}x{h} image", px.len()),
        ));
    }
    write_atomic(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(|e| SceneError::io(path, e))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w as u32, h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let err = |e: png::EncodingError| SceneError::malformed(path, format!("PNG write: {e}"));
        let mut writer = enc.write_header().map_err(err)?;
        let flat: Vec<u8> = px.iter().flatten().copied().collect();
        writer.write_image_data(&flat).map_err(err)?;
        writer.finish().map_err(err)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_util::temp_dir;

    fn gradient(w: usize, h: usize) -> Vec<Vec3> {
        (0..w * h)
            .map(|i| {
                Vec3::new(
                    (i % w) as f32 * 0.37 + 0.01,
                    (i / w) as f32 * 3.1,
                    1000.0 / (1.0 + i as f32),
                )
            })
            .collect()
    }

    #[test]
    fn hdr_round_trip_within_rgbe_precision() {
        let dir = temp_dir("hdr");
        let (w, h) = (37, 5);
        let mut px = gradient(w, h);
        px[3] = Vec3::splat(2.5); // a run for the RLE encoder
        px[4] = Vec3::splat(2.5);
        px[5] = Vec3::splat(2.5);
        px[6] = Vec3::ZERO;
        let p = dir.join("g.hdr");
        write_hdr(&p, w, h, &px).unwrap();
        let (w2, h2, back) = read_image(&p).unwrap();
        assert_eq!((w2, h2), (w, h));
        for (a, b) in px.iter().zip(&back) {
            // Rounding to nearest with an 8-bit mantissa: error <= 2^-8 of the largest channel.
            let tol = a.max_element() * (1.0 / 256.0) + 1e-30;
            assert!((*a - *b).abs().max_element() <= tol, "{a} vs {b}");
        }
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = temp_dir("exr");
        let (w, h) = (19, 7);
        let px = gradient(w, h);
        let p = dir.join("g.exr");
        write_exr(&p, w, h, &px).unwrap();
        let (w2, h2, back) = read_image(&p).unwrap();
        assert_eq!((w2, h2), (w, h));
        assert_eq!(px, back);
    }

    #[test]
    fn png_writes_a_valid_file() {
        let dir = temp_dir("png");
        let p = dir.join("a.png");
        write_png_srgb8(&p, 2, 1, &[[255, 0, 0], [0, 0, 255]]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(write_png_srgb8(&p, 3, 1, &[[0; 3]]).is_err());
    }

    #[test]
    fn hdr_truncated_is_an_error() {
        let dir = temp_dir("hdrtrunc");
        let p = dir.join("t.hdr");
        write_hdr(&p, 64, 8, &gradient(64, 8)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 50]).unwrap();
        let e = read_image(&p).unwrap_err();
        assert!(
            e.to_string().contains("t.hdr") && e.to_string().contains("truncated"),
            "{e}"
        );
    }

    #[test]
    fn hdr_malformed_header_is_an_error() {
        let dir = temp_dir("hdrbad");
        let p = dir.join("bad.hdr");
        std::fs::write(&p, b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y abc +X 4\n").unwrap();
        let e = read_image(&p).unwrap_err();
        assert!(e.to_string().contains("bad.hdr: line 4"), "{e}");
        std::fs::write(&p, b"P6\n1 1\n255\n").unwrap();
        assert!(read_image(&p).is_err());
    }

    #[test]
    fn hdr_absurd_size_is_refused_before_allocating() {
        let dir = temp_dir("hdrhuge");
        let p = dir.join("huge.hdr");
        std::fs::write(
            &p,
            b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n\x02\x02",
        )
        .unwrap();
        let e = read_image(&p).unwrap_err();
        assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
        // Within the limits but far more than the file holds.
        std::fs::write(
            &p,
            b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 16000 +X 16000\n\x02\x02",
        )
        .unwrap();
        assert!(read_image(&p)
            .unwrap_err()
            .to_string()
            .contains("truncated"));
    }

    /// A Radiance file of old-style run-length scanlines: each row is one texel and two run
    /// codes (1, 1, 1, n) repeating it, the second shifted by 8 bits: 12 bytes per row.
    fn old_rle_hdr(w: usize, h: usize) -> Vec<u8> {
        let n = w - 1;
        assert!(n < 1 << 16);
        let mut b = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n").into_bytes();
        for _ in 0..h {
            b.extend_from_slice(&[128, 128, 128, 129]);
            b.extend_from_slice(&[1, 1, 1, (n & 0xff) as u8]);
            b.extend_from_slice(&[1, 1, 1, (n >> 8) as u8]);
        }
        b
    }

    #[test]
    fn hdr_old_style_rle_bomb_is_refused_by_the_expansion_limit() {
        // 23170 x 11585 = 2^28 pixels (the pixel cap) from 139 KB: 4 GiB to decode.
        let dir = temp_dir("hdrbomb");
        let p = dir.join("bomb.hdr");
        std::fs::write(&p, old_rle_hdr(23170, 11585)).unwrap();
        let e = crate::io::test_util::within_seconds(20, move || read_image(&p).unwrap_err());
        assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
        assert!(
            e.to_string().contains("bomb.hdr") && e.to_string().contains("decode"),
            "{e}"
        );
        // The same encoding at a size within the free allowance decodes.
        let p = dir.join("small.hdr");
        std::fs::write(&p, old_rle_hdr(300, 20)).unwrap();
        let (w, h, px) = read_image(&p).unwrap();
        assert_eq!((w, h), (300, 20));
        assert!(px.iter().all(|c| *c == Vec3::splat(1.0)));
    }

    /// A 4 x 4 EXR in a fresh folder `dir` whose dataWindow (box2i: xMin, yMin, xMax, yMax)
    /// is patched to claim `(max + 1)^2` pixels.
    fn exr_with_data_window(dir: &str, name: &str, max: i32) -> std::path::PathBuf {
        let p = temp_dir(dir).join(name);
        write_exr(&p, 4, 4, &gradient(4, 4)).unwrap();
        let mut bytes = std::fs::read(&p).unwrap();
        let key = b"dataWindow\0box2i\0";
        let at = bytes
            .windows(key.len())
            .position(|w| w == key)
            .expect("dataWindow attribute")
            + key.len()
            + 4;
        bytes[at + 8..at + 12].copy_from_slice(&max.to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&max.to_le_bytes());
        std::fs::write(&p, &bytes).unwrap();
        p
    }

    #[test]
    fn exr_announcing_far_more_pixels_than_it_holds_is_refused_before_decoding() {
        // dataWindow to 16000 x 16000: within the pixel cap, 9 GB to decode from ~400 bytes.
        let p = exr_with_data_window("exrbomb", "bomb.exr", 15_999);
        let e = crate::io::test_util::within_seconds(20, move || read_image(&p).unwrap_err());
        assert!(matches!(e, SceneError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("decode"), "{e}");
    }

    #[test]
    fn exr_malformed_and_truncated_are_errors() {
        let dir = temp_dir("exrbad");
        let p = dir.join("bad.exr");
        std::fs::write(&p, b"not an exr file at all").unwrap();
        assert!(read_image(&p).unwrap_err().to_string().contains("bad.exr"));
        let good = dir.join("good.exr");
        write_exr(&good, 64, 64, &gradient(64, 64)).unwrap();
        let bytes = std::fs::read(&good).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
        let e = read_image(&p).unwrap_err();
        assert!(e.to_string().contains("bad.exr"), "{e}");
    }

    #[test]
    fn missing_image_is_an_io_error() {
        let p = temp_dir("imgmissing").join("gone.exr");
        let e = read_image(&p).unwrap_err();
        assert!(
            matches!(e, SceneError::Io { .. }) && e.to_string().contains("gone.exr"),
            "{e}"
        );
        assert!(matches!(
            read_image(&p.with_extension("hdr")).unwrap_err(),
            SceneError::Io { .. }
        ));
    }

    #[test]
    fn exr_absurd_data_window_is_refused() {
        // dataWindow to 100000 x 100000 pixels.
        let p = exr_with_data_window("exrhuge", "huge.exr", 99_999);
        let e = read_image(&p).unwrap_err();
        assert!(e.to_string().contains("huge.exr"), "{e}");
    }

    #[test]
    fn write_refuses_nan() {
        let p = temp_dir("nan").join("n.exr");
        assert!(write_exr(&p, 1, 1, &[Vec3::NAN]).is_err());
        assert!(write_hdr(&p.with_extension("hdr"), 1, 1, &[Vec3::INFINITY]).is_err());
    }

    #[test]
    fn rgbe_matches_walter_decoding() {
        assert_eq!(rgbe_to_rgb([128, 64, 0, 129]), Vec3::new(1.0, 0.5, 0.0));
        assert_eq!(rgb_to_rgbe(Vec3::new(1.0, 0.5, 0.0)), [128, 64, 0, 129]);
        assert_eq!(rgb_to_rgbe(Vec3::ZERO), [0; 4]);
    }
}
