//! CPU triangle rasteriser for per-vertex radiance (Gouraud shading of PRT results), and the
//! same rasteriser as a G-buffer (visibility buffer) for deferred shading: [`gbuffer`] stores
//! each sample's [`Fragment`] (triangle, perspective-correct barycentrics, world position,
//! shading and geometric normals); [`render_deferred`] shades fragments band by band with a
//! closure (the hybrid renderer's pass). All three entry points share one triangle setup,
//! binning and sample loop; they differ only in the per-corner attribute interpolated
//! (radiance, or the corner's barycentric unit vector) and in the resolve.
//!
//! Conventions:
//! * Camera: Mitsuba 3's `perspective` sensor ([`Camera::frame`]); continuous pixel coordinates
//!   have `x` from the left and `y` from the top, pixel `(j, i)` spans `[j, j+1) x [i, i+1)`
//!   and its centre is `(j + 0.5, i + 0.5)`.
//! * Sampling: one sample at each pixel centre by default; with `supersample = n` an `n x n`
//!   grid of sub-pixel centres `(j + (a + 0.5)/n, i + (b + 0.5)/n)` averaged with equal weights
//!   (a box filter). The Mitsuba references (`tools/mitsuba_reference.py`) use a `box`
//!   reconstruction filter, which averages radiance over the whole pixel, so silhouettes match
//!   them only with supersampling (use 4).
//! * Visibility: z-buffer on view depth (distance along the camera's forward axis), nearest
//!   wins, ties go to the triangle that comes first in the mesh. No back-face culling: which
//!   side of a one-sided surface is lit is already in the vertex radiance.
//! * Coverage rule: a sample exactly on an edge or vertex is decided as if it were moved by an
//!   infinitesimal `(-e, e^2)` (left, then down), so a sample on an edge shared by two triangles,
//!   or on a vertex shared by a closed fan, is covered exactly once.
//! * Interpolation: per-vertex radiance is interpolated perspective-correctly (linear in world
//!   space over the triangle): `c = (sum_i w_i c_i / z_i) / (sum_i w_i / z_i)` with screen-space
//!   barycentrics `w_i` and view depths `z_i`.
//! * Near plane: triangles are clipped in camera space at `z = 1e-5 x` (largest vertex
//!   distance from the eye); there is no far plane.
//! * Background: samples not covered by any triangle get the environment radiance arriving
//!   through that sample's position (the pixel centre without supersampling), black without an
//!   environment.
//! * Threads: the image is split into bands of rows rendered in parallel with rayon; the result
//!   does not depend on the number of threads.

use crate::image::Image;
use glam::Vec3;
use rayon::prelude::*;
use relight_scene::camera::{Camera, CameraFrame};
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;

/// Options of [`render_with`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RasterOptions {
    /// Samples per pixel along each axis (`n x n` per pixel); 1 = pixel centre only.
    pub supersample: u32,
}

impl Default for RasterOptions {
    /// One sample per pixel, at its centre.
    fn default() -> Self {
        RasterOptions { supersample: 1 }
    }
}

/// An image and the fraction of each pixel's samples covered by geometry.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Linear radiance.
    pub image: Image,
    /// Per pixel, covered samples / all samples, in `[0, 1]` (row-major like the image).
    pub coverage: Vec<f32>,
}

impl Rendered {
    /// Pixels entirely covered by geometry: a mask for [`crate::compare::metrics`] that leaves
    /// out the background and the silhouette pixels.
    pub fn full_coverage_mask(&self) -> Vec<bool> {
        self.coverage.iter().map(|&c| c >= 1.0).collect()
    }
}

/// Rasterise `mesh` with per-vertex radiance, one sample per pixel centre (see the module docs).
///
/// # Panics
/// If `vertex_radiance.len() != mesh.vertex_count()`.
pub fn render(
    mesh: &TriMesh,
    camera: &Camera,
    vertex_radiance: &[Vec3],
    background: Option<&Environment>,
) -> Image {
    render_with(
        mesh,
        camera,
        vertex_radiance,
        background,
        &RasterOptions::default(),
    )
    .image
}

/// Rasterise with options (supersampling); also returns per-pixel coverage.
///
/// # Panics
/// If `vertex_radiance.len() != mesh.vertex_count()`, `opts.supersample == 0` or the camera's
/// image is empty.
pub fn render_with(
    mesh: &TriMesh,
    camera: &Camera,
    vertex_radiance: &[Vec3],
    background: Option<&Environment>,
    opts: &RasterOptions,
) -> Rendered {
    assert_eq!(
        vertex_radiance.len(),
        mesh.vertex_count(),
        "one radiance value per vertex is required"
    );
    let frame = camera.frame();
    let ss = opts.supersample as usize;
    let px = rasterise(
        mesh,
        &frame,
        Corner::Vertex(vertex_radiance),
        opts.supersample,
        |row0, rows, s: &Samples, out: &mut [(Vec3, f32)]| {
            resolve(row0, rows, ss, &frame, background, s, out, |k| s.attr[k])
        },
    );
    split(px, frame.width as usize, frame.height as usize)
}

/// One visible surface sample of a G-buffer: what a deferred shader needs.
///
/// All vertex attributes are interpolated perspective-correctly (linear in world space over
/// the triangle, see the module docs), so any per-vertex value is
/// [`Fragment::interpolate`]d exactly when it is linear over the triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    /// Mesh triangle index.
    pub tri: u32,
    /// Weights of the triangle's three corners (`mesh.indices[tri]` order), summing to 1.
    pub bary: [f32; 3],
    /// World position.
    pub position: Vec3,
    /// Interpolated vertex normal, normalised (the geometric normal if it vanishes).
    pub shading_normal: Vec3,
    /// Unit geometric normal of the triangle (its winding's side; zero if degenerate).
    pub geometric_normal: Vec3,
}

