use super::*;
use crate::io::test_util::temp_dir;
use std::path::PathBuf;

/// Write an 8-bit PNG of `channels` (1 grey, 3 RGB) samples per texel.
pub(crate) fn write_png(path: &Path, w: u32, h: u32, channels: usize, data: &[u8]) {
    let file = std::fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(if channels == 1 {
        png::ColorType::Grayscale
    } else {
        png::ColorType::Rgb
    });
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header().unwrap().write_image_data(data).unwrap();
}

/// Write a float RGB OpenEXR without relight's writer (which refuses NaN).
pub(crate) fn write_exr_raw(path: &Path, w: usize, h: usize, px: &[Vec3]) {
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        let p = px[y * w + x];
        (p.x, p.y, p.z)
    })
    .unwrap();
}

#[test]
fn srgb_decode_matches_the_standard_curve() {
    assert_eq!(srgb_to_linear(0.0), 0.0);
    assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
    // Reference values of IEC 61966-2-1 (computed in double precision).
    assert!((srgb_to_linear(0.5) - 0.214_041_14).abs() < 1e-6);
    assert!((srgb_to_linear(0.02) - 0.02 / 12.92).abs() < 1e-9);
    // The two pieces meet at 0.04045 (continuity to 1e-6).
    let (a, b) = (srgb_to_linear(0.040_45), srgb_to_linear(0.040_450_1));
    assert!((a - b).abs() < 1e-6, "{a} {b}");
    // Monotonic over the 8-bit codes.
    for k in 1..=255 {
        assert!(srgb_to_linear(k as f32 / 255.0) > srgb_to_linear((k - 1) as f32 / 255.0));
    }
}

#[test]
fn png_colour_maps_are_srgb_decoded_and_data_maps_are_not() {
    let dir = temp_dir("tex-png");
    let p = dir.join("grey.png");
    write_png(&p, 2, 1, 3, &[128, 64, 255, 0, 10, 200]);
    let c = Texture::read(&p, Encoding::Colour).unwrap();
    let d = Texture::read(&p, Encoding::Data).unwrap();
    let s = |v: u8| srgb_to_linear(v as f32 / 255.0);
    assert_eq!(c.texel(0, 0), Vec3::new(s(128), s(64), s(255)));
    assert_eq!(c.texel(1, 0), Vec3::new(s(0), s(10), s(200)));
    assert_eq!(d.texel(0, 0), Vec3::new(128.0, 64.0, 255.0) / 255.0);
    // Grey PNGs give three equal channels.
    let g = dir.join("g.png");
    write_png(&g, 1, 1, 1, &[51]);
    assert_eq!(
        Texture::read(&g, Encoding::Data).unwrap().texel(0, 0),
        Vec3::splat(0.2)
    );
    // EXR is linear whatever the map.
    let e = dir.join("e.exr");
    write_exr_raw(&e, 1, 1, &[Vec3::new(0.25, 0.5, 0.75)]);
    for enc in [Encoding::Colour, Encoding::Data] {
        assert_eq!(
            Texture::read(&e, enc).unwrap().texel(0, 0),
            Vec3::new(0.25, 0.5, 0.75)
        );
    }
}

/// A 4 x 3 texture of distinct texels.
fn ramp() -> Texture {
    let px = (0..12)
        .map(|i| Vec3::new(i as f32 / 12.0, (i % 4) as f32 / 4.0, (i / 4) as f32 / 3.0))
        .collect();
    Texture::new(4, 3, px).unwrap()
}

