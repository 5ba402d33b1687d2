//! The illumination cut of a frame (Cheslack-Postava et al. 2008, sec. 3.2 last paragraph,
//! sec. 4.2 "we select the node to split based on the magnitude of the value").
//!
//! The light function is `l_i = L_i O_i` (RGB; [`crate::cuts`] conventions). Refinement is
//! driven by its luminance normalised by the mean over all lights, `y_i = Y(l_i) / <Y(l)>`,
//! so the threshold `sigma` has the same meaning for any exposure (a cluster's `M2` of `y`
//! is its error in units of "an average light"). Two phases, within a budget of nodes:
//! 1. the error bound: split the node of largest `M2` until every node has `M2 <= sigma^2`
//!    (Eq. 6) or the budget is used ([`LightCut::error_bound_met`] says which);
//! 2. intensity: split the brightest splittable cluster (largest `sum y`) until the cut has
//!    the budget's nodes or is all leaves.
//!
//! Node values are the cluster means of the RGB `l` (exact f64 prefix sums over the leaves in
//! left-to-right order). The budgets of the paper's Fig. 9 are [`LIGHT_CUT_BUDGETS`].
//!
//! **Cluster directions** ([`LightCut::direction`], a departure from the paper, measured in
//! docs/RESULTS.md, cuts): the paper evaluates the BRDF at a merged cluster's centre. relight
//! uses the cluster's mean direction weighted by the lights' luminance `Y(l_i)` (the tree's
//! geometric direction where the cluster holds no light), for every tree node. For lights of
//! even power it is the geometric centre; for a cluster whose power is one bright light (a
//! sun) it is that light's direction. With the geometric centre, a sun inside a coarse
//! cluster put a glossy highlight where the cluster's centre reflects, and a larger light
//! cut could be worse than a smaller one (the dragon's GGX conductor under a dawn sky: 18.7 %
//! at 128 nodes, 29.1 % at 256, 7.5 % at 512; weighted: 28.7, 20.9, 7.4 %). Weighting is
//! not a cure (one direction still stands for a cluster mixing a sun and sky), so the
//! evaluation's GGX rows still vary by light cut more than by the reference's noise.
//!
//! **Cluster spread** ([`LightCut::spread_average`], measured in docs/RESULTS.md, section
//! cuts): one direction stands for a cluster whose lights spread over more than a glossy
//! lobe, and which cluster lands in a mirror direction changes with every split (the
//! dragon's GGX plastic was worse at 256 light-cut nodes than at 128). With it, a merged
//! cluster's BRDF is the mean of five evaluations: at its direction `mu` and at four
//! directions around it at the angle `theta_p` of the symmetric five-point rule whose mean
//! resultant length matches the cluster's, `(1 + 4 cos theta_p) / 5 = R` with `R = |sum y_i
//! w_i| / sum y_i` (the first moment of its lights' directions; `cos theta_p` clamped to
//! `[-1, 1]`). Clusters with `theta_p` below [`SPREAD_MIN_ANGLE`] keep one evaluation. Only a
//! material's glossy lobe is spread ([`LightCut::spread_lobes`]); its diffuse lobe (a GGX
//! plastic's base, Blinn-Phong's and Ward's diffuse terms) is evaluated at `mu` alone, as a
//! Lambert material always is: it is smooth over a cluster, and its five evaluations (a
//! transmittance table looked up at each) were half of the plastic's CPU frame
//! (docs/RESULTS.md, section cuts, with its effect on the error against the path tracer).

use super::cut::{select_cut, Keyed, NodeStats};
use super::tree::{LightTree, NodeKind};
use super::CutsError;
use glam::Vec3;
use relight_sphere::luminance;
use std::collections::BinaryHeap;

/// The illumination cut sizes of the paper's Fig. 9 (128 / 256 / 512 nodes).
pub const LIGHT_CUT_BUDGETS: [usize; 3] = [128, 256, 512];
/// Default `sigma` of the illumination cut's error phase (normalised luminance units).
pub const DEFAULT_LIGHT_SIGMA: f32 = 2.0;
/// Below this angle (radians) of the five-point rule a cluster is shaded at its direction
/// alone ([`LightCut::spread_average`]): about the angular radius of one light of 32K.
pub const SPREAD_MIN_ANGLE: f32 = 0.01;
/// `cos(SPREAD_MIN_ANGLE)` (`1 - 0.01^2 / 2` to f32 precision), compared per cluster and
/// pixel.
const SPREAD_MIN_COS: f32 = 0.999_95;

