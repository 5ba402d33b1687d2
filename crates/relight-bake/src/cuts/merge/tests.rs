//! Property tests of the merge: the fast traversal against slow references on the leaves,
//! Eq. 8's bound per merged cluster, and the total error against each cut's own error.

use super::*;
use crate::cuts::cut::{select_cut, NodeStats, VertexCuts};
use crate::cuts::samples::fibonacci_point;
use crate::cuts::tree::LightTree;
use relight_sphere::warp::{square_to_uniform_sphere, Rng};

/// A cut of `values` at threshold `sigma`, with unquantised means and its total `M2`.
struct TestCut {
    index: Vec<u32>,
    leftleaf: Vec<u32>,
    mean: Vec<f32>,
    m2: f64,
}

impl TestCut {
    fn new(tree: &LightTree, values: &[f32], sigma: f32) -> TestCut {
        let mut s = NodeStats::default();
        s.compute(tree, values);
        let c = select_cut(tree, &s, sigma * sigma, usize::MAX, &mut Vec::new());
        TestCut {
            leftleaf: c.nodes.iter().map(|&p| tree.node(p).leftleaf).collect(),
            mean: c.nodes.iter().map(|&p| s.mean[p as usize]).collect(),
            m2: c.nodes.iter().map(|&p| s.m2[p as usize] as f64).sum(),
            index: c.nodes,
        }
    }

    fn keys(&self) -> CutKeys<'_> {
        CutKeys {
            index: &self.index,
            leftleaf: &self.leftleaf,
        }
    }

    /// Slow reference: the cut's piecewise-constant value at every light.
    fn expand(&self, tree: &LightTree) -> Vec<f64> {
        let order = tree.lights_in_order();
        let mut out = vec![f64::NAN; tree.light_count()];
        for (&p, &m) in self.index.iter().zip(&self.mean) {
            let n = tree.node(p);
            for &l in &order[n.first as usize..(n.first + n.leaves) as usize] {
                out[l as usize] = m as f64;
            }
        }
        out
    }
}

fn tree(n: usize) -> (LightTree, Vec<Vec3>) {
    let d: Vec<Vec3> = (0..n).map(|i| fibonacci_point(i, n)).collect();
    (LightTree::environment(&d).unwrap(), d)
}

/// A visibility-like function: a random cosine lobe cut by two random half-spaces, in [0, 1].
fn random_visibility(dirs: &[Vec3], rng: &mut Rng) -> Vec<f32> {
    let n = square_to_uniform_sphere(rng.next_vec2());
    let (a, b) = (
        square_to_uniform_sphere(rng.next_vec2()),
        square_to_uniform_sphere(rng.next_vec2()),
    );
    let (ta, tb) = (rng.next_f32() - 0.5, rng.next_f32() - 0.5);
    dirs.iter()
        .map(|&w| {
            let blocked = w.dot(a) > ta && w.dot(b) > tb;
            if blocked {
                0.0
            } else {
                w.dot(n).max(0.0)
            }
        })
        .collect()
}

/// Slow reference of the merged cut: for every leaf in rank order, the deepest node (lowest
/// index) among the cuts' nodes containing it; consecutive repeats collapsed.
fn merged_slow(tree: &LightTree, cuts: &[&TestCut]) -> Vec<u32> {
    let mut out: Vec<u32> = Vec::new();
    for rank in 0..tree.light_count() as u32 {
        let deepest = cuts
            .iter()
            .map(|c| {
                *c.index
                    .iter()
                    .find(|&&p| {
                        let n = tree.node(p);
                        (n.first..n.first + n.leaves).contains(&rank)
                    })
                    .unwrap()
            })
            .min()
            .unwrap();
        if out.last() != Some(&deepest) {
            out.push(deepest);
        }
    }
    out
}

