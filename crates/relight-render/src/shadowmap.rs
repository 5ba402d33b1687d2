//! Orthographic shadow maps for distant (directional and small-cap) lights, with
//! percentage-closer filtering and a PCSS-style penumbra for lights of finite angular size.
//!
//! This is the shadow pass of the thesis' hybrid renderer (hybrid-environment-illumination
//! thesis, section 4.4 and Figure 4.6: one shadow map per extracted light, PCF-filtered).
//!
//! Conventions:
//! * Light frame: `dir` is the unit world direction *towards* the light; `(u, v)` is any
//!   orthonormal pair completing it. The map covers the square `[-half, half]^2` in `(u, v)`
//!   around the centre of the mesh's bounding box, `half` = half its diagonal, so the whole
//!   mesh projects inside the map for every direction.
//! * Map coordinates `(s, t)` are continuous texel units: texel `(j, i)` (column `j`, row `i`)
//!   spans `[j, j+1) x [i, i+1)` and its centre is `(j + 0.5, i + 0.5)`.
//! * Depth is the distance along `-dir` from the plane through the centre: `z(p) = -(p - c).dir`,
//!   so smaller is nearer the light. Each texel stores the least depth of the mesh at its centre
//!   (`+inf` where empty); depth is linear over a triangle in an orthographic view, so it is
//!   exact at texel centres.
//! * Bias: the receiver's depth is extrapolated to each tested texel centre along its plane
//!   (receiver-plane depth bias; Isidoro 2006), from the *geometric* normal, with the slope
//!   clamped to [`MAX_SLOPE`]; a texel then blocks if its depth is below the receiver's minus
//!   `depth_bias * texel * (1 + slope)` (slope-scaled constant bias).
//! * Filters: [`ShadowFilter::Pcf`] is the exact box filter of width `kernel` texels over the
//!   nearest-texel depth test (Reeves, Salesin & Cook 1987, "Rendering antialiased shadows
//!   with depth maps"). [`ShadowFilter::Area`] is percentage-closer soft shadows (Fernando 2005,
//!   "Percentage-closer soft shadows"): a blocker search estimates the mean occluder distance
//!   `d`, the penumbra of a cap of angular radius `a` is `2 d tan(a)` wide (the cap projected
//!   over the distance to the blocker), and PCF runs with that width (at least `kernel`). The
//!   filter footprint is a square: a straight shadow edge gives a linear ramp over the full
//!   geometric penumbra (the exact disk of the cap gives an S-shaped ramp over the same width).
//!   The blocker search starts from the nearest geometry of the map and shrinks with the
//!   nearest geometry of the min-max depth pyramid inside the current square (sound), and is
//!   capped at 64 texels: wider penumbrae are truncated to 128 texels.
//! * Early outs: a min-max depth pyramid decides in at most 4 reads when every texel a filter
//!   would read passes (or fails) the test; it rarely can for receivers tilted to the light,
//!   whose own depths span the block.
//! * Threads: the depth map is rasterised in bands of rows in parallel (rayon); the map does
//!   not depend on the number of threads.

use glam::Vec3;
use rayon::prelude::*;
use relight_scene::mesh::TriMesh;

/// Largest receiver slope (depth change per unit of lateral distance) used by the
/// receiver-plane bias: grazing receivers would otherwise extrapolate to any depth.
pub const MAX_SLOPE: f32 = 8.0;

/// Largest filter width (texels) filtered exactly; wider PCSS filters use `taps x taps`
/// jittered point taps (see [`ShadowFilter::Area`]).
const EXACT_MAX_WIDTH: f32 = 12.0;

/// Taps per axis of the PCSS blocker search (a regular grid over the search square, corners
/// and centre included; Fernando 2005 uses 16 to 36 blocker samples).
const SEARCH_TAPS: u32 = 5;

/// Rows of texels per parallel band of the depth rasteriser.
const BAND: usize = 16;

