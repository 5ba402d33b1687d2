//! Exact nearest-direction queries over a fixed set of unit directions (the light samples of
//! `cuts::samples`: Voronoi solid angles in the bake, the lights' power under every new
//! environment or rotation in the frame).
//!
//! A uniform grid over the cube `[-1, 1]^3` whose cells (about two sample spacings wide) list
//! the directions inside them, searched cell by cell, nearest boxes first, until no unvisited
//! cell can hold a nearer direction. Two shortcuts keep it exact:
//!
//! * **The certain radius.** Every direction `s_k` has `r_k`, half the distance to its nearest
//!   other direction. A query `d` with `|d - s_k| < r_k` has `s_k` as its unique nearest
//!   direction: for every other `j`, `|d - s_j| >= |s_j - s_k| - |d - s_k| > 2 r_k - r_k`.
//!   The search stops as soon as its best direction is that close (for well-spread samples,
//!   the inscribed disc is about nine tenths of a hexagonal Voronoi cell). The stored radius
//!   is shrunk by `CERTAIN_MARGIN` so that f32 rounding of the distances cannot turn the
//!   strict inequality around.
//! * **A hint** ([`NearestSample::nearest_from`]): the answer of a nearby query (the previous
//!   texel of a row). The query's nearest direction is then usually the hint or one of its
//!   neighbours, so the directions within one cell edge `e` of the hint (listed per
//!   direction when the grid is built, about a dozen) are scanned first. Their best is the
//!   answer if it is certain, or if it is nearer to `d` than `e - |d - s_hint|` (every
//!   direction not listed is further than that from `d`); else it seeds the search's best
//!   distance.
//!
//! Ties (two directions at the same f32 distance) go to the lower index, as in a brute-force
//! scan; a certified answer has no tie.

use glam::Vec3;
use rayon::prelude::*;

/// The certain radius of a direction, squared, is `(1 - CERTAIN_MARGIN)` times a quarter of
/// the squared distance to its nearest other direction (module docs). 1 %: far above the
/// f32 rounding of squared distances between unit vectors a sample spacing apart (relative
/// `1e-5` at 32K samples, `ulp(1) / spacing`), far below the gain.
const CERTAIN_MARGIN: f32 = 0.01;

/// The near list of a direction (module docs, "a hint") holds every direction within one
/// cell edge of it; what [`NearestSample::nearest_from`] relies on is `NEAR_REACH` cell
/// edges, 1 % less, so that f32 rounding of the list's distances and cells cannot matter.
const NEAR_REACH: f32 = 0.99;

/// Slack on the distance from a query to a cell's box: covers the f32 rounding of the cell's
/// bounds and of a direction's cell (a hundred times the rounding of coordinates of
/// magnitude 1), far below a cell (`2 / dims`, at least 2^-7).
const BOX_SLACK: f32 = 1e-5;