impl Fragment {
    /// Interpolate a per-vertex value (PRT radiance, albedo, ...) at this fragment.
    ///
    /// # Panics
    /// If `values` is shorter than the mesh's vertex count.
    #[inline]
    pub fn interpolate(&self, mesh: &TriMesh, values: &[Vec3]) -> Vec3 {
        let [a, b, c] = mesh.indices[self.tri as usize];
        values[a as usize] * self.bary[0]
            + values[b as usize] * self.bary[1]
            + values[c as usize] * self.bary[2]
    }

    /// The fragment of triangle `tri` at perspective-correct corner weights `bary`.
    #[inline]
    fn new(mesh: &TriMesh, tri: u32, bary: Vec3) -> Fragment {
        let bary = (bary / bary.element_sum()).to_array();
        let [a, b, c] = mesh.indices[tri as usize].map(|i| i as usize);
        let p = &mesh.positions;
        let ng = mesh.geometric_normal(tri as usize);
        let n = mesh.normals[a] * bary[0] + mesh.normals[b] * bary[1] + mesh.normals[c] * bary[2];
        let n = n.normalize_or_zero();
        Fragment {
            tri,
            bary,
            position: p[a] * bary[0] + p[b] * bary[1] + p[c] * bary[2],
            shading_normal: if n == Vec3::ZERO { ng } else { n },
            geometric_normal: ng,
        }
    }
}

/// The visible fragment of every sample: `width x height` samples, row-major (the image
/// size times `supersample` along each axis), `None` where no triangle covers the sample.
#[derive(Clone, Debug)]
pub struct GBuffer {
    /// Samples per row (image width times `supersample`).
    pub width: usize,
    /// Sample rows (image height times `supersample`).
    pub height: usize,
    /// Samples per pixel along each axis.
    pub supersample: u32,
    /// Row-major samples.
    pub fragments: Vec<Option<Fragment>>,
}

/// Rasterise `mesh` into a G-buffer (a visibility buffer of [`Fragment`]s), one entry per
/// sample, with the same sample positions, coverage rule and depth test as [`render_with`].
///
/// # Panics
/// If `opts.supersample == 0` or the camera's image is empty.
pub fn gbuffer(mesh: &TriMesh, camera: &Camera, opts: &RasterOptions) -> GBuffer {
    let frame = camera.frame();
    let ss = opts.supersample as usize;
    let (w, h) = (frame.width as usize, frame.height as usize);
    // One "pixel" of `rasterise` output holds that pixel's `ss x ss` samples, row by row.
    let px = rasterise(
        mesh,
        &frame,
        Corner::Barycentric,
        opts.supersample,
        |_, rows, s: &Samples, out: &mut [Vec<Option<Fragment>>]| {
            for r in 0..rows {
                for x in 0..w {
                    out[r * w + x] = (0..ss * ss)
                        .map(|q| {
                            let k = (r * ss + q / ss) * w * ss + x * ss + q % ss;
                            (s.depth[k] > 0.0).then(|| Fragment::new(mesh, s.id[k], s.attr[k]))
                        })
                        .collect();
                }
            }
        },
    );
    let mut fragments = vec![None; w * h * ss * ss];
    for (p, samples) in px.into_iter().enumerate() {
        let (x, y) = (p % w, p / w);
        for (q, f) in samples.into_iter().enumerate() {
            fragments[(y * ss + q / ss) * w * ss + x * ss + q % ss] = f;
        }
    }
    GBuffer {
        width: w * ss,
        height: h * ss,
        supersample: opts.supersample,
        fragments,
    }
}

/// Deferred shading: rasterise visibility like [`render_with`], then call `shade` once per
/// covered sample with its [`Fragment`] and box-filter the results (uncovered samples get the
/// background, as in [`render_with`]). The shader runs in parallel over bands of rows, so it
/// must be `Sync`; no full-size G-buffer is ever stored.
///
/// # Panics
/// If `opts.supersample == 0` or the camera's image is empty.
pub fn render_deferred<F>(
    mesh: &TriMesh,
    camera: &Camera,
    background: Option<&Environment>,
    opts: &RasterOptions,
    shade: F,
) -> Rendered
where
    F: Fn(&Fragment) -> Vec3 + Sync,
{
    let frame = camera.frame();
    let ss = opts.supersample as usize;
    let px = rasterise(
        mesh,
        &frame,
        Corner::Barycentric,
        opts.supersample,
        |row0, rows, s: &Samples, out: &mut [(Vec3, f32)]| {
            resolve(row0, rows, ss, &frame, background, s, out, |k| {
                shade(&Fragment::new(mesh, s.id[k], s.attr[k]))
            })
        },
    );
    split(px, frame.width as usize, frame.height as usize)
}