#[test]
fn bilinear_lookup_is_exact_at_texel_centres_and_wraps() {
    let t = ramp();
    for y in 0..3 {
        for x in 0..4 {
            // Texel (x, y) from the top-left sits at u = (x + 0.5) / w, v = 1 - (y + 0.5) / h.
            let uv = Vec2::new((x as f32 + 0.5) / 4.0, 1.0 - (y as f32 + 0.5) / 3.0);
            let want = t.texel(x, y);
            assert!((t.lookup(uv) - want).abs().max_element() < 1e-6, "{x} {y}");
            // Repeat: whole periods away, the same texel.
            for (du, dv) in [(1.0, 0.0), (-2.0, 3.0), (5.0, -1.0)] {
                let v = t.lookup(uv + Vec2::new(du, dv));
                assert!((v - want).abs().max_element() < 1e-5, "{x} {y} {du} {dv}");
            }
        }
    }
    // Halfway between two centres: their mean; at the right edge it mixes with column 0.
    let mid = t.lookup(Vec2::new(1.0 / 4.0, 1.0 - 0.5 / 3.0));
    assert!(
        (mid - (t.texel(0, 0) + t.texel(1, 0)) * 0.5)
            .abs()
            .max_element()
            < 1e-6
    );
    let edge = t.lookup(Vec2::new(1.0, 1.0 - 0.5 / 3.0));
    assert!(
        (edge - (t.texel(3, 0) + t.texel(0, 0)) * 0.5)
            .abs()
            .max_element()
            < 1e-6
    );
    // v = 0 is the bottom edge: between the last row and (wrapping) the first.
    let bottom = t.lookup(Vec2::new(0.5 / 4.0, 0.0));
    assert!(
        (bottom - (t.texel(0, 2) + t.texel(0, 0)) * 0.5)
            .abs()
            .max_element()
            < 1e-6
    );
    // Non-finite coordinates read a texel, never panic.
    assert_eq!(t.lookup(Vec2::new(f32::NAN, 0.0)), t.texel(0, 0));
    let _ = t.lookup(Vec2::new(1e30, -1e30));
}

fn err(path: &Path, enc: Encoding) -> String {
    let e = Texture::read(path, enc).unwrap_err().to_string();
    assert!(
        e.contains(&*path.file_name().unwrap().to_string_lossy()),
        "the error names the file: {e}"
    );
    e
}

#[test]
fn bad_texture_files_are_refused_naming_the_file_and_the_problem() {
    let dir = temp_dir("tex-bad");
    let at = |n: &str| -> PathBuf { dir.join(n) };
    // Missing.
    let e = err(&at("missing.png"), Encoding::Colour);
    assert!(e.to_lowercase().contains("no such file"), "{e}");
    // Neither PNG nor EXR.
    std::fs::write(at("t.jpg"), b"\xff\xd8\xff").unwrap();
    let e = err(&at("t.jpg"), Encoding::Colour);
    assert!(e.contains("expected png or exr"), "{e}");
    // Not a PNG inside.
    std::fs::write(at("fake.png"), b"hello, world").unwrap();
    let e = err(&at("fake.png"), Encoding::Colour);
    assert!(e.contains("PNG"), "{e}");
    // NaN, negative and over-one texels (EXR can hold them).
    for (name, v, what) in [
        ("nan.exr", f32::NAN, "NaN"),
        ("neg.exr", -0.5, "-0.5"),
        ("big.exr", 2.0, "2"),
    ] {
        write_exr_raw(&at(name), 2, 1, &[Vec3::splat(0.5), Vec3::new(0.1, v, 0.1)]);
        let e = err(&at(name), Encoding::Data);
        assert!(
            e.contains("texel (1, 0)") && e.contains(what) && e.contains("[0, 1]"),
            "{e}"
        );
    }
    // Oversized: refused from the header, before the texels are allocated.
    let wide = MAX_TEXTURE_SIDE as u32 + 1;
    write_png(&at("wide.png"), wide, 1, 1, &vec![0u8; wide as usize]);
    let e = err(&at("wide.png"), Encoding::Data);
    assert!(e.contains("exceed the texture limit"), "{e}");
    exr::prelude::write_rgb_file(at("wide.exr"), wide as usize, 1, |_, _| (0.0, 0.0, 0.0)).unwrap();
    let e = err(&at("wide.exr"), Encoding::Data);
    assert!(e.contains("exceed the texture limit"), "{e}");
    // A directory is not a texture.
    std::fs::create_dir_all(at("dir.png")).unwrap();
    err(&at("dir.png"), Encoding::Data);
}

