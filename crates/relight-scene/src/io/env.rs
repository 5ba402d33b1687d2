//! Loading environment maps from `.hdr` / `.exr`: latlong, vertical cross, angular probe.
//!
//! # Layouts
//! * **Latlong** (2:1): used as is, with Mitsuba 3's placement (see `relight_sphere::latlong`).
//! * **Vertical cross** (3:4, Debevec's `*_cross.hdr`): a 3 x 4 grid of `N x N` faces,
//!   converted texel for texel (no resampling) to relight's OpenGL cube
//!   (`relight_sphere::cubemap`). Cells `(column, row)` and the direction of in-cell
//!   coordinates `a` (left to right) and `b` (top to bottom), both in `[-1, 1]`:
//!
//!   | cell | face | direction |
//!   |------|------|-----------|
//!   | (1, 0) | +Y (up)    | `( a,  1, -b)` |
//!   | (0, 1) | -X (left)  | `(-1, -b, -a)` |
//!   | (1, 1) | -Z (front) | `( a, -b, -1)` |
//!   | (2, 1) | +X (right) | `( 1, -b,  a)` |
//!   | (1, 2) | -Y (down)  | `( a, -1,  b)` |
//!   | (1, 3) | +Z (back, upside down) | `( a,  b,  1)` |
//!
//!   i.e. the cross is the cube unfolded around the front face -Z as seen from inside, with
//!   +Y up: the same frame as Debevec's angular probes (centre = -Z, up = +Y, right = +X).
//!   Verified on data: `rnl_cross.hdr` against `rnl_probe.hdr` (test below), and
//!   `grace_cross.hdr` reproduces Ramamoorthi & Hanrahan's published SH coefficients
//!   (`tests/grace_sh.rs`).
//! * **Angular probe** (1:1): Debevec's angular map, passed to `EnvMap::probe`.
//! * A 1:6 image is taken as six faces already in relight's cube order and orientation.
//!
//! Every pixel must be finite and non-negative: anything else is an error naming the pixel
//! (nothing is clamped silently).
//!
//! # Other conventions met in the shared data
//! Probulator's latlong exports (`debevec_latlong_256x128/*.hdr`) use
//! `u = 1/2 + atan2(x, -z) / 2pi` (Probulator's `cartesianToLatLongTexcoord`), i.e. Mitsuba's
//! `u` shifted by one half: loaded as is, their world appears rotated by 180 degrees about +Y.
//! An `Environment` with `rotate_y_deg = 180` restores Probulator's frame.

use super::image::read_image;
use crate::error::SceneError;
use crate::Vec3;
use relight_sphere::cubemap::{self, CubeFace};
use relight_sphere::{EnvLayout, EnvMap};
use std::path::Path;

/// Load an environment map. `layout = None` detects it from the aspect ratio (2:1 latlong,
/// 3:4 vertical cross, 1:1 angular probe, 1:6 stacked cube faces); an explicit layout must
/// match the image's shape (`Cube` accepts a 3:4 vertical cross or 1:6 stacked faces).
pub fn load_env(path: &Path, layout: Option<EnvLayout>) -> Result<EnvMap, SceneError> {
    let (w, h, px) = read_image(path)?;
    check_radiance(path, w, &px)?;
    build_env(path, w, h, px, layout)
}

/// Err on the first NaN, infinite or negative pixel.
pub fn check_radiance(path: &Path, w: usize, px: &[Vec3]) -> Result<(), SceneError> {
    match px
        .iter()
        .position(|c| !(c.is_finite() && c.min_element() >= 0.0))
    {
        None => Ok(()),
        Some(i) => Err(SceneError::BadPixel {
            file: path.display().to_string(),
            x: i % w.max(1),
            y: i / w.max(1),
            value: format!("({}, {}, {})", px[i].x, px[i].y, px[i].z),
        }),
    }
}