/// How [`ShadowMap::visibility`] filters the depth test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShadowFilter {
    /// Percentage-closer filtering over a square of `kernel` texels (the thesis' PCF, a point
    /// light's hard shadow anti-aliased). `kernel = 1` is one texel.
    Pcf {
        /// Filter width in texels (>= 1; need not be odd).
        kernel: f32,
    },
    /// PCSS for a uniform cap of angular radius `cap_radius` (radians): penumbrae sized to the
    /// cap and the occluder distance, never narrower than `kernel` texels.
    Area {
        /// Angular radius of the light's cap, radians.
        cap_radius: f32,
        /// Smallest filter width in texels (the PCF kernel).
        kernel: f32,
        /// Taps per axis of penumbrae wider than 12 texels (jittered point taps).
        taps: u32,
    },
}

/// An orthographic depth map of a mesh seen from a distant light (see the module docs).
#[derive(Clone, Debug)]
pub struct ShadowMap {
    /// Unit world direction towards the light.
    pub dir: Vec3,
    u: Vec3,
    v: Vec3,
    center: Vec3,
    half: f32,
    size: usize,
    /// World size of one texel.
    pub texel: f32,
    /// Depth bias in texels (see the module docs).
    pub depth_bias: f32,
    /// Least depth stored in the map (the nearest geometry to the light).
    min_depth: f32,
    /// `size * size` depths, row-major, `+inf` where empty.
    depth: Vec<f32>,
    /// Min-max pyramid: level `l` (from 1) holds `(min, max)` of the depths of each
    /// `2^l x 2^l` block of texels, `(size >> l)` rounded up per side.
    pyramid: Vec<(usize, Vec<(f32, f32)>)>,
}