#[test]
fn texture_new_checks_its_size() {
    assert!(Texture::new(0, 1, vec![]).is_err());
    assert!(Texture::new(2, 2, vec![Vec3::ZERO; 3]).is_err());
    assert!(Texture::constant(Vec3::splat(0.5)).is_ok());
}

/// Truncated and corrupted PNG and EXR textures are errors (or, when the damage misses
/// what is read, textures), never panics.
#[test]
fn corrupted_textures_never_panic() {
    let dir = temp_dir("tex-corrupt");
    let png = dir.join("ok.png");
    let data: Vec<u8> = (0..8 * 8 * 3).map(|i| (i * 37 % 256) as u8).collect();
    write_png(&png, 8, 8, 3, &data);
    let exr = dir.join("ok.exr");
    let px: Vec<Vec3> = (0..16).map(|i| Vec3::splat(i as f32 / 16.0)).collect();
    write_exr_raw(&exr, 4, 4, &px);
    for (good, ext) in [(png, "png"), (exr, "exr")] {
        let bytes = std::fs::read(&good).unwrap();
        let bad = dir.join(format!("bad.{ext}"));
        let mut n = 0;
        for k in (0..bytes.len()).step_by(3) {
            // Truncated at k, and byte k inverted.
            let mut flipped = bytes.clone();
            flipped[k] ^= 0xff;
            for b in [&bytes[..k], &flipped[..]] {
                std::fs::write(&bad, b).unwrap();
                let r = std::panic::catch_unwind(|| Texture::read(&bad, Encoding::Colour));
                assert!(r.is_ok(), "{ext}: panic at byte {k}");
                n += 1;
            }
        }
        assert!(n > 20);
    }
}

/// A 4 x 4 texture whose texel `(x, y)` is `(x / 4, y / 4, 0)`.
fn grid(sampler: Sampler) -> Texture {
    let texels = (0..16)
        .map(|i| Vec3::new((i % 4) as f32 / 4.0, (i / 4) as f32 / 4.0, 0.0))
        .collect();
    Texture::new(4, 4, texels).unwrap().with_sampler(sampler)
}

fn at(x: i64, y: i64) -> Vec3 {
    Vec3::new(x as f32 / 4.0, y as f32 / 4.0, 0.0)
}

#[test]
fn texture_transform_composes_as_khr_texture_transform_in_gltf_uv_space() {
    let nearest = |wrap_t| Sampler {
        wrap_s: Wrap::Repeat,
        wrap_t,
        filter: Filter::Nearest,
    };
    let t = UvTransform {
        offset: Vec2::new(0.25, 0.0),
        rotation: std::f32::consts::FRAC_PI_2,
        scale: Vec2::new(2.0, 1.0),
    };
    // By hand: mesh (u, v) = (0.1, 0.7) is glTF (s, t) = (0.1, 0.3); scaled (0.2, 0.3);
    // rotated by 90 degrees (cos 0, sin 1): s = 0.3, t = -0.2; offset: (0.55, -0.2).
    let st = t.apply(Vec2::new(0.1, 0.3));
    assert!((st - Vec2::new(0.55, -0.2)).length() < 1e-6, "{st}");
    let uv = Vec2::new(0.1, 0.7);
    // Texel x = floor(0.55 * 4) = 2; y = floor(-0.2 * 4) = -1, which repeats to 3, clamps to
    // 0 and mirrors to 0.
    for (wrap, y) in [
        (Wrap::Repeat, 3),
        (Wrap::ClampToEdge, 0),
        (Wrap::MirroredRepeat, 0),
    ] {
        let tex = grid(nearest(wrap)).with_transform(Some(t));
        assert_eq!(tex.lookup(uv), at(2, y), "{wrap:?}");
    }
    // Without the transform: (0.1, 0.3) reads texel (0, 1).
    assert_eq!(grid(nearest(Wrap::Repeat)).lookup(uv), at(0, 1));
    // Offset alone moves the image: +0.25 in s reads one texel further right.
    let shift = UvTransform {
        offset: Vec2::new(0.25, 0.0),
        ..UvTransform::default()
    };
    let tex = grid(nearest(Wrap::Repeat)).with_transform(Some(shift));
    assert_eq!(tex.lookup(uv), at(1, 1));
}

