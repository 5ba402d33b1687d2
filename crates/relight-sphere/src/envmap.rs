//! Environment maps in memory: latlong, cube and angular-probe layouts, bilinear lookup and
//! exact quadrature weights.
//!
//! An [`EnvMap`] holds linear RGB radiance *arriving from* each direction, in the map's own
//! frame (the crate conventions: +Y up, Mitsuba 3's latlong placement). Each layout defines
//! * a lookup [`EnvMap::eval`] (the function "as the renderer interpolates it"), and
//! * a set of samples [`EnvMap::texel`] `(dir_i, w_i, value_i)` whose weights are exact
//!   integrals, so `sum_i value_i f(dir_i) w_i` approximates `int L(w) f(w) dw` and a constant
//!   map integrates to exactly `4 pi` times its value:
//!   * latlong: every pixel; `w` = integral of its bilinear hat function (see [`crate::latlong`]);
//!   * cube: every texel; `w` = its exact solid angle (see [`crate::cubemap`]);
//!   * probe: pixels whose centre is inside the disc; `w` = exact solid angle of the pixel
//!     square (see [`crate::probe`]).
//!
//! [`project_point_rule`] is the inner product of such a rule with any set of basis functions.
//! Importance sampling lives in [`crate::env_sampler`].

use crate::cubemap::{self, CubeFace};
use crate::latlong;
use crate::probe::{self, ProbeSamples};
use crate::{Vec2, Vec3};
use std::sync::Arc;

/// Layout of an environment map's texel array.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EnvLayout {
    /// Equirectangular, Mitsuba 3 placement (`width x height`, row-major, row 0 = +Y).
    LatLong,
    /// Six `n x n` faces stacked `+X, -X, +Y, -Y, +Z, -Z`, OpenGL orientation.
    Cube,
    /// Debevec angular map (`n x n`), centre looks at -Z.
    Probe,
}

/// One quadrature sample of an environment map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelInfo {
    /// Unit direction of the sample, map frame.
    pub dir: Vec3,
    /// Exact quadrature weight (steradians); all weights of a map sum to `4 pi`.
    pub solid_angle: f32,
    /// Radiance of the texel.
    pub value: Vec3,
}

/// Rec. 709 luminance `0.2126 r + 0.7152 g + 0.0722 b`.
#[inline]
pub fn luminance(rgb: Vec3) -> f32 {
    0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z
}

/// An environment map (radiance arriving from each direction, map frame).
///
/// `Debug` prints the layout, size and average radiance, not the texels.
#[derive(Clone)]
pub struct EnvMap {
    layout: EnvLayout,
    width: usize,
    height: usize,
    texels: Vec<Vec3>,
    /// Latlong: weight per row; cube: weight per face texel (`n^2`); probe: unused.
    weights: Vec<f32>,
    /// Probe sample table (shared between clones).
    probe: Option<Arc<ProbeSamples>>,
}

impl std::fmt::Debug for EnvMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EnvMap")
            .field("layout", &self.layout)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("samples", &self.texel_count())
            .field("average", &self.average())
            .finish()
    }
}

impl EnvMap {
    /// A latlong map (`width x height`, row-major, Mitsuba 3 placement: see [`crate::latlong`]).
    ///
    /// # Panics
    /// Panics if `height < 2`, `width < 1` or `texels.len() != width * height`.
    pub fn latlong(width: usize, height: usize, texels: Vec<Vec3>) -> EnvMap {
        assert!(
            height >= 2 && width >= 1,
            "latlong map needs width >= 1, height >= 2"
        );
        assert_eq!(texels.len(), width * height, "latlong texel count");
        let weights = (0..height)
            .map(|j| latlong::row_weight(width, height, j) as f32)
            .collect();
        EnvMap {
            layout: EnvLayout::LatLong,
            width,
            height,
            texels,
            weights,
            probe: None,
        }
    }

