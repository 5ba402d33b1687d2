//! The data term's texels, grouped (thesis section 3.1, Algorithm 2, extended): a quadtree per
//! cube face whose leaves are single texels where the data carries detail and coarse cells
//! (summed solid angle, solid-angle-weighted mean direction and value) where it does not.
//!
//! A block of texels becomes one cell when it is
//! * entirely zero (Green's `S_0`, Algorithm 2), up to [`ZERO_CELL`] texels on a side;
//! * negligible: every channel below [`NEGLIGIBLE`] times the view's peak, up to
//!   [`ZERO_CELL`] on a side (data `1e-3` of the peak weighs `1e-6` in the squared error);
//! * smooth: the channel sum of every texel within [`SMOOTH`] times the view's peak of the
//!   block's least-squares plane in (row, column), up to [`SMOOTH_CELL`] on a side (the
//!   midpoint rule integrates a linear function exactly, so the cell keeps the data's mean
//!   and the model's, and only loses the variance of the residual inside it).
//!
//! Merging preserves the solid-angle-weighted sums `sum dA T` exactly, so a lobe's integral
//! against the data (and the energy used by the sharpness clamp) is unchanged.

use glam::Vec3;
use relight_sphere::cubemap::{texel_dir, texel_index, texel_solid_angle, CubeFace};
use relight_sphere::sg_fit::FitTarget;

/// Largest side (texels) of a cell of zero or negligible data.
pub const ZERO_CELL: usize = 8;
/// Largest side (texels) of a cell of smooth non-zero data.
pub const SMOOTH_CELL: usize = 8;
/// Data below this fraction of the view's peak counts as negligible.
pub const NEGLIGIBLE: f32 = 1e-3;
/// A block whose texels all lie within this fraction of the peak of their plane is smooth.
pub const SMOOTH: f32 = 4e-3;

/// Texel directions and solid angles of an `n x n`-per-face cube map (texel order of
/// [`relight_sphere::cubemap::texel_index`]).
#[derive(Clone, Debug)]
pub struct CubeTables {
    /// Face size.
    pub n: usize,
    dirs: Vec<Vec3>,
    solid_angles: Vec<f32>,
}

impl CubeTables {
    /// Tables of a `6 n^2` cube map.
    pub fn new(n: usize) -> CubeTables {
        let mut dirs = Vec::with_capacity(6 * n * n);
        let mut solid_angles = Vec::with_capacity(6 * n * n);
        for face in CubeFace::ALL {
            for row in 0..n {
                for col in 0..n {
                    debug_assert_eq!(dirs.len(), texel_index(n, face, row, col));
                    dirs.push(texel_dir(n, face, row, col));
                    solid_angles.push(texel_solid_angle(n, row, col) as f32);
                }
            }
        }
        CubeTables {
            n,
            dirs,
            solid_angles,
        }
    }

    /// Unit texel directions.
    pub fn dirs(&self) -> &[Vec3] {
        &self.dirs
    }

    /// Exact texel solid angles (steradians).
    pub fn solid_angles(&self) -> &[f32] {
        &self.solid_angles
    }

    /// Texels per view, `6 n^2`.
    pub fn texels(&self) -> usize {
        self.dirs.len()
    }

    /// All texels as one target, ungrouped (the reference the grouping is tested against).
    pub fn full_target(&self, data: &[Vec3]) -> FitTarget {
        FitTarget::new(&self.dirs, &self.solid_angles, data)
    }
}

/// One view's data, grouped, with what the fit needs to know about it.
#[derive(Clone, Debug)]
pub struct ViewTarget {
    /// Texels and cells of the data term.
    pub target: FitTarget,
    /// `sum dA |T|^2` of the grouped data (0: no data, the view is fully occluded).
    pub norm2: f64,
    /// `sum dA T`, the data's integral per channel (exact, grouping preserves it).
    pub integral: Vec3,
    /// The largest channel of any texel (before grouping).
    pub peak: f32,
    /// The view whose half vectors the target's directions are ([`ViewTarget::to_half_vector`]),
    /// `None` in the light domain.
    pub view: Option<Vec3>,
}

impl ViewTarget {
    /// Moves the target to the half-vector domain of the view `v`
    /// (`relight_sphere::half_vector`): every direction `w` becomes `h = normalize(w + v)`,
    /// weights and values unchanged, so the objective is still the L2 distance over `w` with
    /// the model evaluated at `h(w)`. The one direction with no half vector, `w = -v`, maps
    /// to `v` (a set of measure zero).
    pub fn to_half_vector(&mut self, v: Vec3) {
        self.target.map_dirs(|w| (w + v).normalize_or(v));
        self.view = Some(v);
    }
}