/// An illumination cut: nodes in increasing post-order index with their cluster means.
#[derive(Clone, Debug, PartialEq)]
pub struct LightCut {
    /// Post-order node indices, increasing.
    pub index: Vec<u32>,
    /// Leftmost leaf of each node.
    pub leftleaf: Vec<u32>,
    /// Cluster mean of `l = L O` (RGB) of each node.
    pub value: Vec<Vec3>,
    /// Every node satisfies the error bound (phase 1 finished within the budget).
    pub error_bound_met: bool,
    /// Every tree node's luminance-weighted mean light direction (module docs), by post-order
    /// index.
    pub dirs: Vec<Vec3>,
    /// Every tree node's `cos theta_p` of the five-point rule (module docs), by post-order
    /// index.
    pub spread_cos: Vec<f32>,
}

impl LightCut {
    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// The direction at which a cluster is shaded: tree node `node`'s luminance-weighted mean
    /// light direction (module docs).
    #[inline]
    pub fn direction(&self, node: u32) -> Vec3 {
        self.dirs[node as usize]
    }

    /// `brdf` averaged over tree node `node`'s cluster by the five-point rule of the module
    /// docs ("Cluster spread"); `brdf(direction(node))` for a cluster narrower than
    /// [`SPREAD_MIN_ANGLE`].
    #[inline]
    pub fn spread_average(&self, node: u32, mut brdf: impl FnMut(Vec3) -> Vec3) -> Vec3 {
        let mu = self.direction(node);
        if !self.spreads(node) {
            return brdf(mu);
        }
        let c = self.spread_cos[node as usize];
        let s = (1.0 - c * c).max(0.0).sqrt();
        let f = relight_sphere::warp::Frame::from_normal(mu);
        let mut sum = brdf(mu);
        for (x, y) in [(s, 0.0), (-s, 0.0), (0.0, s), (0.0, -s)] {
            sum += brdf(f.s * x + f.t * y + f.n * c);
        }
        sum * 0.2
    }

    /// A BRDF given as `[glossy, diffuse]` lobes (`MaterialEval::lobes`) averaged over tree
    /// node `node`'s cluster: the glossy lobe by the five-point rule ([`LightCut::spread_average`]),
    /// the diffuse lobe at the cluster's direction alone, as a Lambert material is (module
    /// docs, "Cluster spread": a diffuse lobe is smooth, and one evaluation instead of five
    /// is what makes a plastic's frame affordable).
    #[inline]
    pub fn spread_lobes(&self, node: u32, mut lobes: impl FnMut(Vec3) -> [Vec3; 2]) -> Vec3 {
        let [glossy, diffuse] = lobes(self.direction(node));
        if !self.spreads(node) {
            return glossy + diffuse;
        }
        let c = self.spread_cos[node as usize];
        let s = (1.0 - c * c).max(0.0).sqrt();
        let f = relight_sphere::warp::Frame::from_normal(self.direction(node));
        let mut sum = glossy;
        for (x, y) in [(s, 0.0), (-s, 0.0), (0.0, s), (0.0, -s)] {
            sum += lobes(f.s * x + f.t * y + f.n * c)[0];
        }
        sum * 0.2 + diffuse
    }

    /// `cos theta_p` of tree node `node`'s five-point rule if its cluster spreads
    /// ([`LightCut::spreads`]), else exactly 1 (one evaluation at its direction).
    #[inline]
    pub fn rule_cos(&self, node: u32) -> f32 {
        if self.spreads(node) {
            self.spread_cos[node as usize]
        } else {
            1.0
        }
    }

    /// Whether tree node `node`'s cluster is averaged by the five-point rule
    /// ([`LightCut::spread_average`]): wider than [`SPREAD_MIN_ANGLE`].
    #[inline]
    pub fn spreads(&self, node: u32) -> bool {
        self.spread_cos[node as usize] < SPREAD_MIN_COS
    }