/// The nearest-direction grid (module docs).
#[derive(Clone, Debug)]
pub struct NearestSample {
    dirs: Vec<Vec3>,
    /// Per direction, its certain radius squared (module docs); 0 for a lone direction.
    certain: Vec<f32>,
    /// `near[near_starts[i]..near_starts[i + 1]]`: the directions within one cell edge of
    /// direction `i`, itself included, increasing (module docs, "a hint").
    near: Vec<u32>,
    near_starts: Vec<u32>,
    /// Cell edge.
    cell: f32,
    /// Cells per axis.
    dims: usize,
    /// `items[starts[c]..starts[c + 1]]` are the directions in cell `c`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl NearestSample {
    /// The grid over `dirs` (unit directions), with every direction's certain radius (one
    /// search per direction, on all cores).
    ///
    /// # Panics
    /// Debug builds: `dirs` empty.
    pub fn new(dirs: &[Vec3]) -> NearestSample {
        debug_assert!(!dirs.is_empty());
        let spacing = (4.0 * std::f32::consts::PI / dirs.len() as f32).sqrt();
        let dims = ((2.0 / (2.0 * spacing)).ceil() as usize).clamp(1, 256);
        let cell = 2.0 / dims as f32;
        let mut grid = NearestSample {
            dirs: dirs.to_vec(),
            certain: vec![0.0; dirs.len()],
            near: vec![],
            near_starts: vec![],
            cell,
            dims,
            starts: vec![0; dims * dims * dims + 1],
            items: vec![0; dirs.len()],
        };
        let keys: Vec<usize> = dirs.iter().map(|&d| grid.flat(grid.coords(d))).collect();
        for &k in &keys {
            grid.starts[k + 1] += 1;
        }
        for c in 0..grid.starts.len() - 1 {
            grid.starts[c + 1] += grid.starts[c];
        }
        let mut fill = grid.starts.clone();
        for (i, &k) in keys.iter().enumerate() {
            grid.items[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        // Near lists (the 27 cells around a direction's cell hold every direction within one
        // cell edge of it) and certain radii (the nearest other direction is almost always
        // listed; else searched, while every radius is still 0 so no search stops early).
        const RUN: usize = 1024;
        let runs: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)> = dirs
            .par_chunks(RUN)
            .enumerate()
            .map(|(run, chunk)| {
                let (mut near, mut ends, mut certain) = (vec![], vec![], vec![]);
                for (j, &s) in chunk.iter().enumerate() {
                    let i = run * RUN + j;
                    let c = grid.coords(s);
                    let range = |x: usize| x.saturating_sub(1)..=(x + 1).min(dims - 1);
                    let mut nn2 = f32::INFINITY;
                    for z in range(c[2]) {
                        for y in range(c[1]) {
                            for x in range(c[0]) {
                                for &k in grid.cell_items(grid.flat([x, y, z])) {
                                    let d2 = (dirs[k as usize] - s).length_squared();
                                    if d2 <= cell * cell {
                                        near.push(k);
                                        if k as usize != i {
                                            nn2 = nn2.min(d2);
                                        }
                                    }
                                }
                            }
                        }
                    }
                    let start = ends.last().map_or(0, |&e| e as usize);
                    near[start..].sort_unstable();
                    if nn2 == f32::INFINITY {
                        nn2 = grid.search(s, (f32::INFINITY, usize::MAX), i).0;
                    }
                    ends.push(near.len() as u32);
                    certain.push(if nn2.is_finite() {
                        0.25 * nn2 * (1.0 - CERTAIN_MARGIN)
                    } else {
                        0.0
                    });
                }
                (near, ends, certain)
            })
            .collect();
        grid.near_starts = vec![0];
        let mut certain = Vec::with_capacity(dirs.len());
        for (near, ends, c) in runs {
            let base = grid.near.len() as u32;
            grid.near_starts.extend(ends.iter().map(|e| base + e));
            grid.near.extend(near);
            certain.extend(c);
        }
        grid.certain = certain;
        grid
    }

    /// Index of the direction nearest to `d` (largest dot product; ties to the lower index).
    pub fn nearest(&self, d: Vec3) -> usize {
        self.search(d, (f32::INFINITY, usize::MAX), usize::MAX).1
    }

    /// [`NearestSample::nearest`] with a guess: `hint`, an index of a direction near `d`
    /// (module docs). The same answer for every hint.
    ///
    /// # Panics
    /// `hint` out of range.
    pub fn nearest_from(&self, d: Vec3, hint: usize) -> usize {
        let mut best = (f32::INFINITY, usize::MAX);
        let near = &self.near[self.near_starts[hint] as usize..self.near_starts[hint + 1] as usize];
        // Every direction not listed is further than `NEAR_REACH` cell edges from the hint,
        // so further than `reach` from `d`.
        let reach = NEAR_REACH * self.cell - (self.dirs[hint] - d).length();
        for &i in near {
            let i = i as usize;
            let d2 = (self.dirs[i] - d).length_squared();
            // Increasing indices: ties keep the first, the lower.
            if d2 < best.0 {
                best = (d2, i);
            }
        }
        if best.0 < self.certain[best.1] || (reach > 0.0 && best.0 < reach * reach) {
            return best.1;
        }
        self.search(d, best, usize::MAX).1
    }

    /// The best `(distance^2, index)` for `d` over every direction but `skip`, starting from
    /// `best` (a real candidate, or `(inf, usize::MAX)`). The cell of `d` is searched first;
    /// then the blocks of cells around it, ring by ring, skipping every cell whose box lies
    /// further from `d` than the best so far (it cannot hold a nearer one, nor an equal one:
    /// the box distance is reduced by [`BOX_SLACK`]); it stops as soon as the best is within
    /// its certain radius.
    fn search(&self, d: Vec3, mut best: (f32, usize), skip: usize) -> (f32, usize) {
        let c = self.coords(d);
        if self.scan(self.flat(c), d, &mut best, skip) {
            return best;
        }
        // Per axis, the distance from `d` to the lower and the upper side of its cell.
        let base = c.map(|x| -1.0 + x as f32 * self.cell);
        let below = [d.x - base[0], d.y - base[1], d.z - base[2]];
        let gap = |axis: usize, cell: usize| {
            let k = cell as f32 - c[axis] as f32;
            let g = if k > 0.0 {
                (k - 1.0) * self.cell + (self.cell - below[axis])
            } else if k < 0.0 {
                (-k - 1.0) * self.cell + below[axis]
            } else {
                0.0
            };
            (g - BOX_SLACK).max(0.0)
        };
        let mut ring = 1usize;
        loop {
            let lo = c.map(|x| x.saturating_sub(ring));
            let hi = c.map(|x| (x + ring).min(self.dims - 1));
            for z in lo[2]..=hi[2] {
                let gz = gap(2, z);
                for y in lo[1]..=hi[1] {
                    let gzy = gz * gz + gap(1, y).powi(2);
                    if gzy > best.0 {
                        continue;
                    }
                    for x in lo[0]..=hi[0] {
                        // Inside the previous block: searched already.
                        let inner = [x, y, z]
                            .iter()
                            .zip(&c)
                            .all(|(&a, &b)| a.abs_diff(b) < ring);
                        if inner || gzy + gap(0, x).powi(2) > best.0 {
                            continue;
                        }
                        if self.scan(self.flat([x, y, z]), d, &mut best, skip) {
                            return best;
                        }
                    }
                }
            }
            // Every direction outside the block is more than `ring` cells away along one axis.
            let whole = lo.iter().all(|&x| x == 0) && hi.iter().all(|&x| x == self.dims - 1);
            let reach = ring as f32 * self.cell;
            if whole || (best.1 != usize::MAX && best.0 <= reach * reach) {
                return best;
            }
            ring += 1;
        }
    }

    fn coords(&self, p: Vec3) -> [usize; 3] {
        let c = |x: f32| (((x + 1.0) / self.cell).floor().max(0.0) as usize).min(self.dims - 1);
        [c(p.x), c(p.y), c(p.z)]
    }

    fn flat(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims + c[1]) * self.dims + c[0]
    }