/// Deferred shading by triangle: like [`render_deferred`], but within each band of rows the
/// covered samples are grouped by triangle and `shade` is called once per (band, triangle)
/// with all of that triangle's fragments, filling one radiance per fragment. A shader with
/// per-triangle set-up (the `cuts` renderer merges its triangle's three vertex cuts once)
/// pays it once per band instead of once per sample. Same samples, coverage and resolve as
/// [`render_deferred`]: with a shader that treats fragments independently both give the same
/// image.
///
/// # Panics
/// If `opts.supersample == 0` or the camera's image is empty, or if `shade` leaves its
/// output slice's length unchanged is violated (debug).
pub fn render_deferred_batched<F>(
    mesh: &TriMesh,
    camera: &Camera,
    background: Option<&Environment>,
    opts: &RasterOptions,
    shade: F,
) -> Rendered
where
    F: Fn(u32, &[Fragment], &mut [Vec3]) + Sync,
{
    let frame = camera.frame();
    let ss = opts.supersample as usize;
    let px = rasterise(
        mesh,
        &frame,
        Corner::Barycentric,
        opts.supersample,
        |row0, rows, s: &Samples, out: &mut [(Vec3, f32)]| {
            // Covered samples sorted by triangle (stable: sample order within a triangle).
            let mut covered: Vec<u32> = (0..s.depth.len() as u32)
                .filter(|&k| s.depth[k as usize] > 0.0)
                .collect();
            covered.sort_by_key(|&k| s.id[k as usize]);
            let mut color = vec![Vec3::ZERO; s.depth.len()];
            let (mut frags, mut radiance) = (Vec::new(), Vec::new());
            for run in covered.chunk_by(|&a, &b| s.id[a as usize] == s.id[b as usize]) {
                let tri = s.id[run[0] as usize];
                frags.clear();
                frags.extend(
                    run.iter()
                        .map(|&k| Fragment::new(mesh, tri, s.attr[k as usize])),
                );
                radiance.clear();
                radiance.resize(run.len(), Vec3::ZERO);
                shade(tri, &frags, &mut radiance);
                for (&k, &c) in run.iter().zip(&radiance) {
                    color[k as usize] = c;
                }
            }
            resolve(row0, rows, ss, &frame, background, s, out, |k| color[k])
        },
    );
    split(px, frame.width as usize, frame.height as usize)
}

/// Split resolved `(radiance, coverage)` pixels into a [`Rendered`].
fn split(px: Vec<(Vec3, f32)>, w: usize, h: usize) -> Rendered {
    let (pixels, coverage) = px.into_iter().unzip();
    Rendered {
        image: Image {
            width: w,
            height: h,
            pixels,
        },
        coverage,
    }
}

/// Rows of image per band of the parallel rasteriser.
const BAND: usize = 8;

/// The shared front end: transform, bin and rasterise `mesh` band by band in parallel with
/// per-corner attributes `attr`, handing each band's sample buffers to `per_band(row0, rows,
/// samples, out)` which fills that band's `rows * width` output pixels.
fn rasterise<T, B>(
    mesh: &TriMesh,
    frame: &CameraFrame,
    attr: Corner<'_>,
    supersample: u32,
    per_band: B,
) -> Vec<T>
where
    T: Default + Clone + Send,
    B: Fn(usize, usize, &Samples, &mut [T]) + Sync,
{
    assert!(supersample >= 1, "supersample must be at least 1");
    let ss = supersample as usize;
    let (w, h) = (frame.width as usize, frame.height as usize);
    assert!(w > 0 && h > 0, "empty image {w}x{h}");

    // Transform vertices to camera space once.
    let cam: Vec<Vec3> = mesh
        .positions
        .par_iter()
        .map(|&p| {
            let d = p - frame.origin;
            Vec3::new(d.dot(frame.right), d.dot(frame.up), d.dot(frame.forward))
        })
        .collect();
    let far = cam.iter().fold(0.0f32, |m, c| m.max(c.length()));
    let near = (1e-5 * far).max(f32::MIN_POSITIVE);
    let setup = Setup {
        cam: &cam,
        attr,
        frame: *frame,
        scale: ss as f32,
        near,
    };

    // Bin triangle indices (in mesh order, which keeps the depth tie rule) by the bands of
    // image rows their screen bounding boxes touch, dropping those entirely off screen. Bands
    // set their triangles up themselves: no per-triangle array as large as the mesh.
    let bands = h.div_ceil(BAND);
    let ranges: Vec<Option<(u32, u32)>> = mesh
        .indices
        .par_iter()
        .map(|&tri| setup.band_range(tri, w, h, BAND))
        .collect();
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (i, r) in ranges.iter().enumerate() {
        if let Some((b0, b1)) = *r {
            for bin in &mut bins[b0 as usize..=b1 as usize] {
                bin.push(i as u32);
            }
        }
    }

    // Rasterise bands of image rows in parallel; each band owns its samples.
    let mut out = vec![T::default(); w * h];
    out.par_chunks_mut(w * BAND)
        .enumerate()
        .for_each(|(band, out)| {
            let tris = bins[band]
                .iter()
                .flat_map(|&i| setup.triangle(i, mesh.indices[i as usize]));
            let rows = out.len() / w;
            let samples = raster_samples(tris, band * BAND * ss, rows * ss, w * ss);
            per_band(band * BAND, rows, &samples, out);
        });
    out
}

/// Where the interpolated per-sample attribute comes from.
#[derive(Clone, Copy, Debug)]
enum Corner<'a> {
    /// A per-vertex value (radiance).
    Vertex(&'a [Vec3]),
    /// The corner's unit barycentric vector: the sample gets its perspective-correct weights.
    Barycentric,
}

/// A projected triangle in sample-grid coordinates (pixel coordinates times `supersample`),
/// counter-clockwise on screen (positive `area`).
#[derive(Clone, Copy, Debug)]
struct ScreenTri {
    /// Mesh triangle index.
    id: u32,
    x: [f32; 3],
    y: [f32; 3],
    /// `1 / z` per vertex.
    iz: [f32; 3],
    /// Attribute divided by `z` per vertex.
    ciz: [Vec3; 3],
    /// Twice the signed area (> 0).
    area: f32,
    ymin: f32,
    ymax: f32,
}

/// Everything needed to turn mesh triangles into screen triangles.
struct Setup<'a> {
    /// Camera-space vertex positions (x right, y up, z forward).
    cam: &'a [Vec3],
    attr: Corner<'a>,
    frame: CameraFrame,
    /// Samples per pixel along each axis.
    scale: f32,
    near: f32,
}