impl ShadowMap {
    /// Rasterise `mesh`'s depth along `dir` (unit, towards the light) into a `size x size` map
    /// with `depth_bias` texels of constant bias.
    ///
    /// # Panics
    /// Debug builds: if `dir` is not unit, `size == 0` or the bias is negative.
    pub fn build(mesh: &TriMesh, dir: Vec3, size: u32, depth_bias: f32) -> ShadowMap {
        debug_assert!((dir.length() - 1.0).abs() < 1e-3, "dir must be unit: {dir}");
        debug_assert!(size > 0 && depth_bias >= 0.0);
        let size = size as usize;
        let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let center = (lo + hi) * 0.5;
        // A little margin so that silhouettes never touch the map's border.
        let half = ((hi - lo).length() * 0.5 * 1.001).max(1e-6);
        let (u, v) = dir.any_orthonormal_pair();
        let mut map = ShadowMap {
            dir,
            u,
            v,
            center,
            half,
            size,
            texel: 2.0 * half / size as f32,
            depth_bias,
            min_depth: f32::INFINITY,
            depth: vec![f32::INFINITY; size * size],
            pyramid: Vec::new(),
        };

        // Light-space vertices, then triangles binned by bands of rows.
        let ls: Vec<Vec3> = mesh.positions.par_iter().map(|&p| map.to_map(p)).collect();
        let bands = size.div_ceil(BAND);
        let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands];
        for (i, tri) in mesh.indices.iter().enumerate() {
            let t = tri.map(|k| ls[k as usize].y);
            let (t0, t1) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            if !(t1 >= 0.0 && t0 <= size as f32) {
                continue;
            }
            let b0 = ((t0.max(0.0) as usize) / BAND).min(bands - 1);
            let b1 = ((t1.min(size as f32 - 1.0) as usize) / BAND).min(bands - 1);
            for bin in &mut bins[b0..=b1] {
                bin.push(i as u32);
            }
        }
        map.depth
            .par_chunks_mut(size * BAND)
            .enumerate()
            .for_each(|(band, out)| {
                let row0 = band * BAND;
                for &i in &bins[band] {
                    let p = mesh.indices[i as usize].map(|k| ls[k as usize]);
                    raster_depth(p, row0, size, out);
                }
            });
        map.min_depth = map.depth.iter().copied().fold(f32::INFINITY, f32::min);
        map.build_pyramid();
        map
    }

    /// Build the min-max pyramid of the depths (for [`ShadowMap::classify`]).
    fn build_pyramid(&mut self) {
        let mut levels: Vec<(usize, Vec<(f32, f32)>)> = Vec::new();
        let (depth, mut n) = (&self.depth, self.size);
        while n > 1 {
            let m = n.div_ceil(2);
            let prev = levels.last().map(|(_, v)| v.as_slice());
            let level: Vec<(f32, f32)> = (0..m * m)
                .into_par_iter()
                .map(|k| {
                    let (x, y) = (k % m, k / m);
                    let mut acc = (f32::INFINITY, f32::NEG_INFINITY);
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (cx, cy) = (2 * x + dx, 2 * y + dy);
                        let v = match prev {
                            _ if cx >= n || cy >= n => (f32::INFINITY, f32::INFINITY), // empty
                            None => (depth[cy * n + cx], depth[cy * n + cx]),
                            Some(p) => p[cy * n + cx],
                        };
                        acc = (acc.0.min(v.0), acc.1.max(v.1));
                    }
                    acc
                })
                .collect();
            levels.push((m, level));
            n = m;
        }
        self.pyramid = levels;
    }

    /// Min and max stored depth over a superset of the texels `floor(s - half) ..=
    /// floor(s + half)` (same in `t`), and the receiver plane's depth variation over that
    /// superset: at most 4 reads of the min-max pyramid (blocks at least as wide as the span).
    fn block_bounds(&self, r: &Receiver, half: f32) -> (f32, f32, f32) {
        let (s0, s1) = (ifloor(r.s - half), ifloor(r.s + half));
        let (t0, t1) = (ifloor(r.t - half), ifloor(r.t + half));
        let span = (s1 - s0 + 1).max(t1 - t0 + 1).max(1) as u64;
        let l = (64 - (span - 1).leading_zeros()).max(1) as usize;
        let Some((m, level)) = self.pyramid.get(l - 1) else {
            return (self.min_depth, f32::INFINITY, f32::INFINITY); // undecided
        };
        let (b0, b1, c0, c1) = (s0 >> l, s1 >> l, t0 >> l, t1 >> l);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for i in c0..=c1 {
            for j in b0..=b1 {
                let v = if j < 0 || i < 0 || j >= *m as i64 || i >= *m as i64 {
                    (f32::INFINITY, f32::INFINITY) // outside the map: empty
                } else {
                    level[i as usize * m + j as usize]
                };
                (lo, hi) = (lo.min(v.0), hi.max(v.1));
            }
        }
        // Receiver-plane depths over the blocks' extent (texel centres lie inside it).
        let ext = |a: i64, b: i64, c: f32| {
            ((a << l) as f32 - c)
                .abs()
                .max((((b + 1) << l) as f32 - c).abs())
        };
        (
            lo,
            hi,
            r.gs.abs() * ext(b0, b1, r.s) + r.gt.abs() * ext(c0, c1, r.t),
        )
    }

    /// Conservative answer for a filter reading texels `floor(s - half) ..= floor(s + half)`
    /// (same in `t`): `Some(1)` if every such texel passes the depth test, `Some(0)` if every
    /// one fails, `None` if undecided.
    fn classify(&self, r: &Receiver, half: f32) -> Option<f32> {
        let (lo, hi, range) = self.block_bounds(r, half);
        if lo >= r.z + range - r.bias {
            Some(1.0)
        } else if hi < r.z - range - r.bias {
            Some(0.0)
        } else {
            None
        }
    }

    /// Map coordinates `(s, t)` in texels and depth `z` of a world point.
    #[inline]
    pub fn to_map(&self, p: Vec3) -> Vec3 {
        let d = p - self.center;
        let k = 0.5 * self.size as f32 / self.half;
        Vec3::new(
            (d.dot(self.u) + self.half) * k,
            (d.dot(self.v) + self.half) * k,
            -d.dot(self.dir),
        )
    }

    /// Map resolution (texels per side).
    pub fn size(&self) -> u32 {
        self.size as u32
    }

    /// Stored depth of texel `(j, i)`; `+inf` outside the map.
    #[inline]
    fn texel_depth(&self, j: i64, i: i64) -> f32 {
        if j < 0 || i < 0 || j >= self.size as i64 || i >= self.size as i64 {
            return f32::INFINITY;
        }
        self.depth[i as usize * self.size + j as usize]
    }

    /// Fraction in `[0, 1]` of the light reaching world point `p` with geometric normal `ng`
    /// (either orientation; it only sets the receiver plane), filtered by `filter`.
    pub fn visibility(&self, p: Vec3, ng: Vec3, filter: &ShadowFilter) -> f32 {
        let r = Receiver::new(self, p, ng);
        match *filter {
            ShadowFilter::Pcf { kernel } => {
                debug_assert!(kernel >= 1.0);
                self.classify(&r, 0.5 * kernel)
                    .unwrap_or_else(|| self.box_exact(&r, kernel))
            }
            ShadowFilter::Area {
                cap_radius,
                kernel,
                taps,
            } => {
                debug_assert!(cap_radius >= 0.0 && kernel >= 1.0 && taps >= 1);
                let tan_a = cap_radius.min(1.5).tan();
                // Blocker search over the widest possible penumbra: a blocker at depth d
                // shades the receiver only within (z - d) tan(a) of it. Start with the nearest
                // geometry of the whole map, then shrink with the nearest geometry inside the
                // current square (sound: any relevant blocker lies inside every square).
                let mut reach = ((r.z - self.min_depth).max(0.0) * tan_a / self.texel).min(64.0);
                for _ in 0..4 {
                    let (lo, _, _) = self.block_bounds(&r, reach.max(0.5 * kernel));
                    let next = ((r.z - lo).max(0.0) * tan_a / self.texel).min(reach);
                    if next > 0.9 * reach {
                        break;
                    }
                    reach = next;
                }
                let search = reach.max(0.5 * kernel);
                // Whole search square lit (no blocker: 1) or blocked (the filter lies inside).
                if let Some(v) = self.classify(&r, search) {
                    return v;
                }
                let n = SEARCH_TAPS.min((2.0 * search).ceil() as u32 + 1);
                let (mut sum, mut count) = (0.0f32, 0u32);
                for a in 0..n {
                    for b in 0..n {
                        let ds = search * (2.0 * a as f32 / (n - 1) as f32 - 1.0);
                        let dt = search * (2.0 * b as f32 / (n - 1) as f32 - 1.0);
                        let (j, i) = (ifloor(r.s + ds), ifloor(r.t + dt));
                        let gap = r.depth_at(j, i) - self.texel_depth(j, i);
                        if gap > r.bias {
                            sum += gap;
                            count += 1;
                        }
                    }
                }
                if count == 0 {
                    return 1.0;
                }
                let penumbra = 2.0 * (sum / count as f32) * tan_a / self.texel;
                // Inside the classified search square (penumbra <= 2 reach, but for clamps).
                let width = penumbra.max(kernel).min(2.0 * search);
                if width <= EXACT_MAX_WIDTH {
                    self.box_exact(&r, width)
                } else {
                    self.box_jittered(&r, width, taps)
                }
            }
        }
    }

    /// Exact box filter of width `width` texels centred at the receiver: each texel's test
    /// weighted by its overlap with the box.
    fn box_exact(&self, r: &Receiver, width: f32) -> f32 {
        let (s0, s1) = (r.s - 0.5 * width, r.s + 0.5 * width);
        let (t0, t1) = (r.t - 0.5 * width, r.t + 0.5 * width);
        let overlap = |a: f32, b: f32, k: i64| (b.min(k as f32 + 1.0) - a.max(k as f32)).max(0.0);
        // Normalise by the summed weights, not width^2: all lit is then exactly 1.
        let (mut lit, mut total) = (0.0, 0.0);
        for i in ifloor(t0)..=ifloor(t1) {
            let wi = overlap(t0, t1, i);
            for j in ifloor(s0)..=ifloor(s1) {
                let w = wi * overlap(s0, s1, j);
                total += w;
                if self.texel_depth(j, i) >= r.depth_at(j, i) - r.bias {
                    lit += w;
                }
            }
        }
        if total > 0.0 {
            (lit / total).min(1.0)
        } else {
            1.0
        }
    }

    /// Box filter of width `width` texels by `taps x taps` stratified point taps, jittered per
    /// receiver texel (deterministic hash): wide penumbrae at a fixed cost, noise not banding.
    fn box_jittered(&self, r: &Receiver, width: f32, taps: u32) -> f32 {
        let seed = hash((ifloor(r.s) as u32) ^ (ifloor(r.t) as u32).rotate_left(16));
        let mut lit = 0u32;
        for a in 0..taps {
            for b in 0..taps {
                let h = hash(seed ^ (a * taps + b).wrapping_mul(0x9e37_79b9));
                let (ja, jb) = ((h & 0xffff) as f32 / 65536.0, (h >> 16) as f32 / 65536.0);
                let s = r.s + width * ((a as f32 + ja) / taps as f32 - 0.5);
                let t = r.t + width * ((b as f32 + jb) / taps as f32 - 0.5);
                let (j, i) = (ifloor(s), ifloor(t));
                if self.texel_depth(j, i) >= r.depth_at(j, i) - r.bias {
                    lit += 1;
                }
            }
        }
        lit as f32 / (taps * taps) as f32
    }
}

