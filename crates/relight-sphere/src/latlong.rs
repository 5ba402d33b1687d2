//! Latlong (equirectangular) grid with Mitsuba 3's texel placement.
//!
//! Conventions (those of the crate, see `lib.rs`): `u = phi / 2pi (mod 1)` with
//! `phi = atan2(d.x, -d.z)`, `v = theta / pi` with `cos theta = d.y`. Column `i` of a
//! `W`-wide image is centred at `u = (i + 0.5) / W` and wraps horizontally; **row `j` of an
//! `H`-high image sits at `theta = pi j / (H - 1)`** (row 0 exactly +Y, row `H - 1` exactly
//! -Y). Lookups interpolate bilinearly in `(u, theta)`, exactly as Mitsuba 3's `envmap`.
//!
//! Quadrature weight of a texel (its "solid angle"): the integral over the sphere of its
//! bilinear hat function, `(2 pi / W) * int tent_j(theta) sin(theta) dtheta`. With
//! `h = pi / (H - 1)` this is, in closed form,
//! `(2 pi / W) * 2 sin(theta_j) (1 - cos h) / h` for interior rows and
//! `(2 pi / W) * (1 - sin(h) / h)` for the two pole rows; the weights sum to exactly `4 pi`.

use crate::{Vec2, Vec3};
use std::f32::consts::PI;
use std::f64::consts::PI as PI64;

/// `(u, v)` of a unit direction: `u in [0, 1)`, `v in [0, 1]`.
#[inline]
pub fn dir_to_uv(dir: Vec3) -> Vec2 {
    let mut u = dir.x.atan2(-dir.z) * (0.5 / PI);
    if u < 0.0 {
        u += 1.0;
    }
    if u >= 1.0 {
        u -= 1.0;
    }
    let v = dir.y.clamp(-1.0, 1.0).acos() * (1.0 / PI);
    Vec2::new(u, v)
}

/// Unit direction of `(u, v)`: `d = (sin phi sin theta, cos theta, -cos phi sin theta)`.
#[inline]
pub fn uv_to_dir(uv: Vec2) -> Vec3 {
    let (sp, cp) = (2.0 * PI * uv.x).sin_cos();
    let (st, ct) = (PI * uv.y).sin_cos();
    Vec3::new(sp * st, ct, -cp * st)
}

/// Polar angle of row `row` of an `height`-high map: `pi row / (height - 1)`.
///
/// # Panics
/// Debug builds assert `height >= 2` and `row < height`.
#[inline]
pub fn row_theta(height: usize, row: usize) -> f64 {
    debug_assert!(height >= 2 && row < height);
    PI64 * row as f64 / (height - 1) as f64
}

/// Direction of texel `(col, row)` of a `width x height` map (column centred, row on its
/// Mitsuba latitude). The azimuth uses f64 so that texel directions are exactly reproducible.
#[inline]
pub fn texel_dir(width: usize, height: usize, col: usize, row: usize) -> Vec3 {
    let phi = 2.0 * PI64 * (col as f64 + 0.5) / width as f64;
    let theta = row_theta(height, row);
    let (sp, cp) = phi.sin_cos();
    let (st, ct) = theta.sin_cos();
    // Exact poles: sin(pi) is not 0 in floating point.
    let st = if row == 0 || row + 1 == height {
        0.0
    } else {
        st
    };
    let ct = if row == 0 {
        1.0
    } else if row + 1 == height {
        -1.0
    } else {
        ct
    };
    Vec3::new((sp * st) as f32, ct as f32, (-cp * st) as f32)
}

/// Every texel direction of a `width x height` map, [`texel_dir`] bit for bit, from
/// per-column and per-row sines and cosines: `width + height` pairs of f64 `sin_cos`
/// instead of two per texel (which were a quarter of the cuts frame's lights' power under a
/// new environment, docs/RESULTS.md, section cuts).
#[derive(Clone, Debug)]
pub struct TexelDirs {
    /// `(sin phi, cos phi)` of each column.
    cols: Vec<(f64, f64)>,
    /// `(sin theta, cos theta)` of each row, exact at the poles as in [`texel_dir`].
    rows: Vec<(f64, f64)>,
}

