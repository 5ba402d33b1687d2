//! The [`Decomposer`]: tables built once per settings, layout and size (icosahedron, culled
//! convolution, SH basis at vertices and texels, texel buckets), and the per-frame steps of
//! thesis 4.3.3 (see the parent module for the algorithm and what is conserved).

use super::{
    cap_solid_angle, elbow, DecomposeError, DecomposeSettings, Decomposition, ExtractedLight,
};
use crate::envmap::{luminance, EnvLayout, EnvMap};
use crate::icosphere::Icosphere;
use crate::sh;
use crate::warp::Frame;
use crate::Vec3;
use std::f32::consts::PI;

/// Maps with more quadrature samples than this are box-filtered into 1-degree bins before
/// the smoothing (a 256 x 129 latlong, a 6 x 64^2 cube and a 256^2 probe are not).
pub const MAX_DIRECT_TEXELS: usize = 65_536;

/// Largest `Y_k(dir_t) w_t` table kept (floats); beyond, the basis is evaluated per texel.
const MAX_PROJ_TABLE: usize = 1 << 21;

/// Texels bucketed by their nearest vertex of a coarse icosahedron, for "all texels within an
/// angle of a direction" queries (the culling of the convolution and of the caps).
#[derive(Clone, Debug)]
struct TexelGrid {
    coarse: Icosphere,
    start: Vec<u32>,
    items: Vec<u32>,
    /// Largest angle between a texel and its bucket's vertex.
    cell_angle: f32,
}

impl TexelGrid {
    fn new(dirs: &[Vec3]) -> TexelGrid {
        let coarse = Icosphere::new(8);
        let nv = coarse.vertices().len();
        let bucket: Vec<u32> = dirs
            .iter()
            .map(|&d| coarse.nearest_vertex(d) as u32)
            .collect();
        let mut start = vec![0u32; nv + 1];
        for &b in &bucket {
            start[b as usize + 1] += 1;
        }
        for i in 0..nv {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; dirs.len()];
        let mut min_cos = 1.0f32;
        for (t, &b) in bucket.iter().enumerate() {
            items[fill[b as usize] as usize] = t as u32;
            fill[b as usize] += 1;
            min_cos = min_cos.min(dirs[t].dot(coarse.vertices()[b as usize]));
        }
        let cell_angle = min_cos.clamp(-1.0, 1.0).acos() + 1e-3;
        TexelGrid {
            coarse,
            start,
            items,
            cell_angle,
        }
    }

    /// Calls `f(t, cos)` for every texel `t` with `cos = dirs[t] . centre >= cos(angle)`.
    fn for_each_within(
        &self,
        dirs: &[Vec3],
        centre: Vec3,
        angle: f32,
        mut f: impl FnMut(usize, f32),
    ) {
        let cos_a = angle.min(PI).cos();
        let cos_b = (angle + self.cell_angle).min(PI).cos();
        for (b, v) in self.coarse.vertices().iter().enumerate() {
            if v.dot(centre) < cos_b {
                continue;
            }
            for &t in &self.items[self.start[b] as usize..self.start[b + 1] as usize] {
                let c = dirs[t as usize].dot(centre);
                if c >= cos_a {
                    f(t as usize, c);
                }
            }
        }
    }
}

/// Precomputed tables for one settings / layout / size: decomposing a map is then a sparse
/// convolution, one projection and a few cap sums (the per-frame work; `relight bench`
/// times it, section "Hybrid: environment decomposition").
#[derive(Clone, Debug)]
pub struct Decomposer {
    s: DecomposeSettings,
    layout: EnvLayout,
    width: usize,
    height: usize,
    /// Quadrature samples: direction, weight, pixel index.
    dirs: Vec<Vec3>,
    weights: Vec<f32>,
    pixels: Vec<u32>,
    grid: TexelGrid,
    ico: Icosphere,
    /// Large maps only: the bin (vertex of a fine icosahedron) of each texel, the bins'
    /// solid angles; the smoothing then gathers bins instead of texels.
    bins: Option<(Vec<u32>, Vec<f32>)>,
    /// Culled SG convolution, CSR by vertex: source (texel or bin) indices, normalised weights.
    gather_start: Vec<u32>,
    gather_idx: Vec<u32>,
    gather_w: Vec<f32>,
    /// `Y_k(vertex)` (vertex-major).
    vert_basis: Vec<f32>,
    /// `Y_k(dir_t) w_t` (texel-major); empty for large maps (evaluated on the fly).
    proj: Vec<f32>,
}