/// A receiver point in map space with its depth plane and bias.
struct Receiver {
    s: f32,
    t: f32,
    z: f32,
    /// Depth change per texel along `s` and `t`.
    gs: f32,
    gt: f32,
    bias: f32,
}

impl Receiver {
    fn new(map: &ShadowMap, p: Vec3, ng: Vec3) -> Receiver {
        let q = map.to_map(p);
        // Plane n.(dp) = 0 with dp = a u + b v + c dir: depth change -c = (n_u a + n_v b) / n_d.
        let (nu, nv, nd) = (ng.dot(map.u), ng.dot(map.v), ng.dot(map.dir));
        let slope = |x: f32| {
            if nd.abs() > 1e-6 {
                (x / nd).clamp(-MAX_SLOPE, MAX_SLOPE)
            } else {
                0.0
            }
        };
        let (gs, gt) = (slope(nu), slope(nv));
        let steep = (gs * gs + gt * gt).sqrt().min(MAX_SLOPE);
        Receiver {
            s: q.x,
            t: q.y,
            z: q.z,
            gs: gs * map.texel,
            gt: gt * map.texel,
            bias: map.depth_bias * map.texel * (1.0 + steep),
        }
    }

    /// Receiver-plane depth at the centre of texel `(j, i)`.
    #[inline]
    fn depth_at(&self, j: i64, i: i64) -> f32 {
        self.z + self.gs * (j as f32 + 0.5 - self.s) + self.gt * (i as f32 + 0.5 - self.t)
    }
}