/// Build an [`EnvMap`] from decoded pixels (see [`load_env`]).
pub fn build_env(
    path: &Path,
    w: usize,
    h: usize,
    px: Vec<Vec3>,
    layout: Option<EnvLayout>,
) -> Result<EnvMap, SceneError> {
    let is_cross = w.is_multiple_of(3) && 4 * w == 3 * h;
    let is_stack = h == 6 * w;
    let layout = match layout {
        Some(l) => l,
        None if w == 2 * h => EnvLayout::LatLong,
        None if is_cross || is_stack => EnvLayout::Cube,
        None if w == h => EnvLayout::Probe,
        None => {
            return Err(SceneError::unsupported(
                path,
                format!("cannot tell the layout of a {w}x{h} image (2:1 latlong, 3:4 vertical cross, 1:1 angular probe, 1:6 cube faces); give it explicitly"),
            ))
        }
    };
    let mismatch =
        |what: &str| SceneError::malformed(path, format!("a {w}x{h} image is not {what}"));
    Ok(match layout {
        EnvLayout::LatLong if w >= 1 && h >= 2 => EnvMap::latlong(w, h, px),
        EnvLayout::LatLong => return Err(mismatch("a latlong map (needs height >= 2)")),
        EnvLayout::Cube if is_cross => EnvMap::cube(w / 3, cross_to_cube(w / 3, &px)),
        EnvLayout::Cube if is_stack => EnvMap::cube(w, px),
        EnvLayout::Cube => return Err(mismatch("a 3:4 vertical cross or 1:6 stack of cube faces")),
        EnvLayout::Probe if w == h && w >= 2 => EnvMap::probe(w, px),
        EnvLayout::Probe => return Err(mismatch("a square angular probe")),
    })
}

/// Convert a vertical cross (`3n x 4n`, row-major) to relight's cube faces (`6 n^2`, order and
/// orientation of `relight_sphere::cubemap`). Every cube texel is exactly one cross pixel.
///
/// # Panics
/// Debug builds assert `cross.len() == 12 n^2`.
pub fn cross_to_cube(n: usize, cross: &[Vec3]) -> Vec<Vec3> {
    debug_assert_eq!(cross.len(), 12 * n * n);
    let mut out = Vec::with_capacity(6 * n * n);
    for face in CubeFace::ALL {
        for row in 0..n {
            for col in 0..n {
                let (x, y) = cross_pixel(n, cubemap::texel_dir(n, face, row, col));
                out.push(cross[y * 3 * n + x]);
            }
        }
    }
    out
}

/// Direction of in-cell coordinates `(a, b)` of cross cell `(column, row)` (module table);
/// `None` for the empty cells.
pub fn cross_dir(cell: (usize, usize), a: f32, b: f32) -> Option<Vec3> {
    Some(match cell {
        (1, 0) => Vec3::new(a, 1.0, -b),
        (0, 1) => Vec3::new(-1.0, -b, -a),
        (1, 1) => Vec3::new(a, -b, -1.0),
        (2, 1) => Vec3::new(1.0, -b, a),
        (1, 2) => Vec3::new(a, -1.0, b),
        (1, 3) => Vec3::new(a, b, 1.0),
        _ => return None,
    })
}