    /// Whether the cut has no node (never for a built cut).
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// Build the cut of `power` (`l_i` per light, RGB, finite and non-negative) over `tree`
    /// with at most `budget` nodes. An all-black light gives the root alone.
    ///
    /// # Errors
    /// [`CutsError::Input`]: `budget == 0`, `power` of another length than the tree's
    /// lights, a NaN, infinite or negative value, or a negative or NaN `sigma`.
    pub fn build(
        tree: &LightTree,
        power: &[Vec3],
        sigma: f32,
        budget: usize,
    ) -> Result<LightCut, CutsError> {
        let n = tree.light_count();
        if budget == 0 {
            return Err(CutsError::Input("light cut budget must be >= 1".into()));
        }
        if power.len() != n {
            return Err(CutsError::Input(format!(
                "{} light values for a tree of {n} lights",
                power.len()
            )));
        }
        if let Some(i) = power
            .iter()
            .position(|p| !p.is_finite() || p.min_element() < 0.0)
        {
            return Err(CutsError::Input(format!(
                "light {i} has value {}: must be finite and non-negative",
                power[i]
            )));
        }
        if !(sigma >= 0.0 && sigma.is_finite()) {
            return Err(CutsError::Input(format!("light cut sigma {sigma}")));
        }
        let y: Vec<f64> = power.iter().map(|&p| luminance(p) as f64).collect();
        let mean_y = y.iter().sum::<f64>() / n as f64;
        let nodes = if mean_y > 0.0 {
            let normalised: Vec<f32> = y.iter().map(|&v| (v / mean_y) as f32).collect();
            let mut stats = NodeStats::default();
            stats.compute(tree, &normalised);
            let first = select_cut(tree, &stats, sigma * sigma, budget, &mut Vec::new());
            let met = !first.capped;
            (refine_by_intensity(tree, &stats, first.nodes, budget), met)
        } else {
            (vec![tree.root()], true)
        };
        // Cluster means from prefix sums over the leaves in rank order.
        let mut prefix: Vec<[f64; 3]> = Vec::with_capacity(n + 1);
        prefix.push([0.0; 3]);
        for &l in &tree.lights_in_order() {
            let (last, p) = (prefix[prefix.len() - 1], power[l as usize]);
            prefix.push([
                last[0] + p.x as f64,
                last[1] + p.y as f64,
                last[2] + p.z as f64,
            ]);
        }
        let (index, error_bound_met) = nodes;
        let value = index
            .iter()
            .map(|&p| {
                let node = tree.node(p);
                let (a, b) = (node.first as usize, (node.first + node.leaves) as usize);
                let c = |k: usize| ((prefix[b][k] - prefix[a][k]) / node.leaves as f64) as f32;
                Vec3::new(c(0), c(1), c(2))
            })
            .collect();
        let (dirs, spread_cos) = weighted_directions(tree, &y);
        Ok(LightCut {
            leftleaf: index.iter().map(|&p| tree.node(p).leftleaf).collect(),
            index,
            value,
            error_bound_met,
            dirs,
            spread_cos,
        })
    }
}

/// Every node's `(sum_i w_i at(i), sum_i w_i)` over its leaves `i` (`at` of a leaf's node
/// index, `w` indexed by light), summed up the post-order array (children precede their
/// parent): the weighted means of directions ([`weighted_directions`]) and of positions
/// (`super::local::weighted_positions`).
///
/// # Panics
/// If `w` is shorter than the tree's light count.
pub(crate) fn weighted_sums(
    tree: &LightTree,
    w: &[f64],
    at: impl Fn(u32) -> Vec3,
) -> Vec<([f64; 3], f64)> {
    let nodes = tree.nodes();
    let mut sums: Vec<([f64; 3], f64)> = Vec::with_capacity(nodes.len());
    for (i, node) in nodes.iter().enumerate() {
        let s = match node.kind {
            NodeKind::Leaf { light } => {
                let (d, w) = (at(i as u32), w[light as usize]);
                ([d.x as f64 * w, d.y as f64 * w, d.z as f64 * w], w)
            }
            NodeKind::Inner { left, right } => {
                let (a, b) = (sums[left as usize], sums[right as usize]);
                (
                    [a.0[0] + b.0[0], a.0[1] + b.0[1], a.0[2] + b.0[2]],
                    a.1 + b.1,
                )
            }
        };
        sums.push(s);
    }
    sums
}