/// Rasterise one light-space triangle (`(s, t, z)` corners) into the band of rows starting at
/// `row0` (`out` = that band's texels), keeping the least depth. Texel centres on an edge
/// count as inside (a depth map wants no cracks, double coverage is harmless).
fn raster_depth(p: [Vec3; 3], row0: usize, size: usize, out: &mut [f32]) {
    let rows = out.len() / size;
    let area = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[1].y - p[0].y) * (p[2].x - p[0].x);
    if !(area.abs() > 0.0 && area.is_finite()) {
        return; // edge-on to the light: its neighbours cover it
    }
    let inv = 1.0 / area;
    let lo = p[0].min(p[1]).min(p[2]);
    let hi = p[0].max(p[1]).max(p[2]);
    let j0 = (lo.x - 0.5).ceil().max(0.0) as usize;
    let j1 = (hi.x - 0.5).floor().min(size as f32 - 1.0);
    let i0 = (lo.y - 0.5).ceil().max(row0 as f32) as usize;
    let i1 = (hi.y - 0.5).floor().min((row0 + rows) as f32 - 1.0);
    if j1 < j0 as f32 || i1 < i0 as f32 {
        return;
    }
    let e = |a: Vec3, b: Vec3, x: f32, y: f32| {
        ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)) * inv
    };
    for i in i0..=i1 as usize {
        let y = i as f32 + 0.5;
        for j in j0..=j1 as usize {
            let x = j as f32 + 0.5;
            let (w0, w1, w2) = (
                e(p[1], p[2], x, y),
                e(p[2], p[0], x, y),
                e(p[0], p[1], x, y),
            );
            if w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 {
                let z = w0 * p[0].z + w1 * p[1].z + w2 * p[2].z;
                let k = (i - row0) * size + j;
                if z < out[k] {
                    out[k] = z;
                }
            }
        }
    }
}