impl Decomposer {
    /// Tables for maps of `layout` and `width x height` ([`EnvMap::width`], [`EnvMap::height`]).
    pub fn new(
        s: &DecomposeSettings,
        layout: EnvLayout,
        width: usize,
        height: usize,
    ) -> Result<Decomposer, DecomposeError> {
        s.validate().map_err(DecomposeError::Settings)?;
        // A map of that shape to read the quadrature from (values unused).
        let shape = match layout {
            EnvLayout::LatLong if width >= 1 && height >= 2 => {
                EnvMap::latlong(width, height, vec![Vec3::ZERO; width * height])
            }
            EnvLayout::Cube if width >= 1 && height == 6 * width => {
                EnvMap::cube(width, vec![Vec3::ZERO; 6 * width * width])
            }
            EnvLayout::Probe if width >= 2 && height == width => {
                EnvMap::probe(width, vec![Vec3::ZERO; width * width])
            }
            _ => {
                return Err(DecomposeError::Layout(format!(
                    "no {layout:?} map is {width} x {height}"
                )))
            }
        };
        let nt = shape.texel_count();
        let (mut dirs, mut weights, mut pixels) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..nt {
            let t = shape.texel(i);
            dirs.push(t.dir);
            weights.push(t.solid_angle);
            pixels.push(shape.texel_pixel(i) as u32);
        }
        let grid = TexelGrid::new(&dirs);
        let ico = Icosphere::new(s.icosphere_frequency);
        // Large maps are first box-filtered into the bins of a 1-degree icosahedron (thesis
        // 4.3.3: supersampled input, box filter down), so the convolution's cost and memory
        // do not grow with the map.
        let bins = (nt > MAX_DIRECT_TEXELS).then(|| {
            let fine = Icosphere::new(64);
            let bin: Vec<u32> = dirs
                .iter()
                .map(|&d| fine.nearest_vertex(d) as u32)
                .collect();
            let mut area = vec![0f32; fine.vertices().len()];
            for (&b, &w) in bin.iter().zip(&weights) {
                area[b as usize] += w;
            }
            (bin, area, fine.vertices().to_vec())
        });
        let (src_dirs, src_w, src_grid) = match &bins {
            Some((_, area, verts)) => (
                verts.as_slice(),
                area.as_slice(),
                Some(TexelGrid::new(verts)),
            ),
            None => (dirs.as_slice(), weights.as_slice(), None),
        };
        let sgrid = src_grid.as_ref().unwrap_or(&grid);
        // Culled SG convolution (thesis 4.3.3): sources within 3 sigma of each vertex.
        let sigma = s.kernel_deg.to_radians();
        let inv_s2 = 1.0 / (sigma * sigma);
        let (mut gather_start, mut gather_idx, mut gather_w) = (vec![0u32], Vec::new(), Vec::new());
        for &v in ico.vertices() {
            let first = gather_idx.len();
            let mut angle = 3.0 * sigma;
            loop {
                sgrid.for_each_within(src_dirs, v, angle, |t, c| {
                    if src_w[t] > 0.0 {
                        gather_idx.push(t as u32);
                        gather_w.push(((c - 1.0) * inv_s2).exp() * src_w[t]);
                    }
                });
                // A map coarser than the kernel: widen until a texel is found.
                if gather_idx.len() > first || angle >= PI {
                    break;
                }
                angle *= 2.0;
            }
            let sum: f32 = gather_w[first..].iter().sum();
            if sum > 0.0 {
                gather_w[first..].iter_mut().for_each(|w| *w /= sum);
            } else {
                let n = (gather_w.len() - first) as f32;
                gather_w[first..].iter_mut().for_each(|w| *w = 1.0 / n);
            }
            gather_start.push(gather_idx.len() as u32);
        }
        let nc = sh::sh_count(s.sh_order);
        let mut buf = vec![0f32; nc];
        let mut vert_basis = Vec::with_capacity(ico.vertices().len() * nc);
        for &v in ico.vertices() {
            sh::eval_sh(s.sh_order, v, &mut buf);
            vert_basis.extend_from_slice(&buf);
        }
        let mut proj = Vec::new();
        if nt * nc <= MAX_PROJ_TABLE {
            proj.reserve(nt * nc);
            for (d, w) in dirs.iter().zip(&weights) {
                sh::eval_sh(s.sh_order, *d, &mut buf);
                proj.extend(buf.iter().map(|y| y * w));
            }
        }
        let bins = bins.map(|(bin, area, _)| (bin, area));
        Ok(Decomposer {
            s: *s,
            layout,
            width,
            height,
            dirs,
            weights,
            pixels,
            grid,
            ico,
            bins,
            gather_start,
            gather_idx,
            gather_w,
            vert_basis,
            proj,
        })
    }