#[test]
fn fast_traversal_equals_slow_reference() {
    let (t, dirs) = tree(1500);
    let mut rng = Rng::new(11, 0);
    for trial in 0..12 {
        let sig = [0.3f32, 1.0, 2.0, 5.0];
        let cuts: Vec<TestCut> = (0..4)
            .map(|j| {
                TestCut::new(
                    &t,
                    &random_visibility(&dirs, &mut rng),
                    sig[(trial + j) % 4],
                )
            })
            .collect();
        let dense: Vec<Vec<f64>> = cuts.iter().map(|c| c.expand(&t)).collect();
        // Merged clusters against the slow union, for 1 to 4 cuts.
        let mut visited = Vec::new();
        merge_cuts([cuts[0].keys()], |n, _| visited.push(n.index));
        assert_eq!(visited, cuts[0].index);
        visited.clear();
        merge_cuts([cuts[0].keys(), cuts[1].keys()], |n, _| {
            visited.push(n.index)
        });
        assert_eq!(visited, merged_slow(&t, &[&cuts[0], &cuts[1]]));
        visited.clear();
        let keys4 = [
            cuts[0].keys(),
            cuts[1].keys(),
            cuts[2].keys(),
            cuts[3].keys(),
        ];
        merge_cuts(keys4, |n, pos| {
            visited.push(n.index);
            // The reported positions are the cuts' nodes containing the cluster.
            for (j, c) in cuts.iter().enumerate() {
                let p = c.index[pos[j]];
                assert!(c.leftleaf[pos[j]] <= n.leftleaf && n.index <= p);
            }
        });
        let all: Vec<&TestCut> = cuts.iter().collect();
        assert_eq!(visited, merged_slow(&t, &all));
        // Products of 2, 3 and 4 cuts against the dense products of the expansions.
        let p2 = product(
            [cuts[0].keys(), cuts[1].keys()],
            [&cuts[0].mean, &cuts[1].mean],
        );
        let d2: f64 = (0..t.light_count())
            .map(|i| dense[0][i] * dense[1][i])
            .sum();
        // f32 means multiplied in f64: relative 1e-6.
        assert!((p2 - d2).abs() <= 1e-6 * (1.0 + d2.abs()), "{p2} vs {d2}");
        let p3 = product(
            [cuts[0].keys(), cuts[1].keys(), cuts[2].keys()],
            [&cuts[0].mean, &cuts[1].mean, &cuts[2].mean],
        );
        let d3: f64 = (0..t.light_count())
            .map(|i| dense[0][i] * dense[1][i] * dense[2][i])
            .sum();
        assert!((p3 - d3).abs() <= 1e-6 * (1.0 + d3.abs()), "{p3} vs {d3}");
        let p4 = product(
            keys4,
            [&cuts[0].mean, &cuts[1].mean, &cuts[2].mean, &cuts[3].mean],
        );
        let d4: f64 = (0..t.light_count())
            .map(|i| dense.iter().map(|d| d[i]).product::<f64>())
            .sum();
        assert!((p4 - d4).abs() <= 1e-6 * (1.0 + d4.abs()), "{p4} vs {d4}");
        // A single cut's integral is exact: cluster means preserve sums.
        let one = product([cuts[0].keys()], [&cuts[0].mean]);
        assert!((one - dense[0].iter().sum::<f64>()).abs() < 1e-6 * (1.0 + one));
    }
}

