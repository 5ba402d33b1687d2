//! Lobe correspondence between neighbouring vertices (thesis section 3.4, "Gaussian
//! flipping"): aligning independently flood-filled regions, counting flips, and the
//! relaxation the thesis suggests as future work.

use super::graph::{Adjacency, Regions};
use super::vertex::{best_assignment, lobe_distance, match_to};
use relight_sphere::sg::SgLobe;
use std::collections::VecDeque;

/// The lobes of one component of every vertex: `lobes[(x * views + v) * n + k]`.
pub struct LobeField<'a> {
    /// Views per vertex.
    pub views: usize,
    /// Lobes per view.
    pub n: usize,
    /// The lobes.
    pub lobes: &'a [SgLobe],
}

impl LobeField<'_> {
    #[inline]
    fn at(&self, x: usize, v: usize) -> &[SgLobe] {
        let i = (x * self.views + v) * self.n;
        &self.lobes[i..i + self.n]
    }

    /// Whether edge `(x, y)` is flipped in view `v`: the best permutation of `y`'s lobes
    /// against `x`'s is not the identity (the identity wins ties).
    pub fn flipped(&self, x: usize, y: usize, v: usize) -> bool {
        let p = match_to(self.at(y, v), self.at(x, v));
        p.iter().enumerate().any(|(k, &j)| k != j)
    }

    /// Flips over all edges and views, and per vertex the views (bit `v`) in which one of its
    /// edges is flipped.
    pub fn flips(&self, adj: &Adjacency) -> (u64, Vec<u128>) {
        debug_assert!(self.views <= 128);
        let mut on_flip = vec![0u128; adj.len()];
        if self.n < 2 {
            return (0, on_flip);
        }
        let mut count = 0;
        for (x, y) in adj.edges() {
            for v in 0..self.views {
                if self.flipped(x, y, v) {
                    count += 1;
                    on_flip[x] |= 1 << v;
                    on_flip[y] |= 1 << v;
                }
            }
        }
        (count, on_flip)
    }

    /// The lobes of `x`, each view permuted to agree best with all its neighbours at once
    /// (the assignment minimising the summed [`lobe_distance`] to every neighbour): the
    /// starting point of a relaxation refit.
    pub fn consensus(&self, adj: &Adjacency, x: usize) -> Vec<SgLobe> {
        let n = self.n;
        let mut out = Vec::with_capacity(self.views * n);
        for v in 0..self.views {
            let a = self.at(x, v);
            let mut cost = vec![0f32; n * n];
            for &y in adj.neighbours(x) {
                let b = self.at(y as usize, v);
                for k in 0..n {
                    for j in 0..n {
                        cost[k * n + j] += lobe_distance(&a[j], &b[k]);
                    }
                }
            }
            let p = best_assignment(&cost, n);
            out.extend(p.iter().map(|&j| a[j]));
        }
        out
    }
}

/// Aligns independently filled regions of one component (`lobes` laid out as in
/// [`LobeField`]): regions are visited breadth-first over the region graph (from the
/// lowest-numbered region of each group), and each is permuted, per view and as a whole, by
/// the assignment that best matches its boundary edges to the regions already aligned (sum
/// of [`lobe_distance`] over those edges). Deterministic.
pub fn align_regions(
    lobes: &mut [SgLobe],
    views: usize,
    n: usize,
    adj: &Adjacency,
    regions: &Regions,
) {
    let nr = regions.orders.len();
    if n < 2 || nr < 2 {
        return;
    }
    {
        let rof = |x: usize| regions.region_of[x] as usize;
        // Boundary edges per region (x in the region, y outside).
        let mut boundary: Vec<Vec<(u32, u32)>> = vec![vec![]; nr];
        for (x, y) in adj.edges() {
            if rof(x) != rof(y) {
                boundary[rof(x)].push((x as u32, y as u32));
                boundary[rof(y)].push((y as u32, x as u32));
            }
        }
        let mut aligned = vec![false; nr];
        for start in 0..nr {
            if aligned[start] {
                continue;
            }
            aligned[start] = true;
            let mut queue = VecDeque::from([start]);
            while let Some(r) = queue.pop_front() {
                let mut next: Vec<usize> =
                    boundary[r].iter().map(|&(_, y)| rof(y as usize)).collect();
                next.sort_unstable();
                next.dedup();
                for s in next {
                    if aligned[s] {
                        continue;
                    }
                    // Permute region s per view against its aligned neighbours.
                    for v in 0..views {
                        let mut cost = vec![0f32; n * n];
                        for &(x, y) in &boundary[s] {
                            if !aligned[rof(y as usize)] {
                                continue;
                            }
                            let ia = (x as usize * views + v) * n;
                            let ib = (y as usize * views + v) * n;
                            let (a, b) = (&lobes[ia..ia + n], &lobes[ib..ib + n]);
                            for k in 0..n {
                                for j in 0..n {
                                    cost[k * n + j] += lobe_distance(&a[j], &b[k]);
                                }
                            }
                        }
                        let p = best_assignment(&cost, n);
                        if p.iter().enumerate().all(|(k, &j)| k == j) {
                            continue;
                        }
                        for &x in &regions.orders[s] {
                            let i = (x as usize * views + v) * n;
                            let old: Vec<SgLobe> = lobes[i..i + n].to_vec();
                            for k in 0..n {
                                lobes[i + k] = old[p[k]];
                            }
                        }
                    }
                    aligned[s] = true;
                    queue.push_back(s);
                }
            }
        }
    }
}