impl TexelDirs {
    /// The table of a `width x height` map.
    ///
    /// # Panics
    /// Debug builds: `height < 2`.
    pub fn new(width: usize, height: usize) -> TexelDirs {
        let cols = (0..width)
            .map(|col| (2.0 * PI64 * (col as f64 + 0.5) / width as f64).sin_cos())
            .collect();
        let rows = (0..height)
            .map(|row| match row {
                0 => (0.0, 1.0),
                r if r + 1 == height => (0.0, -1.0),
                r => row_theta(height, r).sin_cos(),
            })
            .collect();
        TexelDirs { cols, rows }
    }

    /// [`texel_dir`] of texel `(col, row)`.
    ///
    /// # Panics
    /// `col` or `row` out of range.
    #[inline]
    pub fn dir(&self, col: usize, row: usize) -> Vec3 {
        let ((sp, cp), (st, ct)) = (self.cols[col], self.rows[row]);
        Vec3::new((sp * st) as f32, ct as f32, (-cp * st) as f32)
    }
}

/// Exact quadrature weight (solid angle) of every texel of row `row` (see module docs).
#[inline]
pub fn row_weight(width: usize, height: usize, row: usize) -> f64 {
    debug_assert!(height >= 2 && row < height && width >= 1);
    let h = PI64 / (height - 1) as f64;
    let dphi = 2.0 * PI64 / width as f64;
    if row == 0 || row + 1 == height {
        // Half tent at a pole: 1 - sin(h)/h, written stably for small h.
        let sinc = if h < 1e-3 {
            1.0 - h * h / 6.0 + h.powi(4) / 120.0
        } else {
            h.sin() / h
        };
        dphi * (1.0 - sinc)
    } else {
        let one_minus_cos = 2.0 * (0.5 * h).sin().powi(2);
        dphi * 2.0 * row_theta(height, row).sin() * one_minus_cos / h
    }
}

/// The four texels and bilinear weights of the lookup of `dir` (horizontal wrap, rows at
/// Mitsuba latitudes). Entries are `(row * width + col, weight)`; weights sum to 1.
///
/// # Panics
/// Debug builds assert `height >= 2`.
#[inline]
pub fn bilinear(width: usize, height: usize, dir: Vec3) -> [(usize, f32); 4] {
    debug_assert!(height >= 2 && width >= 1);
    let uv = dir_to_uv(dir);
    let x = uv.x * width as f32 - 0.5;
    let y = uv.y * (height - 1) as f32;
    let xf = x.floor();
    let fx = x - xf;
    let c0 = (xf as i64).rem_euclid(width as i64) as usize;
    let c1 = if c0 + 1 == width { 0 } else { c0 + 1 };
    let r0 = (y.floor().max(0.0) as usize).min(height - 2);
    let fy = (y - r0 as f32).clamp(0.0, 1.0);
    let r1 = r0 + 1;
    [
        (r0 * width + c0, (1.0 - fx) * (1.0 - fy)),
        (r0 * width + c1, fx * (1.0 - fy)),
        (r1 * width + c0, (1.0 - fx) * fy),
        (r1 * width + c1, fx * fy),
    ]
}