#[test]
fn eq8_double_product_bound_holds_per_cluster() {
    // |sum_{C} a b - |C| <a>_C <b>_C| <= sigma_a sigma_b on every merged cluster C (Eq. 8):
    // Cauchy-Schwarz, with |C| var_C <= M2 of the containing cut node <= sigma^2 (Eq. 7).
    let (t, dirs) = tree(2048);
    let order = t.lights_in_order();
    let mut rng = Rng::new(12, 0);
    let mut tight = 0.0f64;
    for trial in 0..10 {
        let a = random_visibility(&dirs, &mut rng);
        let b = random_visibility(&dirs, &mut rng);
        let (sa, sb) = ([0.5f32, 1.5, 3.0][trial % 3], [2.0f32, 0.7, 1.0][trial % 3]);
        let (ca, cb) = (TestCut::new(&t, &a, sa), TestCut::new(&t, &b, sb));
        merge_cuts([ca.keys(), cb.keys()], |node, _| {
            let n = t.node(node.index);
            let ls = &order[n.first as usize..(n.first + n.leaves) as usize];
            let k = ls.len() as f64;
            let ma = ls.iter().map(|&l| a[l as usize] as f64).sum::<f64>() / k;
            let mb = ls.iter().map(|&l| b[l as usize] as f64).sum::<f64>() / k;
            let ab: f64 = ls
                .iter()
                .map(|&l| a[l as usize] as f64 * b[l as usize] as f64)
                .sum();
            let err = (ab - k * ma * mb).abs();
            let bound = sa as f64 * sb as f64;
            // 1e-5: f32 statistics that selected the cut.
            assert!(err <= bound * (1.0 + 1e-5) + 1e-6, "{err} > {bound}");
            tight = tight.max(err / bound);
        });
    }
    // The bound is not vacuous on these functions: some cluster comes within a few times.
    assert!(tight > 0.05, "largest err / bound {tight}");
}

#[test]
fn merged_product_error_is_bounded_by_the_cuts_errors() {
    // sum a~ b~ - sum a b = sum (a~ - a) b~ + sum a (b~ - b), so by Cauchy-Schwarz the error
    // is at most |a~ - a| |b~| + |a| |b~ - b| with |a~ - a|^2 = sum of the cut's M2.
    let (t, dirs) = tree(2048);
    let mut rng = Rng::new(13, 0);
    for sigma in [0.5f32, 1.5, 3.0] {
        let a = random_visibility(&dirs, &mut rng);
        let b = random_visibility(&dirs, &mut rng);
        let (ca, cb) = (TestCut::new(&t, &a, sigma), TestCut::new(&t, &b, sigma));
        let merged = product([ca.keys(), cb.keys()], [&ca.mean, &cb.mean]);
        let exact: f64 = a.iter().zip(&b).map(|(&x, &y)| x as f64 * y as f64).sum();
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let a64: Vec<f64> = a.iter().map(|&x| x as f64).collect();
        let bound = ca.m2.sqrt() * norm(&cb.expand(&t)) + norm(&a64) * cb.m2.sqrt();
        assert!(
            (merged - exact).abs() <= bound * (1.0 + 1e-5),
            "sigma {sigma}"
        );
        // Each cut's own L2 error is within |cut| sigma^2 (Eq. 6 per node).
        assert!(ca.m2 <= ca.index.len() as f64 * (sigma * sigma) as f64 * (1.0 + 1e-5));
    }
}

/// Quantised cuts of three vertex functions.
fn vertex_cuts(t: &LightTree, fs: &[Vec<f32>], sigma: f32) -> VertexCuts {
    let mut vc = VertexCuts::default();
    let mut s = NodeStats::default();
    for f in fs {
        s.compute(t, f);
        let c = select_cut(t, &s, sigma * sigma, usize::MAX, &mut Vec::new());
        vc.push(t, &c, &s);
    }
    vc.validate(t).unwrap();
    vc
}