impl Setup<'_> {
    /// Sample-grid coordinates, `1/z` and attribute over `z` of a camera-space point.
    #[inline]
    fn project(&self, (p, c): (Vec3, Vec3)) -> (f32, f32, f32, Vec3) {
        let f = &self.frame;
        let sx = p.x / (p.z * f.tan_half_x);
        let sy = p.y / (p.z * f.tan_half_y);
        let x = (sx + 1.0) * 0.5 * f.width as f32 * self.scale;
        let y = (1.0 - sy) * 0.5 * f.height as f32 * self.scale;
        (x, y, 1.0 / p.z, c / p.z)
    }

    /// First and last band of `band` image rows that triangle `tri` may cover; `None` when it
    /// is off screen. Triangles crossing the near plane conservatively span every band.
    fn band_range(&self, tri: [u32; 3], w: usize, h: usize, band: usize) -> Option<(u32, u32)> {
        let last = (h.div_ceil(band) - 1) as u32;
        let p = tri.map(|i| self.cam[i as usize]);
        if p.iter().all(|q| q.z < self.near) {
            return None;
        }
        if p.iter().any(|q| q.z < self.near) {
            return Some((0, last));
        }
        let s = p.map(|q| self.project((q, Vec3::ZERO)));
        let (xmin, xmax) = (
            s[0].0.min(s[1].0).min(s[2].0),
            s[0].0.max(s[1].0).max(s[2].0),
        );
        let (ymin, ymax) = (
            s[0].1.min(s[1].1).min(s[2].1),
            s[0].1.max(s[1].1).max(s[2].1),
        );
        let (sw, sh) = (w as f32 * self.scale, h as f32 * self.scale);
        if !(xmax >= 0.0 && xmin <= sw && ymax >= 0.0 && ymin <= sh) {
            return None; // off screen, or NaN
        }
        let rows = band as f32 * self.scale;
        let b0 = ((ymin.max(0.0) / rows) as u32).min(last);
        let b1 = ((ymax.min(sh) / rows) as u32).min(last);
        Some((b0, b1))
    }

    /// Clip mesh triangle `tri` (index `id`) at the near plane, project it and emit 0, 1 or 2
    /// screen triangles.
    fn triangle(&self, id: u32, tri: [u32; 3]) -> impl Iterator<Item = ScreenTri> {
        let corner = |k: usize| match self.attr {
            Corner::Vertex(v) => v[tri[k] as usize],
            Corner::Barycentric => Vec3::AXES[k],
        };
        let v = [0, 1, 2].map(|k| (self.cam[tri[k] as usize], corner(k)));
        // Common case: entirely in front of the near plane.
        let out = if v.iter().all(|(p, _)| p.z >= self.near) {
            [make_tri(id, v.map(|q| self.project(q))), None]
        } else {
            self.clipped(id, v)
        };
        out.into_iter().flatten()
    }

    /// Sutherland-Hodgman against `z >= near`; attributes interpolate linearly in camera
    /// space. At most 4 vertices remain: a fan of at most 2 triangles.
    fn clipped(&self, id: u32, v: [(Vec3, Vec3); 3]) -> [Option<ScreenTri>; 2] {
        let mut poly: [(Vec3, Vec3); 4] = [(Vec3::Z, Vec3::ZERO); 4];
        let mut n = 0;
        for i in 0..3 {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            let (ina, inb) = (a.0.z >= self.near, b.0.z >= self.near);
            if ina {
                poly[n] = a;
                n += 1;
            }
            if ina != inb {
                let t = (self.near - a.0.z) / (b.0.z - a.0.z);
                poly[n] = (a.0.lerp(b.0, t), a.1.lerp(b.1, t));
                poly[n].0.z = self.near;
                n += 1;
            }
        }
        let p = poly.map(|q| self.project(q));
        match n {
            3 => [make_tri(id, [p[0], p[1], p[2]]), None],
            4 => [
                make_tri(id, [p[0], p[1], p[2]]),
                make_tri(id, [p[0], p[2], p[3]]),
            ],
            _ => [None, None],
        }
    }
}

/// Orient a projected triangle counter-clockwise on screen; `None` if degenerate or not finite.
fn make_tri(id: u32, mut v: [(f32, f32, f32, Vec3); 3]) -> Option<ScreenTri> {
    let mut area = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[1].1 - v[0].1) * (v[2].0 - v[0].0);
    if area < 0.0 {
        v.swap(1, 2);
        area = -area;
    }
    if !(area > 0.0 && area.is_finite()) {
        return None;
    }
    let y = [v[0].1, v[1].1, v[2].1];
    Some(ScreenTri {
        id,
        x: [v[0].0, v[1].0, v[2].0],
        y,
        iz: [v[0].2, v[1].2, v[2].2],
        ciz: [v[0].3, v[1].3, v[2].3],
        area,
        ymin: y[0].min(y[1]).min(y[2]),
        ymax: y[0].max(y[1]).max(y[2]),
    })
}

/// Edge function of edge `a -> b` at `p`, positive on the inside of a counter-clockwise
/// triangle, with the tie-breaking rule of the module docs folded in (`None` = outside).
#[inline]
fn edge(ax: f32, ay: f32, bx: f32, by: f32, px: f32, py: f32) -> Option<f32> {
    let (dx, dy) = (bx - ax, by - ay);
    let e = dx * (py - ay) - dy * (px - ax);
    if e > 0.0 || (e == 0.0 && (dy > 0.0 || (dy == 0.0 && dx > 0.0))) {
        Some(e)
    } else {
        None
    }
}

/// The sample buffers of one band: `1/z` (0 = nothing drawn), interpolated attribute and
/// mesh triangle index of the nearest triangle per sample, row-major over the band.
struct Samples {
    depth: Vec<f32>,
    attr: Vec<Vec3>,
    id: Vec<u32>,
}

