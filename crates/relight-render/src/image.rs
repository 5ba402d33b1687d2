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
