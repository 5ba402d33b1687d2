//! Linear RGB images in memory (row-major, row 0 at the top).

use glam::Vec3;

/// A linear-radiance RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` pixels.
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        Image {
            width,
            height,
            pixels: vec![Vec3::ZERO; width * height],
        }
    }

    /// Pixel at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Vec3 {
        self.pixels[y * self.width + x]
    }

    /// Set the pixel at column `x`, row `y`.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: Vec3) {
        self.pixels[y * self.width + x] = v;
    }
}

/// The image files relight writes, chosen by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// OpenEXR, linear float.
    Exr,
    /// Radiance RGBE, linear.
    Hdr,
    /// PNG, tone-mapped sRGB, 8 bits.
    Png,
}

impl ImageFormat {
    /// The format of `path` by its (case-insensitive) extension, if relight writes it.
    pub fn of(path: &std::path::Path) -> Option<ImageFormat> {
        let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
        match ext.as_str() {
            "exr" => Some(ImageFormat::Exr),
            "hdr" => Some(ImageFormat::Hdr),
            "png" => Some(ImageFormat::Png),
            _ => None,
        }
    }

    /// [`ImageFormat::of`], or an error naming the file and the extensions accepted.
    ///
    /// # Errors
    /// [`ImageError::Extension`].
    pub fn require(path: &std::path::Path) -> Result<ImageFormat, ImageError> {
        ImageFormat::of(path).ok_or_else(|| ImageError::Extension(path.to_path_buf()))
    }
}

/// Why an image could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The extension is not one relight writes.
    #[error("{}: unknown image extension (exr, hdr, png)", .0.display())]
    Extension(std::path::PathBuf),
    /// The file could not be written or read.
    #[error(transparent)]
    File(#[from] relight_scene::error::SceneError),
}

/// Write `img` to `path` by extension: `.exr` (linear float), `.hdr` (linear RGBE), `.png`
/// (tone-mapped with `tm`, sRGB). Writes are atomic (temporary sibling, then rename).
///
/// # Errors
/// An unknown extension or a write error, naming `path`.
pub fn write_image(
    path: &std::path::Path,
    img: &Image,
    tm: &crate::tonemap::ToneMap,
) -> Result<(), ImageError> {
    use relight_scene::io::image as io;
    let (w, h) = (img.width, img.height);
    match ImageFormat::require(path)? {
        ImageFormat::Exr => io::write_exr(path, w, h, &img.pixels)?,
        ImageFormat::Hdr => io::write_hdr(path, w, h, &img.pixels)?,
        ImageFormat::Png => io::write_png_srgb8(path, w, h, &tm.to_srgb8(img))?,
    }
    Ok(())
}

/// Read an `.exr` or `.hdr` image.
///
/// # Errors
/// A read or format error naming `path`.
pub fn read_image(path: &std::path::Path) -> Result<Image, ImageError> {
    let (width, height, pixels) = relight_scene::io::image::read_image(path)?;
    Ok(Image {
        width,
        height,
        pixels,
    })
}