/// Groups one view's data (`6 n^2` texels) into texels and cells (module docs).
///
/// # Panics
/// Debug builds assert `data.len() == 6 n^2`.
pub fn group(tables: &CubeTables, data: &[Vec3]) -> ViewTarget {
    debug_assert_eq!(data.len(), tables.texels());
    // One pass for the peaks, the integral and the per-texel channel sums and maxima.
    let (mut peak, mut peak_sum) = (0f32, 0f32);
    let mut integral = [0f64; 3];
    let mut sums = Vec::with_capacity(data.len());
    let mut maxs = Vec::with_capacity(data.len());
    for (v, &w) in data.iter().zip(&tables.solid_angles) {
        let (s, m) = (v.element_sum(), v.max_element());
        peak = peak.max(m);
        peak_sum = peak_sum.max(s);
        sums.push(s);
        maxs.push(m);
        for c in 0..3 {
            integral[c] += (v[c] * w) as f64;
        }
    }
    let mut out = Cells::default();
    let n = tables.n;
    if peak > 0.0 {
        let top = ZERO_CELL.min(n.next_power_of_two());
        let g = Grid {
            t: tables,
            data,
            sums: &sums,
            maxs: &maxs,
            negligible: NEGLIGIBLE * peak,
            smooth: SMOOTH * peak_sum,
        };
        for f in 0..6 {
            for r0 in (0..n).step_by(top) {
                for c0 in (0..n).step_by(top) {
                    g.block((f, r0, c0, top), &mut out);
                }
            }
        }
    } else {
        // No data: a single zero cell per face keeps the target valid and cheap.
        for f in 0..6 {
            let face = &tables.dirs[f * n * n..(f + 1) * n * n];
            let centre = face.iter().copied().sum::<Vec3>().normalize();
            out.push(
                centre,
                tables.solid_angles[..n * n].iter().sum(),
                Vec3::ZERO,
            );
        }
    }
    let target = FitTarget::new(&out.dirs, &out.weights, &out.values);
    ViewTarget {
        norm2: target.norm2(),
        target,
        integral: Vec3::new(integral[0] as f32, integral[1] as f32, integral[2] as f32),
        peak,
        view: None,
    }
}

#[derive(Default)]
struct Cells {
    dirs: Vec<Vec3>,
    weights: Vec<f32>,
    values: Vec<Vec3>,
}

impl Cells {
    fn push(&mut self, d: Vec3, w: f32, v: Vec3) {
        self.dirs.push(d);
        self.weights.push(w);
        self.values.push(v);
    }
}

/// One view's data with its per-texel channel sums and maxima and the merge thresholds.
struct Grid<'a> {
    t: &'a CubeTables,
    data: &'a [Vec3],
    sums: &'a [f32],
    maxs: &'a [f32],
    negligible: f32,
    smooth: f32,
}

impl Grid<'_> {
    /// Emits block `(face, row0, col0, size)` (clipped to the face) as one cell or recurses.
    fn block(&self, (f, r0, c0, size): (usize, usize, usize, usize), out: &mut Cells) {
        let n = self.t.n;
        let (r1, c1) = ((r0 + size).min(n), (c0 + size).min(n));
        if r0 >= r1 || c0 >= c1 {
            return;
        }
        let idx = |r: usize, c: usize| (f * n + r) * n + c;
        if size == 1 {
            let i = idx(r0, c0);
            out.push(self.t.dirs[i], self.t.solid_angles[i], self.data[i]);
            return;
        }
        // Maximum and the plane fit of the channel sum in centred (row, column), an
        // orthogonal design.
        let (rm, cm) = ((r0 + r1 - 1) as f32 / 2.0, (c0 + c1 - 1) as f32 / 2.0);
        let (mut hi, mut s0, mut sr, mut sc, mut rr, mut cc) = (0f32, 0f32, 0f32, 0f32, 0f32, 0f32);
        for r in r0..r1 {
            let dr = r as f32 - rm;
            for c in c0..c1 {
                let i = idx(r, c);
                let (dc, x) = (c as f32 - cm, self.sums[i]);
                hi = hi.max(self.maxs[i]);
                s0 += x;
                sr += x * dr;
                sc += x * dc;
                rr += dr * dr;
                cc += dc * dc;
            }
        }
        let merge = hi <= self.negligible
            || (size <= SMOOTH_CELL && {
                let count = ((r1 - r0) * (c1 - c0)) as f32;
                let (a, b, g) = (s0 / count, sr / rr.max(1e-12), sc / cc.max(1e-12));
                (r0..r1).all(|r| {
                    let base = a + b * (r as f32 - rm);
                    (c0..c1).all(|c| {
                        (self.sums[idx(r, c)] - base - g * (c as f32 - cm)).abs() <= self.smooth
                    })
                })
            });
        if merge {
            let (mut sw, mut sd, mut sv) = (0f32, Vec3::ZERO, Vec3::ZERO);
            for r in r0..r1 {
                for c in c0..c1 {
                    let i = idx(r, c);
                    let w = self.t.solid_angles[i];
                    sw += w;
                    sd += w * self.t.dirs[i];
                    sv += w * self.data[i];
                }
            }
            out.push(sd.normalize(), sw, sv / sw);
            return;
        }
        let h = size / 2;
        for (dr, dc) in [(0, 0), (0, h), (h, 0), (h, h)] {
            self.block((f, r0 + dr, c0 + dc, h), out);
        }
    }
}