    /// A cube map: 6 faces `+X, -X, +Y, -Y, +Z, -Z`, each `face_size^2` row-major, OpenGL
    /// orientation (table in [`crate::cubemap`]). `width()` is `face_size`, `height()` is
    /// `6 face_size`.
    ///
    /// # Panics
    /// Panics if `face_size < 1` or `texels.len() != 6 face_size^2`.
    pub fn cube(face_size: usize, texels: Vec<Vec3>) -> EnvMap {
        let n = face_size;
        assert!(n >= 1, "cube face size must be >= 1");
        assert_eq!(texels.len(), 6 * n * n, "cube texel count");
        let mut weights = Vec::with_capacity(n * n);
        for r in 0..n {
            for c in 0..n {
                weights.push(cubemap::texel_solid_angle(n, r, c) as f32);
            }
        }
        EnvMap {
            layout: EnvLayout::Cube,
            width: n,
            height: 6 * n,
            texels,
            weights,
            probe: None,
        }
    }

    /// A Debevec angular map (`size x size`, row-major, row 0 at the top): centre looks at -Z,
    /// up is +Y, right is +X, radius `r` maps to angle `pi r` from -Z. Texels outside the disc
    /// are ignored. Computing the exact sample weights costs about `64 size^2` sines.
    ///
    /// # Panics
    /// Panics if `size < 2` or `texels.len() != size^2`.
    pub fn probe(size: usize, texels: Vec<Vec3>) -> EnvMap {
        assert!(size >= 2, "probe size must be >= 2");
        assert_eq!(texels.len(), size * size, "probe texel count");
        let samples = Arc::new(ProbeSamples::new(size));
        EnvMap {
            layout: EnvLayout::Probe,
            width: size,
            height: size,
            texels,
            weights: Vec::new(),
            probe: Some(samples),
        }
    }

    /// A constant environment (a small 64 x 33 latlong map filled with `rgb`; dense enough
    /// that its SH projection has bands above 0 at rounding level, ~1e-15 of band 0, with the exact latlong projection of `sh::project`).
    pub fn constant(rgb: Vec3) -> EnvMap {
        EnvMap::latlong(64, 33, vec![rgb; 64 * 33])
    }

    /// A latlong map whose texel `(col, row)` is `f(texel direction)`.
    pub fn latlong_from_fn(width: usize, height: usize, f: impl Fn(Vec3) -> Vec3) -> EnvMap {
        assert!(
            height >= 2 && width >= 1,
            "latlong map needs width >= 1, height >= 2"
        );
        let texels = (0..height)
            .flat_map(|j| (0..width).map(move |i| (i, j)))
            .map(|(i, j)| f(latlong::texel_dir(width, height, i, j)))
            .collect();
        EnvMap::latlong(width, height, texels)
    }

    /// A cube map whose texels are `f(texel centre direction)`.
    pub fn cube_from_fn(face_size: usize, f: impl Fn(Vec3) -> Vec3) -> EnvMap {
        let n = face_size;
        let texels = (0..6 * n * n)
            .map(|i| {
                let (face, r, c) = cubemap::texel_coords(n, i);
                f(cubemap::texel_dir(n, face, r, c))
            })
            .collect();
        EnvMap::cube(n, texels)
    }