/// Every node's mean direction weighted by `y` (one weight per light), summed up the
/// post-order array (children precede their parent); the tree's own direction where the
/// weights vanish or the weighted directions cancel (a mean shorter than 1e-3: a cluster
/// about as symmetric as the whole sphere, whose direction means little either way); and
/// each node's `cos theta_p = (5 R - 1) / 4` of the five-point rule (module docs), 1 where
/// the weights vanish.
fn weighted_directions(tree: &LightTree, y: &[f64]) -> (Vec<Vec3>, Vec<f32>) {
    let sums = weighted_sums(tree, y, |i| tree.direction(i));
    let spread_cos = sums
        .iter()
        .map(|(s, w)| {
            if *w > 0.0 {
                let r = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt() / w;
                ((5.0 * r - 1.0) / 4.0).clamp(-1.0, 1.0) as f32
            } else {
                1.0
            }
        })
        .collect();
    let dirs = sums
        .iter()
        .enumerate()
        .map(|(i, (s, w))| {
            let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
            if *w > 0.0 && len > 1e-3 * w {
                Vec3::new(
                    (s[0] / len) as f32,
                    (s[1] / len) as f32,
                    (s[2] / len) as f32,
                )
            } else {
                tree.direction(i as u32)
            }
        })
        .collect();
    (dirs, spread_cos)
}