/// Pixel `(x, y)` of a `3n x 4n` vertical cross seen in direction `d` (inverse of
/// [`cross_dir`]).
pub fn cross_pixel(n: usize, d: Vec3) -> (usize, usize) {
    let ad = d.abs();
    let (cell, a, b) = if ad.x >= ad.y && ad.x >= ad.z {
        if d.x > 0.0 {
            ((2, 1), d.z / ad.x, -d.y / ad.x)
        } else {
            ((0, 1), -d.z / ad.x, -d.y / ad.x)
        }
    } else if ad.y >= ad.z {
        if d.y > 0.0 {
            ((1, 0), d.x / ad.y, -d.z / ad.y)
        } else {
            ((1, 2), d.x / ad.y, d.z / ad.y)
        }
    } else if d.z < 0.0 {
        ((1, 1), d.x / ad.z, -d.y / ad.z)
    } else {
        ((1, 3), d.x / ad.z, d.y / ad.z)
    };
    let px = |t: f32| (((t + 1.0) * 0.5 * n as f32) as usize).min(n - 1);
    (cell.0 * n + px(a), cell.1 * n + px(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::image::write_hdr;
    use crate::io::test_util::temp_dir;
    use crate::io::write_exr;
    use relight_testdata::shared_file;

    #[test]
    fn cross_dir_and_pixel_are_inverse() {
        let n = 8;
        for cy in 0..4 {
            for cx in 0..3 {
                for j in 0..n {
                    for i in 0..n {
                        let (a, b) = (
                            2.0 * (i as f32 + 0.5) / n as f32 - 1.0,
                            2.0 * (j as f32 + 0.5) / n as f32 - 1.0,
                        );
                        if let Some(d) = cross_dir((cx, cy), a, b) {
                            assert_eq!(cross_pixel(n, d), (cx * n + i, cy * n + j));
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn cross_conversion_is_a_permutation() {
        let n = 4;
        let cross: Vec<Vec3> = (0..12 * n * n).map(|i| Vec3::splat(i as f32)).collect();
        let mut cube: Vec<u32> = cross_to_cube(n, &cross)
            .iter()
            .map(|v| v.x as u32)
            .collect();
        cube.sort_unstable();
        cube.dedup();
        assert_eq!(cube.len(), 6 * n * n);
    }

    #[test]
    fn layout_detection_and_mismatch() {
        let p = Path::new("x.hdr");
        let px = |w: usize, h: usize| vec![Vec3::ONE; w * h];
        assert_eq!(
            build_env(p, 8, 4, px(8, 4), None).unwrap().layout(),
            EnvLayout::LatLong
        );
        assert_eq!(
            build_env(p, 6, 8, px(6, 8), None).unwrap().layout(),
            EnvLayout::Cube
        );
        assert_eq!(
            build_env(p, 4, 24, px(4, 24), None).unwrap().layout(),
            EnvLayout::Cube
        );
        assert_eq!(
            build_env(p, 8, 8, px(8, 8), None).unwrap().layout(),
            EnvLayout::Probe
        );
        assert!(build_env(p, 7, 3, px(7, 3), None)
            .unwrap_err()
            .to_string()
            .contains("layout"));
        assert!(build_env(p, 8, 4, px(8, 4), Some(EnvLayout::Probe)).is_err());
        assert!(build_env(p, 8, 4, px(8, 4), Some(EnvLayout::Cube)).is_err());
        assert_eq!(
            build_env(p, 8, 8, px(8, 8), Some(EnvLayout::LatLong))
                .unwrap()
                .layout(),
            EnvLayout::LatLong
        );
    }

    #[test]
    fn nan_pixel_is_refused_with_its_position() {
        let dir = temp_dir("envnan");
        let mut px = vec![Vec3::ONE; 8 * 4];
        px[8 + 3] = Vec3::new(1.0, f32::NAN, 0.0);
        let p = dir.join("nan.exr");
        // write_exr refuses NaN, so write the file with the exr crate directly.
        exr::prelude::write_rgb_file(&p, 8, 4, |x, y| {
            let c = px[y * 8 + x];
            (c.x, c.y, c.z)
        })
        .unwrap();
        let e = load_env(&p, None).unwrap_err();
        assert!(matches!(e, SceneError::BadPixel { x: 3, y: 1, .. }), "{e}");
        assert!(e.to_string().contains("nan.exr"), "{e}");
    }

    #[test]
    fn negative_pixel_is_refused() {
        let dir = temp_dir("envneg");
        let mut px = vec![Vec3::ONE; 8 * 4];
        px[5] = Vec3::new(-0.25, 1.0, 1.0);
        let p = dir.join("neg.exr");
        write_exr(&p, 8, 4, &px).unwrap();
        let e = load_env(&p, None).unwrap_err();
        assert!(matches!(e, SceneError::BadPixel { x: 5, y: 0, .. }), "{e}");
        assert!(e.to_string().contains("-0.25"), "{e}");
    }

    #[test]
    fn hdr_latlong_loads() {
        let dir = temp_dir("envhdr");
        let p = dir.join("c.hdr");
        write_hdr(&p, 16, 8, &vec![Vec3::new(0.5, 1.0, 2.0); 128]).unwrap();
        let m = load_env(&p, None).unwrap();
        assert_eq!(
            (m.layout(), m.width(), m.height()),
            (EnvLayout::LatLong, 16, 8)
        );
        assert!((m.eval(Vec3::X) - Vec3::new(0.5, 1.0, 2.0)).length() < 1e-6);
    }

    #[test]
    fn every_shared_envmap_loads() {
        let Some(root) = relight_testdata::require_shared_dir("the layouts test") else {
            return;
        };
        let mut count = 0;
        for sub in ["debevec", "debevec_latlong_256x128", "polyhaven_1k", "exr"] {
            let Ok(rd) = std::fs::read_dir(root.join("data/envmaps").join(sub)) else {
                continue;
            };
            for entry in rd.flatten() {
                let p = entry.path();
                let m = load_env(&p, None).unwrap_or_else(|e| panic!("{e}"));
                let expect = if sub == "debevec" && p.to_string_lossy().contains("probe") {
                    EnvLayout::Probe
                } else if sub == "debevec" {
                    EnvLayout::Cube
                } else {
                    EnvLayout::LatLong
                };
                assert_eq!(m.layout(), expect, "{}", p.display());
                assert!(m.average_luminance() > 0.0, "{}", p.display());
                count += 1;
            }
        }
        assert_eq!(count, 19, "envmaps listed in SOURCES.md");
    }

    #[test]
    fn orientation_exr_tiled_mipmapped_loads_largest_level() {
        let Some(p) = shared_file("data/envmaps/exr/OrientationLatLong.exr") else {
            return;
        };
        let (w, h, _) = read_image(&p).unwrap();
        assert_eq!((w, h), (1024, 512));
        let Some(p) = shared_file("data/envmaps/exr/KernerEnvLatLong.exr") else {
            return;
        };
        let (w, h, _) = read_image(&p).unwrap();
        assert_eq!((w, h), (1024, 512));
    }

    #[test]
    fn venice_exr_and_hdr_have_the_same_mean_luminance() {
        let Some(a) = shared_file("data/envmaps/exr/venice_sunset_1k.exr") else {
            return;
        };
        let Some(b) = shared_file("data/envmaps/polyhaven_1k/venice_sunset_1k.hdr") else {
            return;
        };
        let (la, lb) = (
            load_env(&a, None).unwrap().average_luminance(),
            load_env(&b, None).unwrap().average_luminance(),
        );
        eprintln!("venice mean luminance: exr {la}, hdr {lb}");
        // Same image stored as half floats vs 8-bit-mantissa RGBE: both quantise to < 0.4 %.
        assert!((la / lb - 1.0).abs() < 0.01, "exr {la} vs hdr {lb}");
    }

    /// Directions spread evenly over the sphere (spherical Fibonacci).
    fn fibonacci(n: usize) -> impl Iterator<Item = Vec3> {
        (0..n).map(move |i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let phi = i as f32 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * phi.cos(), z, r * phi.sin())
        })
    }

    #[test]
    fn rnl_cross_matches_rnl_probe() {
        let Some(c) = shared_file("data/envmaps/debevec/rnl_cross.hdr") else {
            return;
        };
        let Some(p) = shared_file("data/envmaps/debevec/rnl_probe.hdr") else {
            return;
        };
        let (cross, probe) = (load_env(&c, None).unwrap(), load_env(&p, None).unwrap());
        let rel_err = |f: &dyn Fn(Vec3) -> Vec3| {
            let (mut e, mut s) = (0.0, 0.0);
            for d in fibonacci(20_000) {
                let (a, b) = (cross.eval(d), probe.eval(f(d)));
                e += (a - b).abs().element_sum();
                s += 0.5 * (a + b).element_sum();
            }
            e / s
        };
        let right = rel_err(&|d| d);
        eprintln!("rnl cross vs probe: mean relative difference {right:.4}");
        // Both are resamplings of one capture (256^2 faces vs a 900^2 disc), compared with
        // bilinear lookups: edges and highlights give a 3.0 % mean relative difference
        // (measured), so 6 % leaves room for lookup changes; any wrong face placement or flip
        // gives > 100 % (a mirrored or rotated world).
        assert!(right < 0.06, "cross vs probe: {right}");
        for wrong in [
            |d: Vec3| Vec3::new(-d.x, d.y, d.z),
            |d: Vec3| Vec3::new(d.x, d.y, -d.z),
            |d: Vec3| Vec3::new(d.z, d.y, -d.x),
        ] {
            assert!(rel_err(&wrong) > 4.0 * right);
        }
    }
}