/// A 32-bit integer hash (Wellons' lowbias32).
#[inline]
fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// `floor(x)` as an integer without the libm call (no SSE4.1 `roundss` on the baseline
/// target); exact for `|x| < 2^31`, which map coordinates are.
#[inline(always)]
fn ifloor(x: f32) -> i64 {
    let i = x as i64;
    i - ((x < i as f32) as i64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_scene::accel::{build_default, offset_ray_origin, Ray};
    use relight_scene::shapes::{aabb_box, ground_plane, uv_sphere};
    use relight_sphere::warp::Rng;

    /// Slab occluder: top at this height above the plane y = 0.
    const TOP: f32 = 1.02;

    /// A ground plane (8 x 8 at y = 0) under a thin 2 x 2 slab spanning y in [1, 1.02].
    fn plane_and_slab() -> TriMesh {
        let mut m = ground_plane(Vec3::ZERO, 8.0, 8);
        m.append(
            &aabb_box(Vec3::new(-1.0, 1.0, -1.0), Vec3::new(1.0, TOP, 1.0), 1),
            0,
        );
        m
    }

    /// Visibility on the plane along x in `[x0, x1]`, averaged over 16 lines z in
    /// [-0.5, 0.5] (which smooths the jitter of wide filters), at `n` points.
    fn profile(
        map: &ShadowMap,
        filter: &ShadowFilter,
        x0: f32,
        x1: f32,
        n: usize,
    ) -> Vec<(f32, f32)> {
        (0..n)
            .map(|k| {
                let x = x0 + (x1 - x0) * k as f32 / (n - 1) as f32;
                let v = (0..16)
                    .map(|l| {
                        let z = -0.5 + l as f32 / 15.0;
                        map.visibility(Vec3::new(x, 0.0, z), Vec3::Y, filter)
                    })
                    .sum::<f32>()
                    / 16.0;
                (x, v)
            })
            .collect()
    }

    /// Width of the x range where `lo < V < hi`.
    fn ramp_width(p: &[(f32, f32)], lo: f32, hi: f32) -> f32 {
        let first = p.iter().find(|(_, v)| *v > lo).unwrap().0;
        let last = p.iter().rev().find(|(_, v)| *v < hi).unwrap().0;
        last - first
    }

    #[test]
    fn straight_down_light_shadows_under_the_slab_only() {
        let map = ShadowMap::build(&plane_and_slab(), Vec3::Y, 1024, 1.0);
        let f = ShadowFilter::Pcf { kernel: 3.0 };
        for (x, z) in [(0.0, 0.0), (0.9, -0.9), (-0.5, 0.7)] {
            assert_eq!(map.visibility(Vec3::new(x, 0.0, z), Vec3::Y, &f), 0.0);
        }
        for (x, z) in [(1.1, 0.0), (-3.0, 2.0), (0.0, -1.2)] {
            assert_eq!(map.visibility(Vec3::new(x, 0.0, z), Vec3::Y, &f), 1.0);
        }
        // The slab's top is not shadowed by itself (the bias).
        assert_eq!(map.visibility(Vec3::new(0.3, TOP, 0.2), Vec3::Y, &f), 1.0);
    }

    #[test]
    fn pcf_penumbra_is_the_kernel_width() {
        let map = ShadowMap::build(&plane_and_slab(), Vec3::Y, 1024, 1.0);
        for kernel in [1.0, 5.0, 9.0] {
            let p = profile(&map, &ShadowFilter::Pcf { kernel }, 0.9, 1.1, 2001);
            let w = ramp_width(&p, 1e-6, 1.0 - 1e-6) / map.texel;
            // The box of `kernel` texels over a nearest-texel edge: a ramp `kernel` texels wide
            // (+-0.1 texel: the profile's step of 1e-4 world = 0.02 texel and the edge texel).
            assert!(
                (w - kernel).abs() < 0.1 + 1e-3,
                "kernel {kernel}: ramp {w} texels"
            );
        }
    }

    #[test]
    fn area_penumbra_matches_the_geometric_penumbra_of_the_cap() {
        let map = ShadowMap::build(&plane_and_slab(), Vec3::Y, 2048, 1.0);
        let mut last = 0.0;
        for a in [0.02f32, 0.05, 0.1, 0.2] {
            let filter = ShadowFilter::Area {
                cap_radius: a,
                kernel: 3.0,
                taps: 8,
            };
            let p = profile(&map, &filter, 0.3, 1.7, 1401);
            // Geometric penumbra of a cap of radius a past an edge at height h: 2 h tan a. The
            // square filter ramps linearly over it, so 2%..98% spans 96% of it.
            let expect = 0.96 * 2.0 * TOP * a.tan();
            let w = ramp_width(&p, 0.02, 0.98);
            // 10% + 2 texels: the jittered taps (8 x 8, averaged over 16 lines) and the texel
            // grid; a penumbra from the plane distance or a point light is off by far more.
            assert!(
                (w - expect).abs() < 0.1 * expect + 2.0 * map.texel,
                "cap {a}: penumbra {w}, geometric {expect}"
            );
            // The middle of the ramp is at the slab's edge.
            let mid = p.iter().find(|(_, v)| *v >= 0.5).unwrap().0;
            assert!(
                (mid - 1.0).abs() < 0.05 * expect + 2.0 * map.texel,
                "cap {a}: mid {mid}"
            );
            assert!(w > last);
            last = w;
        }
    }

    #[test]
    fn agrees_with_ray_cast_visibility_away_from_edges() {
        let mut mesh = plane_and_slab();
        mesh.append(&uv_sphere(Vec3::new(1.5, 1.0, 1.0), 0.8, 24, 48), 0);
        let dir = Vec3::new(0.4, 1.0, 0.3).normalize();
        let map = ShadowMap::build(&mesh, dir, 2048, 1.0);
        let rt = build_default(&mesh);
        let filter = ShadowFilter::Pcf { kernel: 1.0 };
        // Area-weighted random surface points.
        let areas: Vec<f32> = (0..mesh.triangle_count())
            .map(|t| {
                let [a, b, c] = mesh.triangle(t);
                (b - a).cross(c - a).length()
            })
            .collect();
        let total: f32 = areas.iter().sum();
        let mut rng = Rng::new(7, 0);
        let occluded = |o: Vec3| rt.occluded(&Ray::new(o, dir, 0.0, f32::INFINITY));
        let (mut agree, mut tested, mut shadowed) = (0, 0, 0);
        for _ in 0..20000 {
            let mut x = rng.next_f32() * total;
            let t = areas.iter().position(|&a| {
                x -= a;
                x < 0.0
            });
            let t = t.unwrap_or(areas.len() - 1);
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let (p, ng) = (mesh.point(t, u, v), mesh.geometric_normal(t));
            // Only surfaces facing the light (others get no direct light: cosine 0).
            if ng.dot(dir) < 0.1 {
                continue;
            }
            let o = offset_ray_origin(p, ng, dir);
            let hit = occluded(o);
            // Away from edges: rays shifted 3 texels across the light agree with the centre
            // (origins slid along the light back onto the tangent plane, lifted by 1e-3 for
            // the sphere's curvature: 3 texels on radius 0.8 sag by 2e-4).
            let d = 3.0 * map.texel;
            if [map.u * d, -map.u * d, map.v * d, -map.v * d]
                .iter()
                .any(|&s| occluded(o + s - dir * (s.dot(ng) / dir.dot(ng)) + ng * 1e-3) != hit)
            {
                continue;
            }
            let vis = map.visibility(p, ng, &filter);
            tested += 1;
            shadowed += hit as u32;
            agree += ((vis < 0.5) == hit) as u32;
        }
        let rate = agree as f32 / tested as f32;
        assert!(
            tested > 5000 && shadowed > 200,
            "{tested} tested, {shadowed} in shadow"
        );
        assert!(rate > 0.98, "agreement {rate} over {tested} points");
    }
}