/// Phase 2: split the brightest inner node (largest `|C| <y>`) until `budget` nodes or only
/// leaves remain. Returns the nodes sorted.
fn refine_by_intensity(
    tree: &LightTree,
    stats: &NodeStats,
    cut: Vec<u32>,
    budget: usize,
) -> Vec<u32> {
    let intensity = |p: u32| stats.mean[p as usize] * tree.node(p).leaves as f32;
    let mut out = Vec::with_capacity(budget);
    let mut heap = BinaryHeap::new();
    let push = |p: u32, out: &mut Vec<u32>, heap: &mut BinaryHeap<Keyed>| match tree.node(p).kind {
        NodeKind::Leaf { .. } => out.push(p),
        NodeKind::Inner { .. } => heap.push(Keyed {
            key: intensity(p),
            node: p,
        }),
    };
    let mut len = cut.len();
    for p in cut {
        push(p, &mut out, &mut heap);
    }
    while len < budget {
        let Some(top) = heap.pop() else { break };
        let NodeKind::Inner { left, right } = tree.node(top.node).kind else {
            unreachable!("only inner nodes are queued")
        };
        push(left, &mut out, &mut heap);
        push(right, &mut out, &mut heap);
        len += 1;
    }
    out.extend(heap.into_iter().map(|k| k.node));
    out.sort_unstable();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cuts::cut::VertexCuts;
    use crate::cuts::samples::{sample_power, EnvSamples};
    use relight_scene::scene::Environment;
    use relight_sphere::EnvMap;

    fn setup(n: usize) -> (EnvSamples, LightTree, Vec<Vec3>) {
        let s = EnvSamples::fibonacci(n, 0).unwrap();
        let t = LightTree::environment(&s.dirs).unwrap();
        // A sky with a small bright sun: the intensity phase must concentrate nodes there.
        let sun = Vec3::new(0.3, 0.8, 0.2).normalize();
        let map = EnvMap::latlong_from_fn(256, 129, |d| {
            let s = if d.dot(sun) > 0.995 { 500.0 } else { 0.0 };
            Vec3::new(0.2, 0.3, 0.5) * (1.0 + d.y.max(0.0)) + Vec3::splat(s)
        });
        let power = sample_power(&s, &Environment::new(map)).unwrap();
        (s, t, power)
    }

    /// The five-point rule keeps each cluster's first moment: for a BRDF linear in the
    /// direction, `f(w) = a . w`, the average over the rule is the luminance-weighted mean
    /// of `f` over the cluster's lights (math against math, every node of a tree under a
    /// sky with a sun); and a constant BRDF stays constant.
    #[test]
    fn spread_average_keeps_each_clusters_first_moment() {
        let (s, t, power) = setup(2048);
        let c = LightCut::build(&t, &power, 2.0, 64).unwrap();
        let a = Vec3::new(0.3, -1.2, 0.7);
        let order = t.lights_in_order();
        let mut wide = 0;
        for p in 0..t.nodes().len() as u32 {
            let node = t.node(p);
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for &l in &order[node.first as usize..(node.first + node.leaves) as usize] {
                let y = luminance(power[l as usize]) as f64;
                num += y * a.dot(s.dirs[l as usize]) as f64;
                den += y;
            }
            let got = c.spread_average(p, |w| Vec3::splat(a.dot(w))).x as f64;
            let konst = c.spread_average(p, |_| Vec3::splat(2.5)).x;
            assert!((konst - 2.5).abs() < 1e-5, "node {p}: {konst}");
            if c.spread_cos[p as usize] < SPREAD_MIN_COS {
                wide += 1;
                let want = num / den;
                assert!(
                    (got - want).abs() < 1e-4 * a.length() as f64,
                    "node {p}: {got} vs {want}"
                );
            }
        }
        assert!(wide > 100, "the tree has wide clusters: {wide}");
    }

    /// `spread_lobes` averages the glossy lobe as `spread_average` does and takes the diffuse
    /// lobe at the cluster's direction, on every node of a tree with wide clusters.
    #[test]
    fn spread_lobes_spread_the_glossy_lobe_only() {
        let (_, t, power) = setup(2048);
        let c = LightCut::build(&t, &power, 2.0, 64).unwrap();
        let glossy = |w: Vec3| Vec3::new(w.x.max(0.0).powi(8), w.y * w.y, 1.0 + w.z);
        let diffuse = |w: Vec3| Vec3::new(0.5 + w.x, w.y.max(0.0), 2.0);
        let mut differs = 0;
        for p in 0..t.nodes().len() as u32 {
            let got = c.spread_lobes(p, |w| [glossy(w), diffuse(w)]);
            let want = c.spread_average(p, glossy) + diffuse(c.direction(p));
            assert!(
                (got - want).abs().max_element() < 1e-5,
                "node {p}: {got} vs {want}"
            );
            let all_spread = c.spread_average(p, |w| glossy(w) + diffuse(w));
            differs += usize::from((all_spread - got).abs().max_element() > 1e-4);
        }
        assert!(
            differs > 100,
            "the diffuse lobe is not spread: {differs} nodes differ"
        );
    }

    #[test]
    fn spread_min_cos_is_the_angles_cosine() {
        assert!((SPREAD_MIN_COS - SPREAD_MIN_ANGLE.cos()).abs() < 1e-6);
    }

    fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
    }

    /// Check a light cut as a cut (tiling) through the vertex-cut validator.
    fn assert_is_cut(t: &LightTree, c: &LightCut) {
        let vc = VertexCuts {
            offsets: vec![0, c.len() as u64],
            index: c.index.clone(),
            leftleaf: c.leftleaf.clone(),
            value: vec![0; c.len()],
            capped: vec![],
        };
        vc.validate(t).unwrap();
    }

    #[test]
    fn budgets_are_filled_and_energy_is_exact() {
        let (s, t, power) = setup(8192);
        let f64s = |v: Vec3| [v.x as f64, v.y as f64, v.z as f64];
        let total = power.iter().fold([0.0; 3], |a, &p| add(a, f64s(p)));
        for budget in LIGHT_CUT_BUDGETS {
            let c = LightCut::build(&t, &power, DEFAULT_LIGHT_SIGMA, budget).unwrap();
            assert_is_cut(&t, &c);
            assert_eq!(c.len(), budget);
            // Sum of |C| <l> over the cut is the total power (means preserve sums).
            let sum = c.index.iter().zip(&c.value).fold([0.0; 3], |a, (&p, &v)| {
                add(a, f64s(v * t.node(p).leaves as f32))
            });
            for k in 0..3 {
                // f32 means times leaf counts: relative 1e-5.
                assert!(
                    (sum[k] - total[k]).abs() < 1e-5 * total[k],
                    "{sum:?} vs {total:?}"
                );
            }
            // The sun (a cap of 0.03 sr, ~20 of the 8192 lights, 3/4 of the power) is
            // resolved down to single lights at every budget: the intensity phase splits it
            // before any sky cluster.
            let leaves_of = |light: usize| {
                let rank = t.node(t.leaf_of_light(light)).first;
                let k = c
                    .index
                    .iter()
                    .position(|&p| {
                        let n = t.node(p);
                        (n.first..n.first + n.leaves).contains(&rank)
                    })
                    .unwrap();
                t.node(c.index[k]).leaves
            };
            let sun = Vec3::new(0.3, 0.8, 0.2).normalize();
            let in_sun: Vec<usize> = (0..s.len())
                .filter(|&i| s.dirs[i].dot(sun) > 0.997)
                .collect();
            assert!(in_sun.len() >= 8);
            for &i in &in_sun {
                assert_eq!(leaves_of(i), 1, "budget {budget}: sun light {i}");
            }
        }
    }

    #[test]
    fn error_phase_first_then_reported() {
        let (_, t, power) = setup(4096);
        let tight = LightCut::build(&t, &power, 0.01, 128).unwrap();
        assert!(
            !tight.error_bound_met,
            "sigma 0.01 cannot be met by 128 nodes"
        );
        assert_eq!(tight.len(), 128);
        let loose = LightCut::build(&t, &power, 1e6, 300).unwrap();
        assert!(loose.error_bound_met);
        assert_eq!(loose.len(), 300);
        // A budget above the node count ends with every leaf.
        let all = LightCut::build(&t, &power, 0.0, 100_000).unwrap();
        assert_eq!(all.len(), 4096);
        assert!(all.error_bound_met);
        assert_is_cut(&t, &all);
    }

    /// Even power: every node's shading direction is the tree's own; one bright light: every
    /// node holding it points at it; a black sky falls back to the tree's directions.
    #[test]
    fn cluster_directions_follow_the_power() {
        let (_, tree, _) = setup(512);
        let even = vec![Vec3::ONE; 512];
        let lc = LightCut::build(&tree, &even, 2.0, 16).unwrap();
        for i in 0..tree.nodes().len() as u32 {
            assert!(
                (lc.direction(i) - tree.direction(i)).length() < 1e-4,
                "node {i}"
            );
        }
        let mut sun = vec![Vec3::splat(1e-3); 512];
        sun[77] = Vec3::splat(1e4);
        let lc = LightCut::build(&tree, &sun, 2.0, 16).unwrap();
        let leaf = tree.leaf_of_light(77);
        let sun_dir = tree.direction(leaf);
        let mut holding = 0;
        for i in 0..tree.nodes().len() as u32 {
            let n = tree.node(i);
            if (n.leftleaf..=i).contains(&leaf) {
                // Every ancestor of the sun's leaf: at most 1e-3 x 511 of the power is elsewhere.
                assert!(lc.direction(i).dot(sun_dir) > 0.999, "node {i}");
                holding += 1;
            }
            assert!((lc.direction(i).length() - 1.0).abs() < 1e-5);
        }
        assert!(holding > 5, "{holding}");
        let black = LightCut::build(&tree, &vec![Vec3::ZERO; 512], 2.0, 16).unwrap();
        assert_eq!(
            black.dirs,
            (0..tree.nodes().len() as u32)
                .map(|i| tree.direction(i))
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn bad_input_refused_and_black_is_root() {
        let (_, t, mut power) = setup(256);
        assert!(LightCut::build(&t, &power, 1.0, 0).is_err());
        assert!(LightCut::build(&t, &power[..10], 1.0, 8).is_err());
        assert!(LightCut::build(&t, &power, f32::NAN, 8).is_err());
        power[3] = Vec3::new(0.0, -1.0, 0.0);
        assert!(LightCut::build(&t, &power, 1.0, 8).is_err());
        let black = vec![Vec3::ZERO; 256];
        let c = LightCut::build(&t, &black, 1.0, 128).unwrap();
        assert_eq!(c.index, vec![t.root()]);
        assert_eq!(c.value, vec![Vec3::ZERO]);
    }
}