    /// The settings.
    pub fn settings(&self) -> &DecomposeSettings {
        &self.s
    }

    /// The icosahedron the residual is searched on.
    pub fn icosphere(&self) -> &Icosphere {
        &self.ico
    }

    /// Decompose `map` (same layout and size as at construction).
    ///
    /// Defined behaviour on bad input: a NaN, infinite or negative texel is
    /// [`DecomposeError::BadTexel`]; an all-zero map gives zero SH and no lights.
    pub fn run(&self, map: &EnvMap) -> Result<Decomposition, DecomposeError> {
        if (map.layout(), map.width(), map.height()) != (self.layout, self.width, self.height) {
            return Err(DecomposeError::Layout(format!(
                "decomposer built for {:?} {} x {}, map is {:?} {} x {}",
                self.layout,
                self.width,
                self.height,
                map.layout(),
                map.width(),
                map.height()
            )));
        }
        let s = &self.s;
        let nc = sh::sh_count(s.sh_order);
        // Read and check the quadrature samples.
        let texels = map.texels();
        let mut vals = Vec::with_capacity(self.pixels.len());
        let mut lum = Vec::with_capacity(self.pixels.len());
        let mut integral = [0f64; 3];
        for (&p, &w) in self.pixels.iter().zip(&self.weights) {
            let v = texels[p as usize];
            if !(v.is_finite() && v.min_element() >= 0.0) {
                return Err(DecomposeError::BadTexel {
                    pixel: p as usize,
                    value: v,
                });
            }
            vals.push(v);
            lum.push(luminance(v));
            for k in 0..3 {
                integral[k] += (v[k] * w) as f64;
            }
        }
        let env_integral = Vec3::new(integral[0] as f32, integral[1] as f32, integral[2] as f32);
        let total_luminance = luminance(env_integral);
        let mut out = Decomposition {
            sh: vec![Vec3::ZERO; nc],
            lights: Vec::new(),
            total_luminance,
            env_integral,
        };
        if total_luminance <= 0.0 {
            return Ok(out); // all zero
        }
        // SH projection of the whole map (Fig. 4.4), windowed: the thesis' P.
        let full = self.project(vals.iter().copied().enumerate());
        let mut p0 = full.clone();
        sh::apply_window(&mut p0, s.sh_order, s.window);
        // Residual on the icosahedron: smoothed luminance minus the SH part's luminance.
        let p0_lum: Vec<f32> = p0.iter().map(|c| luminance(*c)).collect();
        let nv = self.ico.vertices().len();
        let src_lum = match &self.bins {
            // Box filter into the bins: mean luminance per bin.
            Some((bin, area)) => {
                let mut acc = vec![0f32; area.len()];
                for ((&b, l), w) in bin.iter().zip(&lum).zip(&self.weights) {
                    acc[b as usize] += l * w;
                }
                acc.iter_mut()
                    .zip(area)
                    .for_each(|(a, w)| *a = if *w > 0.0 { *a / w } else { 0.0 });
                acc
            }
            None => lum,
        };
        let lum = &src_lum;
        let res: Vec<f32> = (0..nv)
            .map(|v| {
                let (a, b) = (
                    self.gather_start[v] as usize,
                    self.gather_start[v + 1] as usize,
                );
                let smooth: f32 = self.gather_idx[a..b]
                    .iter()
                    .zip(&self.gather_w[a..b])
                    .map(|(&t, &w)| lum[t as usize] * w)
                    .sum();
                let basis = &self.vert_basis[v * nc..(v + 1) * nc];
                smooth - basis.iter().zip(&p0_lum).map(|(y, c)| y * c).sum::<f32>()
            })
            .collect();
        // Hill-climbing end points: vertices above their whole one-ring (ties by index).
        let mut maxima: Vec<usize> = (0..nv)
            .filter(|&v| {
                res[v] > 0.0
                    && self.ico.neighbours(v).iter().all(|&u| {
                        let u = u as usize;
                        res[v] > res[u] || (res[v] == res[u] && v < u)
                    })
            })
            .collect();
        maxima.sort_by(|&a, &b| res[b].total_cmp(&res[a]).then(a.cmp(&b)));
        // Quadric refinement, one light per cap (a weaker maximum inside a stronger one's
        // cap is the same light), a bounded number of candidates.
        let r = s.cap_radius();
        let max_candidates = (4 * s.max_lights).max(16);
        let mut cands: Vec<Vec3> = Vec::new();
        for &v in &maxima {
            if cands.len() >= max_candidates || s.max_lights == 0 {
                break;
            }
            let d = self.refine(v, &res);
            if cands.iter().all(|c| c.dot(d) < r.cos()) {
                cands.push(d);
            }
        }
        // Preliminary powers, selection (Fig. 4.5), final removal in the selected order.
        let mut claimed = vec![false; vals.len()];
        let mut prelim: Vec<(Vec3, ExtractedLight)> = cands
            .iter()
            .map(|&d| (d, self.cap_light(d, &vals, &p0, &mut claimed, None)))
            .collect();
        prelim.retain(|(_, l)| l.luminance > 0.0 && l.luminance >= s.min_share * total_luminance);
        prelim.sort_by(|a, b| b.1.luminance.total_cmp(&a.1.luminance));
        let lums: Vec<f32> = prelim.iter().map(|(_, l)| l.luminance).collect();
        let n = elbow(&lums, s.threshold).min(s.max_lights);
        claimed.iter_mut().for_each(|c| *c = false);
        let mut removed = Vec::new();
        for (d, _) in &prelim[..n] {
            let l = self.cap_light(*d, &vals, &p0, &mut claimed, Some(&mut removed));
            if l.luminance > 0.0 {
                out.lights.push(l);
            }
        }
        out.lights
            .sort_by(|a, b| b.luminance.total_cmp(&a.luminance));
        // The SH part: P(L - removed) with removal, P(L) without (thesis).
        out.sh = if s.remove_caps {
            let cut = self.project(removed.iter().copied());
            let mut c: Vec<Vec3> = full.iter().zip(&cut).map(|(a, b)| *a - *b).collect();
            sh::apply_window(&mut c, s.sh_order, s.window);
            c
        } else {
            p0
        };
        Ok(out)
    }