#[test]
fn interpolation_equals_dense_interpolation() {
    let (t, dirs) = tree(1024);
    let mut rng = Rng::new(14, 0);
    let fs: Vec<Vec<f32>> = (0..3).map(|_| random_visibility(&dirs, &mut rng)).collect();
    let vc = vertex_cuts(&t, &fs, 1.0);
    let w = [0.2f32, 0.5, 0.3];
    let (nodes, means) = interpolate([vc.cut(0), vc.cut(1), vc.cut(2)], w);
    // Dense: expand each quantised cut to the leaves and interpolate there.
    let order = t.lights_in_order();
    let mut dense = vec![0.0f32; 1024];
    for (j, &wj) in w.iter().enumerate() {
        let c = vc.cut(j);
        for (&p, &q) in c.index.iter().zip(c.value) {
            let n = t.node(p);
            for &l in &order[n.first as usize..(n.first + n.leaves) as usize] {
                dense[l as usize] += wj * dequantise(q);
            }
        }
    }
    for (node, &m) in nodes.iter().zip(&means) {
        let n = t.node(node.index);
        assert_eq!(node.leaves(), n.leaves);
        for &l in &order[n.first as usize..(n.first + n.leaves) as usize] {
            // Same three f32 products, summed in the same order.
            assert!((dense[l as usize] - m).abs() < 1e-6);
        }
    }
    let covered: u32 = nodes.iter().map(|n| n.leaves()).sum();
    assert_eq!(covered, 1024);
}

#[test]
fn shade_matches_slow_reference_and_converges_to_exact() {
    let (t, dirs) = tree(2048);
    let mut rng = Rng::new(15, 0);
    let fs: Vec<Vec<f32>> = (0..3).map(|_| random_visibility(&dirs, &mut rng)).collect();
    let power: Vec<Vec3> = dirs
        .iter()
        .map(|w| Vec3::new(1.0 + w.x.max(0.0) * 20.0, 1.0, 0.5 + w.y * w.y) * 1e-3)
        .collect();
    let h = Vec3::new(0.2, 0.9, 0.1).normalize();
    // A glossy-looking BRDF lobe (any smooth positive function of the direction will do).
    let brdf = |w: Vec3| Vec3::new(0.3, 0.2, 0.1) + Vec3::splat(2.0 * w.dot(h).max(0.0).powi(8));
    let bary = [0.6f32, 0.1, 0.3];
    let order = t.lights_in_order();
    for (sigma, budget) in [(1.0f32, 256usize), (2.0, 128), (0.0, 1_000_000)] {
        let vc = vertex_cuts(&t, &fs, sigma);
        let lc = LightCut::build(&t, &power, sigma, budget).unwrap();
        let fast = shade(&lc, [vc.cut(0), vc.cut(1), vc.cut(2)], bary, false, |w| {
            [brdf(w), Vec3::ZERO]
        });
        // Slow: every leaf takes each cut's containing node's mean and the BRDF at the
        // deepest of those nodes.
        let find = |index: &[u32], rank: u32| {
            index
                .iter()
                .position(|&p| {
                    let n = t.node(p);
                    (n.first..n.first + n.leaves).contains(&rank)
                })
                .unwrap()
        };
        let mut slow = Vec3::ZERO;
        for rank in 0..2048u32 {
            let li = find(&lc.index, rank);
            let mut deepest = lc.index[li];
            let mut v = 0.0f32;
            for (j, &b) in bary.iter().enumerate() {
                let c = vc.cut(j);
                let k = find(c.index, rank);
                deepest = deepest.min(c.index[k]);
                v += b * dequantise(c.value[k]);
            }
            if v > 0.0 {
                slow += lc.value[li] * v * brdf(lc.direction(deepest));
            }
        }
        // f32 sums over 2048 leaves vs over the merged clusters: relative 1e-4.
        assert!(
            (fast - slow).length() <= 1e-4 * slow.length(),
            "{fast} vs {slow}"
        );
        if sigma == 0.0 {
            // Every cut at the leaves: the exact sum over the lights.
            let exact: Vec3 = (0..2048)
                .map(|i| {
                    let v: f32 = (0..3).map(|j| bary[j] * fs[j][i]).sum();
                    power[i] * v * brdf(dirs[i])
                })
                .sum();
            // Quantisation of v to 16 bits: relative 1e-4.
            assert!(
                (fast - exact).length() <= 1e-4 * exact.length(),
                "{fast} vs {exact}"
            );
        }
    }
    let _ = order;
}