/// Rasterise `tris` in order into the sample rows `[s0, s0 + sh)` of width `sw` (z-buffer,
/// coverage rule of the module docs).
fn raster_samples(
    tris: impl Iterator<Item = ScreenTri>,
    s0: usize,
    sh: usize,
    sw: usize,
) -> Samples {
    let mut depth = vec![0.0f32; sw * sh]; // 1/z; 0 = nothing drawn
    let mut attr = vec![Vec3::ZERO; sw * sh];
    let mut id = vec![0u32; sw * sh];
    let (band_lo, band_hi) = (s0 as f32, (s0 + sh) as f32);

    for t in tris {
        if t.ymax < band_lo || t.ymin > band_hi {
            continue;
        }
        // Sample rows/columns whose centres (index + 0.5) may lie inside the bounding box.
        let y_first = ((t.ymin - 0.5).ceil().max(band_lo)) as usize;
        let y_last = ((t.ymax - 0.5).floor().min(band_hi - 1.0)).max(-1.0);
        let xmin = t.x[0].min(t.x[1]).min(t.x[2]);
        let xmax = t.x[0].max(t.x[1]).max(t.x[2]);
        let x_first = (xmin - 0.5).ceil().max(0.0) as usize;
        let x_last = (xmax - 0.5).floor().min(sw as f32 - 1.0);
        if y_last < y_first as f32 || x_last < x_first as f32 {
            continue;
        }
        let inv_area = 1.0 / t.area;
        for sy in y_first..=y_last as usize {
            let py = sy as f32 + 0.5;
            let row = (sy - s0) * sw;
            for sx in x_first..=x_last as usize {
                let px = sx as f32 + 0.5;
                let Some(e0) = edge(t.x[1], t.y[1], t.x[2], t.y[2], px, py) else {
                    continue;
                };
                let Some(e1) = edge(t.x[2], t.y[2], t.x[0], t.y[0], px, py) else {
                    continue;
                };
                let Some(e2) = edge(t.x[0], t.y[0], t.x[1], t.y[1], px, py) else {
                    continue;
                };
                let (w0, w1, w2) = (e0 * inv_area, e1 * inv_area, e2 * inv_area);
                let iz = w0 * t.iz[0] + w1 * t.iz[1] + w2 * t.iz[2];
                let k = row + sx;
                if iz > depth[k] {
                    depth[k] = iz;
                    attr[k] = (t.ciz[0] * w0 + t.ciz[1] * w1 + t.ciz[2] * w2) / iz;
                    id[k] = t.id;
                }
            }
        }
    }
    Samples { depth, attr, id }
}