    /// `sum_t value_t Y_k(dir_t) w_t` over `(t, value)` pairs (f32 blocks, f64 total).
    fn project(&self, items: impl Iterator<Item = (usize, Vec3)>) -> Vec<Vec3> {
        let nc = sh::sh_count(self.s.sh_order);
        let mut total = vec![[0f64; 3]; nc];
        let mut block = vec![Vec3::ZERO; nc];
        let flush = |block: &mut [Vec3], total: &mut [[f64; 3]]| {
            for (t, b) in total.iter_mut().zip(block.iter_mut()) {
                for k in 0..3 {
                    t[k] += b[k] as f64;
                }
                *b = Vec3::ZERO;
            }
        };
        let mut ybuf = vec![0f32; nc];
        for (i, (t, v)) in items.enumerate() {
            let row = if self.proj.is_empty() {
                sh::eval_sh(self.s.sh_order, self.dirs[t], &mut ybuf);
                ybuf.iter_mut().for_each(|y| *y *= self.weights[t]);
                &ybuf[..]
            } else {
                &self.proj[t * nc..(t + 1) * nc]
            };
            for (b, y) in block.iter_mut().zip(row) {
                *b += v * *y;
            }
            if i % 256 == 255 {
                flush(&mut block, &mut total);
            }
        }
        flush(&mut block, &mut total);
        total
            .iter()
            .map(|t| Vec3::new(t[0] as f32, t[1] as f32, t[2] as f32))
            .collect()
    }

    /// The quadric fit of thesis 4.3.3 around maximum vertex `v`: the one-ring, gnomonically
    /// projected to the tangent plane, fitted by least squares; the vertex itself when the
    /// quadric has no maximum inside the ring.
    fn refine(&self, v: usize, res: &[f32]) -> Vec3 {
        let c = self.ico.vertices()[v];
        let frame = Frame::from_normal(c);
        let ring = self.ico.neighbours(v);
        let mut pts = vec![(0.0f64, 0.0f64, res[v] as f64)];
        let mut h = 0.0f64;
        for &u in ring {
            let p = self.ico.vertices()[u as usize];
            let g = p / p.dot(c);
            let (x, y) = (g.dot(frame.s) as f64, g.dot(frame.t) as f64);
            h = h.max((x * x + y * y).sqrt());
            pts.push((x, y, res[u as usize] as f64));
        }
        // Normal equations of f = a + b x + c y + d x^2 + e xy + g y^2 (coordinates / h).
        let mut m = [[0f64; 7]; 6];
        for &(x, y, f) in &pts {
            let (x, y) = (x / h, y / h);
            let phi = [1.0, x, y, x * x, x * y, y * y];
            for i in 0..6 {
                for j in 0..6 {
                    m[i][j] += phi[i] * phi[j];
                }
                m[i][6] += phi[i] * f;
            }
        }
        let Some(q) = solve6(m) else { return c };
        let (b, cc, d, e, g) = (q[1], q[2], q[3], q[4], q[5]);
        let det = 4.0 * d * g - e * e;
        if !(d < 0.0 && det > 0.0) {
            return c;
        }
        let x = (-2.0 * g * b + e * cc) / det;
        let y = (-2.0 * d * cc + e * b) / det;
        let len = (x * x + y * y).sqrt();
        // Outside the ring the fit is an extrapolation: keep it on the ring's edge.
        let k = h * if len > 1.0 { 1.0 / len } else { 1.0 };
        (c + frame.s * (x * k) as f32 + frame.t * (y * k) as f32).normalize()
    }