    /// The directions in cell `k`.
    #[inline]
    fn cell_items(&self, k: usize) -> &[u32] {
        &self.items[self.starts[k] as usize..self.starts[k + 1] as usize]
    }

    /// The directions of cell `k` but `skip` against the best `(distance^2, index)` so far;
    /// whether the best is then certain (within its certain radius).
    #[inline]
    fn scan(&self, k: usize, d: Vec3, best: &mut (f32, usize), skip: usize) -> bool {
        for &i in self.cell_items(k) {
            let i = i as usize;
            let d2 = (self.dirs[i] - d).length_squared();
            if i != skip && (d2 < best.0 || (d2 == best.0 && i < best.1)) {
                *best = (d2, i);
            }
        }
        best.1 != usize::MAX && best.0 < self.certain[best.1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cuts::samples::{fibonacci_point, EnvSamples};
    use relight_sphere::warp::{square_to_uniform_sphere, Rng};

    /// Brute-force nearest direction (the slow reference of [`NearestSample::nearest`]).
    fn nearest_slow(dirs: &[Vec3], d: Vec3) -> usize {
        let mut best = (f32::INFINITY, 0);
        for (i, &s) in dirs.iter().enumerate() {
            let d2 = (s - d).length_squared();
            if d2 < best.0 {
                best = (d2, i);
            }
        }
        best.1
    }

    /// The grid, with and without hints (good, bad, and the certain shortcut), gives the
    /// brute-force index, ties included, on lattices of every size and on a randomly rotated
    /// one (the bake's), and on queries right at sample directions.
    #[test]
    fn nearest_grid_matches_brute_force() {
        let mut sets: Vec<Vec<Vec3>> = [1usize, 2, 7, 300, 5000, 32768]
            .iter()
            .map(|&n| (0..n).map(|i| fibonacci_point(i, n)).collect())
            .collect();
        sets.push(EnvSamples::fibonacci(4096, 3).unwrap().dirs);
        for dirs in sets {
            let n = dirs.len();
            let grid = NearestSample::new(&dirs);
            let mut rng = Rng::new(9, n as u64);
            let (mut prev, mut certified) = (0, 0);
            for q in 0..3000 {
                let d = if q % 10 == 0 {
                    dirs[q % n]
                } else if q % 2 == 0 {
                    // Near the previous query: the hint is good.
                    let spacing = (4.0 * std::f32::consts::PI / n as f32).sqrt();
                    (dirs[prev] + (rng.next_vec2().extend(0.5) - 0.5) * spacing).normalize()
                } else {
                    square_to_uniform_sphere(rng.next_vec2())
                };
                let want = nearest_slow(&dirs, d);
                assert_eq!(grid.nearest(d), want, "n {n}, {d}");
                let hint = (rng.next_f64() * n as f64) as usize % n;
                for h in [prev, hint, want] {
                    assert_eq!(grid.nearest_from(d, h), want, "n {n}, {d}, hint {h}");
                }
                certified += usize::from((dirs[want] - d).length_squared() < grid.certain[want]);
                prev = want;
            }
            if n >= 300 {
                assert!(certified > 1500, "n {n}: {certified} of 3000 certified");
            }
        }
    }

    /// Every certain radius is below half the distance to every other direction (brute
    /// force) and above a quarter of it for a well-spread lattice.
    #[test]
    fn certain_radius_is_half_the_nearest_neighbour_distance() {
        let dirs = EnvSamples::fibonacci(2000, 1).unwrap().dirs;
        let grid = NearestSample::new(&dirs);
        for (i, &s) in dirs.iter().enumerate() {
            let nn2 = dirs
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, &t)| (t - s).length_squared())
                .fold(f32::INFINITY, f32::min);
            let r2 = grid.certain[i];
            assert!(r2 < 0.25 * nn2 && r2 > 0.2 * nn2, "{i}: {r2} vs {nn2}");
        }
        assert_eq!(NearestSample::new(&[Vec3::Y]).certain, vec![0.0]);
    }
}