    /// A probe whose texels inside the disc are `f(pixel centre direction)` (zero outside).
    pub fn probe_from_fn(size: usize, f: impl Fn(Vec3) -> Vec3) -> EnvMap {
        let n = size;
        let texels = (0..n * n)
            .map(|p| {
                let (i, j) = (p % n, p / n);
                if probe::pixel_in_disc(n, i, j) {
                    f(probe::disc_to_dir(probe::pixel_centre(n, i, j)))
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        EnvMap::probe(n, texels)
    }

    /// The layout.
    #[inline]
    pub fn layout(&self) -> EnvLayout {
        self.layout
    }

    /// Image width (latlong width, cube face size, probe size).
    #[inline]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height (latlong height, `6 x` face size for cubes, probe size).
    #[inline]
    pub fn height(&self) -> usize {
        self.height
    }

    /// All texels of the image, row-major (`width * height` values, including unused probe
    /// texels outside the disc).
    #[inline]
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// Mutable texels (the layout and weights stay valid).
    #[inline]
    pub fn texels_mut(&mut self) -> &mut [Vec3] {
        &mut self.texels
    }

    /// Radiance arriving from unit direction `dir` (map frame), bilinearly interpolated:
    /// latlong as Mitsuba 3 (horizontal wrap, rows at `theta = pi j / (H - 1)`); cube within the
    /// face, clamped at its edges; probe over the inside-disc pixels only (weights renormalised;
    /// nearest inside pixel if none of the four is inside).
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        match self.layout {
            EnvLayout::LatLong => self.gather(latlong::bilinear(self.width, self.height, dir)),
            EnvLayout::Cube => self.gather(cubemap::bilinear(self.width, dir)),
            EnvLayout::Probe => self.eval_probe(dir),
        }
    }

    #[inline]
    fn gather(&self, taps: [(usize, f32); 4]) -> Vec3 {
        taps.iter()
            .fold(Vec3::ZERO, |acc, &(i, w)| acc + self.texels[i] * w)
    }

    fn eval_probe(&self, dir: Vec3) -> Vec3 {
        let samples = self.probe.as_ref().expect("probe samples");
        let n = self.width;
        let p = probe::dir_to_disc(dir);
        let x = ((p.x + 1.0) * 0.5 * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
        let y = ((1.0 - p.y) * 0.5 * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
        let c0 = (x as usize).min(n - 2);
        let r0 = (y as usize).min(n - 2);
        let (fx, fy) = ((x - c0 as f32).min(1.0), (y - r0 as f32).min(1.0));
        let taps = [
            (r0 * n + c0, (1.0 - fx) * (1.0 - fy)),
            (r0 * n + c0 + 1, fx * (1.0 - fy)),
            ((r0 + 1) * n + c0, (1.0 - fx) * fy),
            ((r0 + 1) * n + c0 + 1, fx * fy),
        ];
        let (mut acc, mut wsum) = (Vec3::ZERO, 0.0);
        for (pix, w) in taps {
            if samples.sample_of_pixel[pix] != u32::MAX && w > 0.0 {
                acc += self.texels[pix] * w;
                wsum += w;
            }
        }
        if wsum > 1e-6 {
            acc / wsum
        } else {
            let s = samples.nearest(p);
            self.texels[samples.pixels[s as usize] as usize]
        }
    }

    /// Number of quadrature samples (`W H` latlong, `6 n^2` cube, pixels inside the disc for
    /// a probe).
    #[inline]
    pub fn texel_count(&self) -> usize {
        match self.layout {
            EnvLayout::LatLong | EnvLayout::Cube => self.texels.len(),
            EnvLayout::Probe => self.probe.as_ref().map_or(0, |p| p.pixels.len()),
        }
    }

    /// Image pixel index (into [`EnvMap::texels`]) of quadrature sample `i` (the identity
    /// except for probes).
    #[inline]
    pub fn texel_pixel(&self, i: usize) -> usize {
        match self.layout {
            EnvLayout::LatLong | EnvLayout::Cube => i,
            EnvLayout::Probe => self.probe.as_ref().expect("probe samples").pixels[i] as usize,
        }
    }

    /// `texel(i).dir` for every `i`, bit for bit, by a table for a latlong map
    /// ([`latlong::TexelDirs`]): for passes over every texel's direction.
    pub fn texel_dirs(&self) -> impl Fn(usize) -> Vec3 + Sync + '_ {
        let table = (self.layout == EnvLayout::LatLong)
            .then(|| latlong::TexelDirs::new(self.width, self.height));
        move |i| match &table {
            Some(t) => t.dir(i % self.width, i / self.width),
            None => self.texel(i).dir,
        }
    }

    /// Quadrature sample `i`: direction, exact weight and value (see module docs).
    ///
    /// # Panics
    /// Panics if `i >= texel_count()`.
    #[inline]
    pub fn texel(&self, i: usize) -> TexelInfo {
        match self.layout {
            EnvLayout::LatLong => {
                let (col, row) = (i % self.width, i / self.width);
                TexelInfo {
                    dir: latlong::texel_dir(self.width, self.height, col, row),
                    solid_angle: self.weights[row],
                    value: self.texels[i],
                }
            }
            EnvLayout::Cube => {
                let n = self.width;
                let (face, row, col) = cubemap::texel_coords(n, i);
                TexelInfo {
                    dir: cubemap::texel_dir(n, face, row, col),
                    solid_angle: self.weights[row * n + col],
                    value: self.texels[i],
                }
            }
            EnvLayout::Probe => {
                let s = self.probe.as_ref().expect("probe samples");
                let pix = s.pixels[i] as usize;
                let n = self.width;
                TexelInfo {
                    dir: probe::disc_to_dir(probe::pixel_centre(n, pix % n, pix / n)),
                    solid_angle: s.weights[i] as f32,
                    value: self.texels[pix],
                }
            }
        }
    }

    /// Iterator over all quadrature samples.
    pub fn texel_iter(&self) -> impl Iterator<Item = TexelInfo> + '_ {
        (0..self.texel_count()).map(move |i| self.texel(i))
    }

    /// `int L(w) dw` over the sphere (RGB), by the exact texel weights (f64 accumulation).
    pub fn integral(&self) -> Vec3 {
        let mut acc = [0f64; 3];
        for t in self.texel_iter() {
            let w = t.solid_angle as f64;
            acc[0] += t.value.x as f64 * w;
            acc[1] += t.value.y as f64 * w;
            acc[2] += t.value.z as f64 * w;
        }
        Vec3::new(acc[0] as f32, acc[1] as f32, acc[2] as f32)
    }

    /// Average radiance over the sphere (RGB): `integral() / 4 pi`.
    pub fn average(&self) -> Vec3 {
        self.integral() / (4.0 * std::f32::consts::PI)
    }

    /// Solid-angle-weighted average luminance.
    pub fn average_luminance(&self) -> f32 {
        luminance(self.average())
    }

    /// Largest texel luminance among the quadrature samples.
    pub fn max_luminance(&self) -> f32 {
        self.texel_iter()
            .map(|t| luminance(t.value))
            .fold(0.0, f32::max)
    }

    /// Multiplies every texel by `s`.
    pub fn scale(&mut self, s: Vec3) {
        for t in &mut self.texels {
            *t *= s;
        }
    }

    /// Resamples to a `width x height` latlong map: each output texel is the
    /// solid-angle-weighted mean of [`EnvMap::eval`] over a 4 x 4 grid covering its cell
    /// (`u` within the column, `theta` within half a row spacing of the row; pole rows cover
    /// half a spacing). A latlong of the same size is copied unchanged.
    ///
    /// # Panics
    /// Panics if `height < 2` or `width < 1`.
    pub fn to_latlong(&self, width: usize, height: usize) -> EnvMap {
        if self.layout == EnvLayout::LatLong && self.width == width && self.height == height {
            return self.clone();
        }
        assert!(height >= 2 && width >= 1);
        const K: usize = 4;
        let h = std::f32::consts::PI / (height - 1) as f32;
        let mut texels = Vec::with_capacity(width * height);
        for j in 0..height {
            let t_lo = (j as f32 - 0.5).max(0.0) * h;
            let t_hi = (j as f32 + 0.5).min((height - 1) as f32) * h;
            for i in 0..width {
                let (mut acc, mut wsum) = (Vec3::ZERO, 0.0);
                for a in 0..K {
                    let theta = t_lo + (t_hi - t_lo) * (a as f32 + 0.5) / K as f32;
                    let w = theta.sin().max(1e-6);
                    for b in 0..K {
                        let u = (i as f32 + (b as f32 + 0.5) / K as f32) / width as f32;
                        let d = latlong::uv_to_dir(Vec2::new(u, theta / std::f32::consts::PI));
                        acc += self.eval(d) * w;
                        wsum += w;
                    }
                }
                texels.push(acc / wsum);
            }
        }
        EnvMap::latlong(width, height, texels)
    }

    /// Cube face of sample `i` of a cube map (`None` for other layouts).
    pub fn cube_face_of(&self, i: usize) -> Option<CubeFace> {
        (self.layout == EnvLayout::Cube).then(|| cubemap::texel_coords(self.width, i).0)
    }
}

/// The point-rule projection shared by every spherical basis ([`crate::basis`]):
/// `sum_i value(t_i) B(dir_i) w_i` over the texels `t_i` of `grid` with their quadrature
/// weights `w_i` ([`EnvMap::texel`]), accumulated in f64; texels whose value is zero are
/// skipped. `eval_basis(dir, out)` fills `n` values.
pub fn project_point_rule(
    grid: &EnvMap,
    n: usize,
    eval_basis: impl Fn(Vec3, &mut [f32]),
    value: impl Fn(&TexelInfo) -> Vec3,
) -> Vec<Vec3> {
    let mut acc = vec![[0f64; 3]; n];
    let mut b = vec![0f32; n];
    for t in grid.texel_iter() {
        let v = value(&t);
        if v == Vec3::ZERO {
            continue;
        }
        eval_basis(t.dir, &mut b);
        let w = t.solid_angle as f64;
        let v = [v.x as f64 * w, v.y as f64 * w, v.z as f64 * w];
        for (a, &y) in acc.iter_mut().zip(&b) {
            a[0] += v[0] * y as f64;
            a[1] += v[1] * y as f64;
            a[2] += v[2] * y as f64;
        }
    }
    acc.iter()
        .map(|a| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::warp::Rng;
    use std::f64::consts::PI;

    fn pattern(d: Vec3) -> Vec3 {
        Vec3::new(1.0 + d.x, 2.0 + d.y * d.z, 0.5 + 0.4 * (3.0 * d.z).sin())
    }

    /// The table of texel directions is `texel(i).dir`, bit for bit, for every layout and
    /// for latlong maps of odd, even and two-row heights.
    #[test]
    fn texel_dirs_are_the_texels_directions() {
        let mut all = maps();
        all.push(EnvMap::latlong_from_fn(512, 257, pattern));
        all.push(EnvMap::latlong_from_fn(7, 2, pattern));
        for m in all {
            let dirs = m.texel_dirs();
            for i in 0..m.texel_count() {
                assert_eq!(dirs(i), m.texel(i).dir, "{m:?}, texel {i}");
            }
        }
    }

    fn maps() -> Vec<EnvMap> {
        vec![
            EnvMap::latlong_from_fn(32, 17, pattern),
            EnvMap::cube_from_fn(9, pattern),
            EnvMap::probe_from_fn(24, pattern),
            EnvMap::constant(Vec3::new(1.0, 2.0, 3.0)),
        ]
    }

    #[test]
    fn weights_sum_to_4pi_every_layout() {
        for m in maps() {
            let s: f64 = m.texel_iter().map(|t| t.solid_angle as f64).sum();
            assert!((s - 4.0 * PI).abs() < 4e-5, "{:?}: {s}", m.layout());
            assert!(m.texel_iter().all(|t| (t.dir.length() - 1.0).abs() < 1e-5));
        }
    }

    #[test]
    fn eval_at_texel_dirs_returns_texel_values() {
        for m in maps() {
            for i in 0..m.texel_count() {
                let t = m.texel(i);
                if m.layout() == EnvLayout::LatLong {
                    // Pole rows collapse to a point; their texels differ, so skip them.
                    let row = i / m.width();
                    if row == 0 || row + 1 == m.height() {
                        continue;
                    }
                }
                let e = m.eval(t.dir);
                // Directions are rounded to f32 before the lookup: a few 1e-6 of a texel.
                assert!(
                    (e - t.value).abs().max_element() < 1e-4,
                    "{:?} {i}: {e} vs {}",
                    m.layout(),
                    t.value
                );
            }
        }
    }

    #[test]
    fn latlong_mitsuba_placement() {
        // A map whose texel (i, j) encodes its own coordinates.
        let (w, h) = (8, 5);
        let texels = (0..w * h)
            .map(|p| Vec3::new((p % w) as f32, (p / w) as f32, 0.0))
            .collect();
        let m = EnvMap::latlong(w, h, texels);
        // Row 0 is +Y, row H-1 is -Y (any column: all pole texels have the row value).
        assert_eq!(m.eval(Vec3::Y).y, 0.0);
        assert_eq!(m.eval(-Vec3::Y).y, (h - 1) as f32);
        // u = 0.25 is +X: at 8 columns centred at (i+0.5)/8, u = 0.25 is halfway between
        // columns 1 and 2; the equator row 2 sits exactly at theta = pi/2.
        let e = m.eval(Vec3::X);
        assert!((e.x - 1.5).abs() < 1e-5 && (e.y - 2.0).abs() < 1e-5, "{e}");
        let e = m.eval(Vec3::Z); // u = 0.5: between columns 3 and 4
        assert!((e.x - 3.5).abs() < 1e-5, "{e}");
        // Column centre: texel (5, 1).
        let d = latlong::texel_dir(w, h, 5, 1);
        let e = m.eval(d);
        assert!((e.x - 5.0).abs() < 1e-4 && (e.y - 1.0).abs() < 1e-4);
        // Horizontal wrap: u = 0 (-Z) is halfway between the last and first column.
        let e = m.eval(-Vec3::Z + Vec3::new(0.0, 1e-7, 0.0));
        assert!((e.x - 3.5).abs() < 1e-4, "{e}");
    }

    #[test]
    fn integral_of_smooth_function_converges() {
        // int (1 + x) dw = 4 pi for every layout; quadrature error shrinks with resolution.
        let f = |d: Vec3| Vec3::splat(1.0 + d.x + d.y * d.y);
        let exact = 4.0 * PI + 4.0 * PI / 3.0;
        for m in [
            EnvMap::latlong_from_fn(256, 129, f),
            EnvMap::cube_from_fn(64, f),
            EnvMap::probe_from_fn(256, f),
        ] {
            let i = m.integral().x as f64;
            assert!(
                (i - exact).abs() < 2e-3 * exact,
                "{:?}: {i} vs {exact}",
                m.layout()
            );
        }
    }

    #[test]
    fn to_latlong_preserves_smooth_maps() {
        let mut rng = Rng::new(1, 2);
        for m in [
            EnvMap::cube_from_fn(32, pattern),
            EnvMap::probe_from_fn(64, pattern),
        ] {
            let ll = m.to_latlong(64, 33);
            assert_eq!(ll.layout(), EnvLayout::LatLong);
            for _ in 0..200 {
                let d = crate::warp::square_to_uniform_sphere(rng.next_vec2());
                let (a, b) = (ll.eval(d), pattern(d));
                // Two bilinear resamplings of a smooth function at 32-64 texels per 2 pi.
                assert!(
                    (a - b).abs().max_element() < 0.08,
                    "{:?} {d}: {a} vs {b}",
                    m.layout()
                );
            }
        }
    }

    #[test]
    fn luminance_rec709() {
        assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-6);
        assert_eq!(luminance(Vec3::new(0.0, 1.0, 0.0)), 0.7152);
        let m = EnvMap::constant(Vec3::new(2.0, 2.0, 2.0));
        assert!((m.average_luminance() - 2.0).abs() < 1e-5);
        assert!((m.max_luminance() - 2.0).abs() < 1e-6);
    }
}