    /// The light of the cap around `peak`: removes `max(L - B, 0)` from its unclaimed texels
    /// (`B` the ring median, or the SH part `p0` in thesis mode), claims them, appends
    /// `(texel, removed)` to `removed`.
    fn cap_light(
        &self,
        peak: Vec3,
        vals: &[Vec3],
        p0: &[Vec3],
        claimed: &mut [bool],
        mut removed: Option<&mut Vec<(usize, Vec3)>>,
    ) -> ExtractedLight {
        let s = &self.s;
        let r = s.cap_radius();
        let cos_r = r.cos();
        let spacing = (4.0 * PI / self.dirs.len() as f32).sqrt();
        let rim = (1.5 * r).max(r + 2.0 * spacing);
        let mut cap = Vec::new();
        let mut ring: [Vec<f32>; 3] = Default::default();
        self.grid.for_each_within(&self.dirs, peak, rim, |t, c| {
            if c >= cos_r {
                cap.push((t, c));
            } else {
                (0..3).for_each(|k| ring[k].push(vals[t][k]));
            }
        });
        let median = |v: &mut Vec<f32>| -> f32 {
            if v.is_empty() {
                return 0.0;
            }
            let m = v.len() / 2;
            *v.select_nth_unstable_by(m, |a, b| a.total_cmp(b)).1
        };
        let bg = Vec3::new(
            median(&mut ring[0]),
            median(&mut ring[1]),
            median(&mut ring[2]),
        );
        let mut basis = [0f32; sh::sh_count(sh::MAX_ORDER)];
        let (mut power, mut m2, mut wl) = (Vec3::ZERO, 0.0f32, 0.0f32);
        let mut m1 = Vec3::ZERO;
        for (t, c) in cap {
            if claimed[t] {
                continue;
            }
            let b = if s.remove_caps {
                bg
            } else {
                sh::eval_sh(s.sh_order, self.dirs[t], &mut basis);
                p0.iter()
                    .zip(&basis)
                    .fold(Vec3::ZERO, |a, (c, y)| a + *c * *y)
            };
            let rem = (vals[t] - b).max(Vec3::ZERO);
            if rem == Vec3::ZERO {
                continue;
            }
            claimed[t] = true;
            let e = rem * self.weights[t];
            power += e;
            let theta = c.clamp(-1.0, 1.0).acos();
            m2 += luminance(e) * theta * theta;
            wl += luminance(e);
            m1 += self.dirs[t] * luminance(e);
            if let Some(out) = removed.as_deref_mut() {
                out.push((t, rem));
            }
        }
        let extent = if wl > 0.0 {
            (2.0 * m2 / wl).sqrt().min(r)
        } else {
            0.0
        };
        // The first moment of what was removed: exact direction for the irradiance of a cap
        // above the horizon (`int rem(w) (n . w) dw = n . int rem(w) w dw`).
        let centroid = if m1.length_squared() > 0.0 {
            m1.normalize()
        } else {
            peak
        };
        ExtractedLight {
            dir: centroid,
            peak,
            power,
            cap_radius: r,
            solid_angle: cap_solid_angle(r),
            luminance: luminance(power),
            extent,
        }
    }
}

/// Gaussian elimination with partial pivoting on a 6 x 7 augmented system.
fn solve6(mut m: [[f64; 7]; 6]) -> Option<[f64; 6]> {
    for col in 0..6 {
        let p = (col..6).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))?;
        if m[p][col].abs() < 1e-12 {
            return None;
        }
        m.swap(col, p);
        let pivot = m[col];
        for row in m.iter_mut().skip(col + 1) {
            let f = row[col] / pivot[col];
            for (x, p) in row.iter_mut().zip(&pivot).skip(col) {
                *x -= f * p;
            }
        }
    }
    let mut x = [0f64; 6];
    for i in (0..6).rev() {
        let s: f64 = (i + 1..6).map(|k| m[i][k] * x[k]).sum();
        x[i] = (m[i][6] - s) / m[i][i];
    }
    Some(x)
}