/// Resolve image rows `[row0, row0 + rows)` of width `out.len() / rows`: box-filter the
/// samples of each pixel, `color(k)` for covered sample `k`, the background where uncovered.
#[allow(clippy::too_many_arguments)]
fn resolve(
    row0: usize,
    rows: usize,
    ss: usize,
    frame: &CameraFrame,
    background: Option<&Environment>,
    s: &Samples,
    out: &mut [(Vec3, f32)],
    color: impl Fn(usize) -> Vec3,
) {
    let w = out.len() / rows;
    let sw = w * ss;
    let inv_n = 1.0 / (ss * ss) as f32;
    for r in 0..rows {
        for x in 0..w {
            let (mut sum, mut covered) = (Vec3::ZERO, 0usize);
            for b in 0..ss {
                for a in 0..ss {
                    let k = (r * ss + b) * sw + x * ss + a;
                    if s.depth[k] > 0.0 {
                        sum += color(k);
                        covered += 1;
                    } else if let Some(env) = background {
                        let fx = x as f32 + (a as f32 + 0.5) / ss as f32;
                        let fy = (row0 + r) as f32 + (b as f32 + 0.5) / ss as f32;
                        sum += env.radiance(frame.dir_at(fx, fy));
                    }
                }
            }
            out[r * w + x] = (sum * inv_n, covered as f32 * inv_n);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera at +5 Z looking at the origin, 90 degree fov: the plane z = 0 spans x, y in
    /// [-5, 5] across the 64 x 64 image.
    fn cam() -> Camera {
        Camera::look_at([0.0, 0.0, 5.0], [0.0, 0.0, 0.0], 90.0, 64, 64)
    }

    fn quad(corners: [Vec3; 4]) -> TriMesh {
        TriMesh {
            positions: corners.to_vec(),
            normals: vec![Vec3::Z; 4],
            uvs: None,
            indices: vec![[0, 1, 2], [0, 2, 3]],
            material_ids: vec![0, 0],
        }
    }

    #[test]
    fn camera_facing_quad_covers_exactly_the_expected_pixels() {
        // x in [-2.5, 2.5] maps to pixel columns [16, 48); y in [-1.25, 3.75] to rows [8, 40)
        // (row 0 at the top: y = 3.75 -> (1 - 0.75) 32 = 8, y = -1.25 -> (1 + 0.25) 32 = 40).
        // No pixel centre lies on an edge, so the covered set is unambiguous.
        let (x0, x1, y0, y1) = (-2.5, 2.5, -1.25, 3.75);
        let m = quad([
            Vec3::new(x0, y0, 0.0),
            Vec3::new(x1, y0, 0.0),
            Vec3::new(x1, y1, 0.0),
            Vec3::new(x0, y1, 0.0),
        ]);
        let img = render(&m, &cam(), &[Vec3::ONE; 4], None);
        for i in 0..64 {
            for j in 0..64 {
                let inside = (16..48).contains(&j) && (8..40).contains(&i);
                let v = img.get(j, i);
                assert_eq!(v == Vec3::ONE, inside, "pixel ({j}, {i}) = {v}");
                assert!(v == Vec3::ONE || v == Vec3::ZERO);
            }
        }
    }

    #[test]
    fn shared_edges_cover_each_sample_exactly_once() {
        // A fan of thin triangles around a centre on a pixel centre: accumulate coverage counts
        // by rendering each triangle alone.
        let c = Vec3::new(0.078125, 0.078125, 0.0); // pixel centre (32.5, 31.5)
        let n = 12;
        let mut counts = vec![0u32; 64 * 64];
        for k in 0..n {
            let a0 = k as f32 / n as f32 * std::f32::consts::TAU;
            let a1 = (k + 1) as f32 / n as f32 * std::f32::consts::TAU;
            let p = |a: f32| c + Vec3::new(a.cos(), a.sin(), 0.0) * 3.0;
            let m = TriMesh {
                positions: vec![c, p(a0), p(a1)],
                normals: vec![Vec3::Z; 3],
                uvs: None,
                indices: vec![[0, 1, 2]],
                material_ids: vec![0],
            };
            let r = render_with(&m, &cam(), &[Vec3::ONE; 3], None, &RasterOptions::default());
            for (cnt, &cv) in counts.iter_mut().zip(&r.coverage) {
                *cnt += cv as u32;
            }
        }
        assert!(counts.iter().all(|&c| c <= 1), "a sample was covered twice");
        assert_eq!(
            counts[31 * 64 + 32],
            1,
            "the shared centre sample is covered once"
        );
        // No holes: every pixel centre within 15 px of the fan's centre (radius 19.2 px).
        for i in 0..64 {
            for j in 0..64 {
                let (dx, dy) = (j as f32 - 32.0, i as f32 - 31.0);
                if dx * dx + dy * dy < 225.0 {
                    assert_eq!(counts[i * 64 + j], 1, "hole at ({j}, {i})");
                }
            }
        }
    }

    #[test]
    fn interpolation_of_a_linear_function_is_perspective_exact() {
        // A quad tilted away from the camera, radiance = affine function of world position.
        let f = |p: Vec3| {
            Vec3::new(
                0.3 * p.x + 0.1 * p.z + 1.0,
                0.5 * p.y - 0.2 * p.z + 2.0,
                p.z + 3.0,
            )
        };
        let corners = [
            Vec3::new(-3.0, -2.0, 2.0),
            Vec3::new(3.0, -2.0, 2.0),
            Vec3::new(3.0, 2.0, -6.0),
            Vec3::new(-3.0, 2.0, -6.0),
        ];
        let m = quad(corners);
        let rad: Vec<Vec3> = corners.iter().map(|&p| f(p)).collect();
        let camera = cam();
        let img = render(&m, &camera, &rad, None);
        let frame = camera.frame();
        let (n, p0) = (
            (corners[1] - corners[0])
                .cross(corners[3] - corners[0])
                .normalize(),
            corners[0],
        );
        let mut checked = 0;
        for i in 0..64 {
            for j in 0..64 {
                let v = img.get(j, i);
                if v == Vec3::ZERO {
                    continue;
                }
                // Intersect the pixel-centre ray with the quad's plane.
                let d = frame.dir_at(j as f32 + 0.5, i as f32 + 0.5);
                let t = (p0 - frame.origin).dot(n) / d.dot(n);
                let expect = f(frame.origin + d * t);
                // 2e-4: f32 rounding of the projection and the barycentric weights.
                assert!((v - expect).abs().max_element() < 2e-4 * expect.abs().max_element());
                checked += 1;
            }
        }
        assert!(checked > 500);
    }

    #[test]
    fn nearer_triangle_wins_in_either_order() {
        let sq = |z: f32, s: f32| {
            [
                Vec3::new(-s, -s, z),
                Vec3::new(s, -s, z),
                Vec3::new(s, s, z),
                Vec3::new(-s, s, z),
            ]
        };
        for near_first in [true, false] {
            let (a, b) = if near_first {
                (sq(1.0, 1.0), sq(-1.0, 3.0))
            } else {
                (sq(-1.0, 3.0), sq(1.0, 1.0))
            };
            let mut m = quad(a);
            m.append(&quad(b), 0);
            let red = Vec3::X;
            let blue = Vec3::Z;
            let rad = if near_first {
                [[red; 4], [blue; 4]]
            } else {
                [[blue; 4], [red; 4]]
            }
            .concat();
            let img = render(&m, &cam(), &rad, None);
            // Centre: the near (red) square; near the edge of the big one: blue.
            assert_eq!(img.get(32, 32), red);
            assert_eq!(img.get(32, 32 + 12), blue);
        }
    }

    #[test]
    fn supersampling_averages_partial_coverage_and_clips_behind_the_eye() {
        // A triangle crossing the camera plane must be clipped, not wrapped around.
        let m = TriMesh {
            positions: vec![
                Vec3::new(-2.0, -2.0, 0.0),
                Vec3::new(2.0, -2.0, 0.0),
                Vec3::new(0.0, -2.0, 10.0),
            ],
            normals: vec![Vec3::Y; 3],
            uvs: None,
            indices: vec![[0, 1, 2]],
            material_ids: vec![0],
        };
        let r = render_with(
            &m,
            &cam(),
            &[Vec3::ONE; 3],
            None,
            &RasterOptions { supersample: 4 },
        );
        // Everything drawn lies in the lower half (the floor below the eye).
        for i in 0..32 {
            for j in 0..64 {
                assert_eq!(r.coverage[i * 64 + j], 0.0, "({j},{i})");
            }
        }
        assert!(
            r.coverage.iter().any(|&c| c > 0.0 && c < 1.0),
            "silhouettes are fractional"
        );
        for (c, p) in r.coverage.iter().zip(&r.image.pixels) {
            // 1e-6: radiance 1 times coverage, f32 averaging of 16 samples.
            assert!((p.x - c).abs() < 1e-6);
        }
    }

    #[test]
    fn end_to_end_bake_shade_render_under_a_constant_environment() {
        // Unshadowed transfer of a sphere under radiance 1 everywhere gives L_o = albedo at
        // every vertex; the background shows the environment itself.
        use relight_bake::sh::{bake, ShBakeSettings, ShTransferKind};
        use relight_scene::material::Material;
        use relight_sphere::envmap::EnvMap;
        let mesh = relight_scene::shapes::uv_sphere(Vec3::ZERO, 2.0, 16, 32);
        let caster = relight_scene::accel::build_default(&mesh);
        let settings = ShBakeSettings {
            order: 3,
            transfer: ShTransferKind::Unshadowed,
            ..Default::default()
        };
        let albedo = Vec3::new(0.2, 0.5, 0.8);
        let t = bake(
            &mesh,
            &[Material::Lambert { albedo }],
            caster.as_ref(),
            &settings,
        )
        .unwrap();
        let map = EnvMap::constant(Vec3::ONE);
        let light = relight_sphere::sh::project_env(&map, 3);
        let rad = crate::shade_sh::shade(&t, Some(&vec![albedo; mesh.vertex_count()]), &light);
        let env = Environment::new(map);
        let img = render(&mesh, &cam(), &rad, Some(&env));
        // 1e-3: the SH projection of the constant map is a quadrature over its texels.
        assert!(
            (img.get(32, 32) - albedo).abs().max_element() < 1e-3,
            "{}",
            img.get(32, 32)
        );
        assert!(
            (img.get(1, 1) - Vec3::ONE).abs().max_element() < 1e-3,
            "{}",
            img.get(1, 1)
        );
    }

    #[test]
    fn prt_render_agrees_with_the_path_tracer() {
        // Sphere on a plane under a smooth, asymmetric environment (nearly band-limited to
        // order 3), direct light only and with interreflections, against the reference path
        // tracer at the same settings. Checks that bake, SH projection, shading and raster
        // share one set of conventions (env orientation, 1/pi, albedo).
        use relight_bake::sh::{bake, ShBakeSettings, ShTransferKind};
        use relight_scene::material::Material;
        use relight_sphere::envmap::EnvMap;
        let mut mesh = relight_scene::shapes::uv_sphere(Vec3::new(0.0, 1.0, 0.0), 1.0, 24, 48);
        mesh.append(&relight_scene::shapes::ground_plane(Vec3::ZERO, 8.0, 32), 0);
        let mats = vec![Material::Lambert {
            albedo: Vec3::splat(0.6),
        }];
        let caster = relight_scene::accel::build_default(&mesh);
        let f = |d: Vec3| {
            Vec3::new(
                1.0 + 0.8 * d.x + 0.5 * d.y,
                1.0 + 0.6 * d.y - 0.3 * d.z,
                1.0 + 0.4 * d.z,
            )
        };
        let map = EnvMap::latlong_from_fn(128, 65, f);
        let camera = Camera::look_at([3.0, 2.5, 4.0], [0.0, 0.8, 0.0], 40.0, 64, 48);
        let scene = relight_scene::scene::Scene {
            maps: Default::default(),
            mesh: mesh.clone(),
            materials: mats.clone(),
            env: Environment::new(map.clone()),
            camera,
            objects: Vec::new(),
        };
        let light = relight_sphere::sh::project_env(&map, 3);
        let albedo = relight_bake::transport::vertex_albedo(&mesh, &mats);
        for (transfer, bounces, max_depth) in [
            (ShTransferKind::Shadowed, 0, 2),
            (ShTransferKind::Interreflected, 3, 5),
        ] {
            let s = ShBakeSettings {
                order: 3,
                samples: 256,
                transfer,
                bounces,
                ..Default::default()
            };
            let t = bake(&mesh, &mats, caster.as_ref(), &s).unwrap();
            let rad = crate::shade_sh::shade(&t, Some(&albedo), &light);
            let opts = RasterOptions { supersample: 2 };
            let r = render_with(&mesh, &camera, &rad, Some(&scene.env), &opts);
            let pts = crate::pathtrace::PtSettings {
                spp: 64,
                max_depth,
                ..Default::default()
            };
            let (pt, var) = crate::pathtrace::render_with_variance(&scene, caster.as_ref(), &pts);
            let mask = r.full_coverage_mask();
            // Remove the path tracer's own noise (its variance of the mean, per pixel and
            // channel) from the squared error: what is left is the bias of PRT + raster.
            let bias = |img: &Image| {
                let m = crate::compare::metrics(img, &pt, Some(&mask));
                let noise2 = var
                    .pixels
                    .iter()
                    .zip(&mask)
                    .filter(|(_, &k)| k)
                    .map(|(v, _)| v.element_sum() as f64)
                    .sum::<f64>()
                    / (3 * m.pixels) as f64;
                let rms_ref = m.rmse / m.rel_rmse;
                ((m.rmse * m.rmse - noise2).max(0.0).sqrt() / rms_ref, m)
            };
            let (b, m) = bias(&r.image);
            // 3% relative: per-vertex interpolation of the contact shadow, the bake's own
            // noise and the environment's slight energy above order 3. A mirrored environment
            // or a lost 1/pi gives well over 20%.
            assert!(b < 0.03, "{transfer:?}: bias {b} {m:?}");
            // Mirroring the lighting (negating band 1) must be detected.
            let mut wrong = light.clone();
            wrong[1..4].iter_mut().for_each(|c| *c = -*c);
            let rad = crate::shade_sh::shade(&t, Some(&albedo), &wrong);
            let r = render_with(&mesh, &camera, &rad, Some(&scene.env), &opts);
            let (b, m) = bias(&r.image);
            assert!(
                b > 0.2,
                "{transfer:?}: mirrored light not detected: bias {b} {m:?}"
            );
        }
    }

    fn tilted_quad() -> (TriMesh, Camera) {
        let corners = [
            Vec3::new(-3.0, -2.0, 2.0),
            Vec3::new(3.0, -2.0, 2.0),
            Vec3::new(3.0, 2.0, -6.0),
            Vec3::new(-3.0, 2.0, -6.0),
        ];
        let n = (corners[1] - corners[0])
            .cross(corners[3] - corners[0])
            .normalize();
        let mesh = TriMesh {
            positions: corners.to_vec(),
            // Vertex normals that vary linearly (unnormalised) to test their interpolation.
            normals: vec![n, n + Vec3::X * 0.5, n, n - Vec3::X * 0.5],
            uvs: None,
            indices: vec![[0, 1, 2], [0, 2, 3]],
            material_ids: vec![0, 0],
        };
        let camera = Camera::look_at([0.0, 0.0, 5.0], [0.0, 0.0, 0.0], 90.0, 48, 40);
        (mesh, camera)
    }

    #[test]
    fn gbuffer_interpolation_is_exact_for_linear_attributes() {
        let (mesh, camera) = tilted_quad();
        let f = |p: Vec3| {
            Vec3::new(
                0.3 * p.x + 0.1 * p.z + 1.0,
                0.5 * p.y - 0.2 * p.z,
                p.z + 3.0,
            )
        };
        let values: Vec<Vec3> = mesh.positions.iter().map(|&p| f(p)).collect();
        let opts = RasterOptions { supersample: 2 };
        let g = gbuffer(&mesh, &camera, &opts);
        assert_eq!((g.width, g.height), (96, 80));
        let frame = camera.frame();
        let (p0, ng) = (mesh.positions[0], mesh.geometric_normal(0));
        let mut checked = 0;
        for y in 0..g.height {
            for x in 0..g.width {
                let Some(fr) = g.fragments[y * g.width + x] else {
                    continue;
                };
                // The sample's ray meets the quad's plane at the fragment's position.
                let d = frame.dir_at((x as f32 + 0.5) / 2.0, (y as f32 + 0.5) / 2.0);
                let hit = frame.origin + d * ((p0 - frame.origin).dot(ng) / d.dot(ng));
                // 2e-4 (relative to the scene size ~6): f32 projection and barycentrics.
                assert!(
                    (fr.position - hit).length() < 2e-4 * 6.0,
                    "{} vs {hit}",
                    fr.position
                );
                let v = fr.interpolate(&mesh, &values);
                assert!(
                    (v - f(hit)).abs().max_element() < 2e-4 * f(hit).abs().max_element().max(1.0)
                );
                assert!((fr.geometric_normal.abs() - ng.abs()).length() < 1e-6);
                assert!((fr.shading_normal.length() - 1.0).abs() < 1e-5);
                assert!((fr.bary.iter().sum::<f32>() - 1.0).abs() < 1e-6);
                checked += 1;
            }
        }
        assert!(checked > 2000, "{checked}");
    }

    #[test]
    fn deferred_shading_of_vertex_radiance_matches_render_with() {
        let (mesh, camera) = tilted_quad();
        let rad: Vec<Vec3> = mesh.positions.iter().map(|p| p.abs() + Vec3::ONE).collect();
        for ss in [1, 3] {
            let opts = RasterOptions { supersample: ss };
            let a = render_with(&mesh, &camera, &rad, None, &opts);
            let b = render_deferred(&mesh, &camera, None, &opts, |f| f.interpolate(&mesh, &rad));
            assert_eq!(a.coverage, b.coverage, "same samples covered");
            for (p, q) in a.image.pixels.iter().zip(&b.image.pixels) {
                // 1e-5 relative: the two interpolate in a different order (f32 rounding).
                assert!((*p - *q).abs().max_element() <= 1e-5 * p.max_element().max(1.0));
            }
            // The G-buffer covers exactly the same samples.
            let g = gbuffer(&mesh, &camera, &opts);
            let n = ss as usize;
            for (k, c) in a.coverage.iter().enumerate() {
                let (x, y) = (k % 48, k / 48);
                let cov = (0..n * n)
                    .filter(|q| g.fragments[(y * n + q / n) * g.width + x * n + q % n].is_some())
                    .count();
                assert_eq!(cov as f32 / (n * n) as f32, *c);
            }
        }
    }

    #[test]
    fn batched_deferred_shading_equals_per_fragment_shading() {
        let (mesh, camera) = tilted_quad();
        let shade = |f: &Fragment| f.position.abs() + Vec3::from_array(f.bary) * (f.tri + 1) as f32;
        for ss in [1, 2] {
            let opts = RasterOptions { supersample: ss };
            let a = render_deferred(&mesh, &camera, None, &opts, shade);
            let calls = std::sync::atomic::AtomicUsize::new(0);
            let b = render_deferred_batched(&mesh, &camera, None, &opts, |tri, fs, out| {
                calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                for (f, o) in fs.iter().zip(out) {
                    assert_eq!(f.tri, tri, "a batch holds one triangle");
                    *o = shade(f);
                }
            });
            assert_eq!(a.coverage, b.coverage);
            assert_eq!(a.image.pixels, b.image.pixels, "bit-identical");
            // Batches are per (band, triangle): far fewer calls than covered samples.
            let samples: f32 = a.coverage.iter().sum::<f32>() * (ss * ss) as f32;
            let calls = calls.into_inner();
            assert!(
                calls > 0 && (calls as f32) < samples / 4.0,
                "{calls} vs {samples}"
            );
        }
    }
}