/// The four grid neighbours of texel `(col, row)`: left and right (wrapping in azimuth), then
/// up and down. Across a pole (up from row 0, down from row `H - 1`) the neighbour is the next
/// row at the opposite azimuth, `col + W/2`, since every texel of a pole row sits at the pole
/// itself. Entries are `(col, row)`.
///
/// # Panics
/// Debug builds assert `height >= 2` and that the texel is inside the grid.
pub fn texel_neighbours(
    width: usize,
    height: usize,
    col: usize,
    row: usize,
) -> [(usize, usize); 4] {
    debug_assert!(height >= 2 && col < width && row < height);
    let left = (col + width - 1) % width;
    let right = (col + 1) % width;
    let opposite = (col + width / 2) % width;
    let up = if row == 0 {
        (opposite, 1)
    } else {
        (col, row - 1)
    };
    let down = if row + 1 == height {
        (opposite, height - 2)
    } else {
        (col, row + 1)
    };
    [(left, row), (right, row), up, down]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_are_one_grid_step_away() {
        let (w, h) = (16, 9);
        let dtheta = std::f32::consts::PI / (h - 1) as f32;
        let dphi = std::f32::consts::TAU / w as f32;
        for row in 0..h {
            for col in 0..w {
                let d = texel_dir(w, h, col, row);
                let n = texel_neighbours(w, h, col, row);
                for (k, &(c, r)) in n.iter().enumerate() {
                    assert!(c < w && r < h);
                    let angle = d.dot(texel_dir(w, h, c, r)).clamp(-1.0, 1.0).acos();
                    // Left/right: at most the azimuth step (less away from the equator);
                    // up/down: exactly the row step (also across a pole).
                    let limit = if k < 2 { dphi } else { dtheta };
                    assert!(angle <= limit + 1e-5, "({col},{row}) -> ({c},{r}): {angle}");
                    if k >= 2 {
                        assert!((angle - dtheta).abs() < 1e-5);
                    }
                }
                // Interior left/right/up/down relations are symmetric.
                if row > 0 && row + 1 < h {
                    for &(c, r) in &n {
                        if r > 0 && r + 1 < h {
                            assert!(texel_neighbours(w, h, c, r).contains(&(col, row)));
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn mitsuba_placement() {
        let (w, h) = (8, 5);
        // Row 0 is +Y, row H-1 is -Y.
        assert!((texel_dir(w, h, 3, 0) - Vec3::Y).length() < 1e-7);
        assert!((texel_dir(w, h, 3, h - 1) + Vec3::Y).length() < 1e-7);
        // u = 0.25 is +X, 0.5 is +Z, 0.75 is -X, 0 is -Z.
        for (u, d) in [
            (0.25, Vec3::X),
            (0.5, Vec3::Z),
            (0.75, -Vec3::X),
            (0.0, -Vec3::Z),
        ] {
            assert!((uv_to_dir(Vec2::new(u, 0.5)) - d).length() < 1e-6, "u={u}");
            let back = dir_to_uv(d);
            assert!((back.x - u).abs() < 1e-6 && (back.y - 0.5).abs() < 1e-6);
        }
        // Columns are centred: column 1 of 8 is at u = 1.5 / 8, the equator row at v = 0.5.
        let d = texel_dir(w, h, 1, 2);
        let uv = dir_to_uv(d);
        assert!((uv.x - 1.5 / 8.0).abs() < 1e-6 && (uv.y - 0.5).abs() < 1e-6);
    }

    #[test]
    fn row_weights_sum_to_4pi() {
        for (w, h) in [(1, 2), (4, 3), (16, 9), (64, 33), (512, 257), (7, 1000)] {
            let s: f64 = (0..h).map(|j| row_weight(w, h, j) * w as f64).sum();
            assert!((s - 4.0 * PI64).abs() < 1e-9, "{w}x{h}: {s}");
        }
    }

    #[test]
    fn row_weight_is_tent_integral() {
        // Compare the closed form with a fine midpoint integral of tent * sin.
        let (w, h) = (10usize, 7usize);
        let step = PI64 / (h - 1) as f64;
        for j in 0..h {
            let n = 200_000;
            let mut acc = 0.0;
            for k in 0..n {
                let t = (k as f64 + 0.5) / n as f64 * PI64;
                let tent = (1.0 - (t - j as f64 * step).abs() / step).max(0.0);
                acc += tent * t.sin() * PI64 / n as f64;
            }
            let closed = row_weight(w, h, j) / (2.0 * PI64 / w as f64);
            assert!((acc - closed).abs() < 1e-8, "row {j}: {acc} vs {closed}");
        }
    }

    #[test]
    fn bilinear_hits_texels() {
        let (w, h) = (12, 7);
        for j in 0..h {
            for i in 0..w {
                let b = bilinear(w, h, texel_dir(w, h, i, j));
                let best = b
                    .iter()
                    .copied()
                    .fold((0, -1.0), |a, x| if x.1 > a.1 { x } else { a });
                let s: f32 = b.iter().map(|x| x.1).sum();
                assert!((s - 1.0).abs() < 1e-6);
                if j != 0 && j != h - 1 {
                    assert_eq!(best.0, j * w + i);
                    assert!(best.1 > 0.999);
                } else {
                    assert!(best.0 / w == j);
                }
            }
        }
    }
}