#[test]
fn wrap_modes_and_filters_match_their_definitions() {
    // Index wrapping, against the definitions.
    for i in -9..13i64 {
        assert_eq!(Wrap::Repeat.index(i, 4), i.rem_euclid(4));
        assert_eq!(Wrap::ClampToEdge.index(i, 4), i.clamp(0, 3));
        let m = i.rem_euclid(8);
        assert_eq!(
            Wrap::MirroredRepeat.index(i, 4),
            if m < 4 { m } else { 7 - m }
        );
    }
    let s = |wrap, filter| Sampler {
        wrap_s: wrap,
        wrap_t: wrap,
        filter,
    };
    // Bilinear half-way between the last and first texel columns of row 0 (t = 0.125 is the
    // row's centre; s = 1.0 is the right edge): repeat blends texels 3 and 0, clamp stays on
    // texel 3, mirror blends texel 3 with itself.
    let uv = Vec2::new(1.0, 1.0 - 0.125);
    let lin = |w| grid(s(w, Filter::Linear)).lookup(uv);
    assert!((lin(Wrap::Repeat) - (at(3, 0) + at(0, 0)) * 0.5).length() < 1e-6);
    assert!((lin(Wrap::ClampToEdge) - at(3, 0)).length() < 1e-6);
    assert!((lin(Wrap::MirroredRepeat) - at(3, 0)).length() < 1e-6);
    // Nearest reads the texel containing the point, no blend.
    let uv = Vec2::new(0.49, 1.0 - 0.6);
    assert_eq!(grid(s(Wrap::Repeat, Filter::Nearest)).lookup(uv), at(1, 2));
    // Huge and non-finite coordinates neither panic nor leave the image.
    for w in [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat] {
        for f in [Filter::Linear, Filter::Nearest] {
            let t = grid(s(w, f));
            for uv in [Vec2::splat(1e30), Vec2::splat(-1e30), Vec2::NAN] {
                let c = t.lookup(uv);
                assert!(
                    c.is_finite() && c.cmple(Vec3::ONE).all(),
                    "{w:?} {f:?} {uv}"
                );
            }
        }
    }
}

#[test]
fn decode_reads_png_and_refuses_other_formats_by_name() {
    let dir = temp_dir("tex-decode");
    let p = dir.join("a.png");
    write_png(&p, 2, 1, 3, &[255, 0, 0, 0, 0, 255]);
    let bytes = std::fs::read(&p).unwrap();
    let t = Texture::decode(&bytes, Encoding::Data).unwrap();
    assert_eq!(t.texels(), &[Vec3::X, Vec3::Z]);
    let ktx2 = b"\xABKTX 20\xBB\r\n\x1a\n0000".to_vec();
    assert!(Texture::decode(&ktx2, Encoding::Colour)
        .unwrap_err()
        .contains("KTX2"));
    let webp = b"RIFF0000WEBPVP8 ".to_vec();
    assert!(Texture::decode(&webp, Encoding::Colour)
        .unwrap_err()
        .contains("WebP"));
    // A JPEG signature on garbage is a JPEG error, not a panic.
    let e = Texture::decode(&[0xFF, 0xD8, 0xFF, 0xE0, 0, 3, 1], Encoding::Colour).unwrap_err();
    assert!(e.contains("JPEG"), "{e}");
    // Oversized: refused from the header.
    let big = dir.join("big.png");
    write_png(
        &big,
        MAX_TEXTURE_SIDE as u32 + 1,
        1,
        1,
        &vec![0; MAX_TEXTURE_SIDE + 1],
    );
    let e = Texture::decode(&std::fs::read(&big).unwrap(), Encoding::Data).unwrap_err();
    assert!(e.contains("exceed the texture limit"), "{e}");
}

/// A 16 x 16 baseline JPEG (quality 100, written by Mitsuba 3's `Bitmap.write` for this test):
/// red, green / blue, white quadrants of 8 x 8 texels.
const JPEG_QUADRANTS_HEX: &[&str] = &[
    "ffd8ffe000104a46494600010100000100010000ffdb0043000101010101010101010101010101010101010101010101",
    "0101010101010101010101010101010101010101010101010101010101010101010101010101010101ffdb0043010101",
    "010101010101010101010101010101010101010101010101010101010101010101010101010101010101010101010101",
    "0101010101010101010101010101ffc00011080010001003011100021101031101ffc4001f0000010501010101010100",
    "000000000000000102030405060708090a0bffc400b5100002010303020403050504040000017d010203000411051221",
    "31410613516107227114328191a1082342b1c11552d1f02433627282090a161718191a25262728292a3435363738393a",
    "434445464748494a535455565758595a636465666768696a737475767778797a838485868788898a9293949596979899",
    "9aa2a3a4a5a6a7a8a9aab2b3b4b5b6b7b8b9bac2c3c4c5c6c7c8c9cad2d3d4d5d6d7d8d9dae1e2e3e4e5e6e7e8e9eaf1",
    "f2f3f4f5f6f7f8f9faffc4001f0100030101010101010101010000000000000102030405060708090a0bffc400b51100",
    "020102040403040705040400010277000102031104052131061241510761711322328108144291a1b1c109233352f015",
    "6272d10a162434e125f11718191a262728292a35363738393a434445464748494a535455565758595a63646566676869",
    "6a737475767778797a82838485868788898a92939495969798999aa2a3a4a5a6a7a8a9aab2b3b4b5b6b7b8b9bac2c3c4",
    "c5c6c7c8c9cad2d3d4d5d6d7d8d9dae2e3e4e5e6e7e8e9eaf2f3f4f5f6f7f8f9faffda000c03010002110311003f00fc",
    "5faff29cff00bf83fa50aff2dcff00c2bcfe0debff006983feac0ff710aff8073faa0fffd9",
];

fn from_hex(parts: &[&str]) -> Vec<u8> {
    let h: String = parts.concat();
    (0..h.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&h[i..i + 2], 16).unwrap())
        .collect()
}

#[test]
fn jpeg_decodes_to_its_colours() {
    let bytes = from_hex(JPEG_QUADRANTS_HEX);
    let t = Texture::decode(&bytes, Encoding::Data).unwrap();
    assert_eq!((t.width(), t.height()), (16, 16));
    // Quadrant centres, away from the edges chroma subsampling blurs: JPEG at quality 100
    // stays within a few of 255 levels of the source there (0.02 is 5 levels).
    for ((x, y), want) in [
        ((3, 3), Vec3::X),
        ((12, 3), Vec3::Y),
        ((3, 12), Vec3::Z),
        ((12, 12), Vec3::ONE),
    ] {
        let got = t.texel(x, y);
        assert!((got - want).abs().max_element() < 0.02, "({x}, {y}): {got}");
    }
    // Colour decoding applies the sRGB curve to the same samples.
    let c = Texture::decode(&bytes, Encoding::Colour).unwrap();
    let (d, s) = (t.texel(12, 12), c.texel(12, 12));
    assert!((srgb_to_linear(d.x) - s.x).abs() < 1e-6);
    // Truncated: an error, not a panic.
    for n in [2, 20, 200, bytes.len() - 2] {
        let r = std::panic::catch_unwind(|| Texture::decode(&bytes[..n], Encoding::Data));
        assert!(r.is_ok(), "panic at {n} bytes");
    }
}
