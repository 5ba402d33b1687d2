//! One triangle's merged cut (Cheslack-Postava et al. 2008, sec. 3.2 merge, sec. 4.2 Eq. 5):
//! the per-triangle frame [`super::CutsShader::render_merged`], the merge of the three vertex
//! cuts with the light cut done once per triangle and band of rows and summed per fragment.

use super::cache::{Cluster, LightTables, NodeInfo};
use super::corners::LANES;
use super::lanes;
use super::CutsShader;
use glam::Vec3;
use relight_bake::cuts::cut::dequantise;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::merge::{merge_cuts, CutKeys};
use relight_scene::material::microfacet::{self, PlasticTables};
use std::f32::consts::PI;

thread_local! {
    /// Each rendering thread's [`TriangleCut`] (reused, so a frame allocates once per thread).
    pub(super) static TRIANGLE_CUT: std::cell::RefCell<TriangleCut> = Default::default();
}

/// One triangle's merged cut: the union of its three vertex cuts and the light cut (the
/// traversal of sec. 3.2), with what the per-fragment sum of Eq. 5 needs of each cluster
/// `k`: `|C'_k| <L O>_k`, the three corners' visibility means and the cluster's direction,
/// as structure-of-arrays padded with zero clusters to a multiple of [`LANES`]. Clusters no
/// corner sees, or that hold no light, are dropped (they add nothing). Built for the cluster
/// spread ([`TriangleCut::spread`]), each cluster also keeps the `cos theta_p` of its
/// five-point rule ([`LightCut::spread_average`]), 1 for a cluster shaded at its direction
/// alone, so the GGX lanes (`shade_cuts::lanes`) build the rule's directions themselves.
#[derive(Default)]
pub(super) struct TriangleCut {
    /// `|C'_k| <L O>_k`, per colour channel.
    power: [Vec<f32>; 3],
    /// `<v_j>_k` of corners `j = 0, 1, 2`.
    vis: [Vec<f32>; 3],
    /// The cluster's mean direction ([`relight_bake::cuts::tree::LightTree::direction`]),
    /// per axis.
    dir: [Vec<f32>; 3],
    /// `cos theta_p` of the cluster's five-point rule, exactly 1 for one evaluation (always
    /// without the spread).
    ring_cos: Vec<f32>,
    /// The cluster's tree node (post-order index; [`LightCut::spread_average`]).
    node: Vec<u32>,
    /// Clusters of this triangle, padding included (the arrays may be longer).
    len: usize,
    /// Whether built for the cluster spread (module docs).
    pub(super) spread: bool,
}

impl TriangleCut {
    /// Clusters, padding included.
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// Merge triangle `tri`'s cuts with `light` into `self` (its arrays reused: they only
    /// grow, and are written by index; a merged cut is at most as long as its four cuts
    /// together), for the cluster spread if `spread`.
    pub(super) fn build(
        &mut self,
        shader: &CutsShader<'_>,
        light: &LightCut,
        tri: u32,
        spread: bool,
    ) {
        let cuts = shader.vertex_cuts(tri);
        self.begin(
            spread,
            light.len() + cuts.iter().map(|c| c.index.len()).sum::<usize>(),
        );
        let keys = [
            CutKeys::from(light),
            cuts[0].into(),
            cuts[1].into(),
            cuts[2].into(),
        ];
        let mut out = self.columns();
        let mut n = 0;
        merge_cuts(keys, |node, pos| {
            let q = [
                cuts[0].value[pos[1]],
                cuts[1].value[pos[2]],
                cuts[2].value[pos[3]],
            ];
            let power = light.value[pos[0]] * node.leaves() as f32;
            if q == [0; 3] || power == Vec3::ZERO {
                return;
            }
            let info = NodeInfo {
                dir: light.direction(node.index).to_array(),
                ring_cos: if spread {
                    light.rule_cos(node.index)
                } else {
                    1.0
                },
            };
            out.put(n, node.index, power, q, info);
            n += 1;
        });
        self.finish(n);
    }

    /// Triangle `tri`'s visibility union into `record` (cleared first): the traversal of
    /// sec. 3.2 over its three vertex cuts, the clusters no corner sees dropped
    /// (`shade_cuts::cache`, step 1).
    pub(super) fn union(shader: &CutsShader<'_>, tri: u32, record: &mut Vec<Cluster>) {
        record.clear();
        let cuts = shader.vertex_cuts(tri);
        merge_cuts(cuts.map(CutKeys::from), |node, pos| {
            let vis = [
                cuts[0].value[pos[0]],
                cuts[1].value[pos[1]],
                cuts[2].value[pos[2]],
            ];
            if vis != [0; 3] {
                record.push(Cluster {
                    node: node.index,
                    leftleaf: node.leftleaf,
                    vis,
                });
            }
        });
    }

    /// A triangle's merged cut into `self` from its visibility union `union` and the light
    /// cut `light` (its `tables`), by one pass instead of the traversal (`shade_cuts::cache`,
    /// step 2): the clusters of [`TriangleCut::build`] in its order and arithmetic, so the
    /// same bits.
    pub(super) fn walk(
        &mut self,
        light: &LightCut,
        tables: &LightTables,
        union: &[Cluster],
        spread: bool,
    ) {
        // A merged cluster is a union cluster or a light-cut node inside one.
        self.begin(spread, union.len() + light.len());
        let mut out = self.columns();
        let mut n = 0;
        for c in union {
            // The light-cut node holding the cluster's leftmost leaf (every cut partitions
            // the leaves): the cluster itself or an ancestor (post-order index at least the
            // cluster's: the merged cluster is the union's), else the first of the light-cut
            // nodes inside the cluster (the merged clusters are those, up to its index).
            let mut p = tables.cover[c.leftleaf as usize] as usize;
            if light.index[p] >= c.node {
                n += out.lit((light, tables), spread, n, (c.node, c.leftleaf), p, c.vis);
                continue;
            }
            loop {
                let node = (light.index[p], light.leftleaf[p]);
                n += out.lit((light, tables), spread, n, node, p, c.vis);
                p += 1;
                if p == light.len() || light.index[p] > c.node {
                    break;
                }
            }
        }
        self.finish(n);
    }

    /// Start a merged cut of at most `clusters` clusters, for the spread if `spread`.
    fn begin(&mut self, spread: bool, clusters: usize) {
        self.spread = spread;
        self.reserve(clusters);
    }

    /// The arrays, each cut to the room reserved (so one bound check covers a cluster).
    fn columns(&mut self) -> Columns<'_> {
        fn cut(a: &mut [Vec<f32>; 3], bound: usize) -> [&mut [f32]; 3] {
            a.each_mut().map(|x| &mut x[..bound])
        }
        let bound = self.node.len();
        Columns {
            node: &mut self.node[..bound],
            ring_cos: &mut self.ring_cos[..bound],
            power: cut(&mut self.power, bound),
            vis: cut(&mut self.vis, bound),
            dir: cut(&mut self.dir, bound),
        }
    }

    /// Room for `clusters` clusters (padding included).
    fn reserve(&mut self, clusters: usize) {
        let bound = clusters.next_multiple_of(LANES);
        if self.power[0].len() < bound {
            for a in [&mut self.power, &mut self.vis, &mut self.dir] {
                a.iter_mut().for_each(|x| x.resize(bound, 0.0));
            }
            self.ring_cos.resize(bound, 1.0);
            self.node.resize(bound, 0);
        }
    }

    /// `n` clusters written: pad the last lane group with zero clusters.
    fn finish(&mut self, n: usize) {
        self.len = n.next_multiple_of(LANES);
        for a in [&mut self.power, &mut self.vis, &mut self.dir] {
            a.iter_mut().for_each(|x| x[n..self.len].fill(0.0));
        }
        self.ring_cos[n..self.len].fill(1.0);
    }

    /// Every field of every cluster, padding included, as bits (tests: two ways to the
    /// same merged cut).
    #[cfg(test)]
    pub(super) fn bits(&self) -> (Vec<[u32; 11]>, [glam::Vec3; 3], bool) {
        let clusters = (0..self.len)
            .map(|k| {
                let f = |a: &[Vec<f32>; 3], j: usize| a[j][k].to_bits();
                [
                    self.node[k],
                    self.ring_cos[k].to_bits(),
                    f(&self.power, 0),
                    f(&self.power, 1),
                    f(&self.power, 2),
                    f(&self.vis, 0),
                    f(&self.vis, 1),
                    f(&self.vis, 2),
                    f(&self.dir, 0),
                    f(&self.dir, 1),
                    f(&self.dir, 2),
                ]
            })
            .collect();
        (clusters, self.corner_sums(), self.spread)
    }

    /// `sum_k power_k vis_k[j]` per corner `j` (the Lambert sum without a per-cluster BRDF),
    /// in the clusters' order (the zero clusters of the padding add `+0`).
    pub(super) fn corner_sums(&self) -> [Vec3; 3] {
        let mut sums = [Vec3::ZERO; 3];
        for k in 0..self.len {
            let power = Vec3::new(self.power[0][k], self.power[1][k], self.power[2][k]);
            for (j, sum) in sums.iter_mut().enumerate() {
                *sum += power * self.vis[j][k];
            }
        }
        sums
    }

    /// Cluster `k`'s power, visibility interpolated with `b`, direction and tree node.
    #[inline]
    pub(super) fn cluster(&self, k: usize, b: [f32; 3]) -> (Vec3, f32, Vec3, u32) {
        let at = |a: &[Vec<f32>; 3]| Vec3::new(a[0][k], a[1][k], a[2][k]);
        let v = b[0] * self.vis[0][k] + b[1] * self.vis[1][k] + b[2] * self.vis[2][k];
        (at(&self.power), v, at(&self.dir), self.node[k])
    }

    /// `sum_k power_k (b . vis_k) max(0, n . dir_k)`: Eq. 5 for a Lambert BRDF without its
    /// `albedo / pi`, over [`LANES`] partial sums.
    pub(super) fn lambert_sum(&self, b: [f32; 3], n: Vec3) -> Vec3 {
        fn chunks(a: &[Vec<f32>; 3]) -> [&[[f32; LANES]]; 3] {
            a.each_ref().map(|x| x.as_chunks::<LANES>().0)
        }
        let groups = self.len / LANES;
        let (p, v, d) = (chunks(&self.power), chunks(&self.vis), chunks(&self.dir));
        let mut acc = [[0.0f32; LANES]; 3];
        for i in 0..groups {
            for l in 0..LANES {
                let c = (n.x * d[0][i][l] + n.y * d[1][i][l] + n.z * d[2][i][l]).max(0.0);
                let w = (b[0] * v[0][i][l] + b[1] * v[1][i][l] + b[2] * v[2][i][l]) * c;
                for ch in 0..3 {
                    acc[ch][l] += p[ch][i][l] * w;
                }
            }
        }
        Vec3::from_array(acc.map(|a| a.iter().sum()))
    }

    /// `sum_k power_k (b . vis_k) f(v, dir_k)` for the GGX conductor of `Material::eval`
    /// without its specular colour, `f = D(h) G1(v, h) G1(w, h) / (4 n.v)` (height-separable
    /// Smith masking, `relight_scene::material::microfacet`), evaluated in world space over
    /// [`LANES`] partial sums: `n . h`, `tan^2` of `w` from `n . w`, and `G1(v, h)`, which
    /// depends on the fragment only, hoisted. `n . v > 0` (the caller's one-sided test).
    pub(super) fn ggx_sum(&self, b: [f32; 3], n: Vec3, v: Vec3, alpha: f32) -> Vec3 {
        let (a2, k) = ggx_constants(n, v, alpha);
        lanes::ggx(&self.groups(), &lanes::GgxFragment { b, n, v, a2 }) * k
    }

    /// `sum_k power_k (b . vis_k) f(v, dir_k)` for the GGX plastic of `Material::eval`
    /// (`f = specular F(v . h) D G1 G1 / (4 n.v) + diffuse / (1 - Fdr) / (pi eta^2) t(n.v)
    /// t(n.w) n.w`), `tables` its `PlasticTables`, both terms over [`LANES`]
    /// (`lanes::plastic`). `n . v > 0` (the caller's one-sided test).
    pub(super) fn plastic_sum(
        &self,
        b: [f32; 3],
        n: Vec3,
        v: Vec3,
        (diffuse, specular, alpha, ior): (Vec3, Vec3, f32, f32),
        tables: &PlasticTables,
    ) -> Vec3 {
        let (a2, k) = ggx_constants(n, v, alpha);
        let ci = n.dot(v);
        let f = lanes::PlasticFragment {
            ggx: lanes::GgxFragment { b, n, v, a2 },
            ior,
            transmittance: &tables.external_transmittance,
        };
        let [spec, diff] = lanes::plastic(&self.groups(), &f);
        let d = tables.transmittance(ci) / ((1.0 - tables.internal_reflectance) * PI * ior * ior);
        specular * k * spec + diffuse * d * diff
    }

    /// The clusters as [`LANES`]-wide groups (padding included).
    fn groups(&self) -> lanes::Groups<'_> {
        fn chunks(a: &[Vec<f32>; 3], len: usize) -> [&[[f32; LANES]]; 3] {
            [0, 1, 2].map(|c| a[c][..len].as_chunks::<LANES>().0)
        }
        lanes::Groups {
            power: chunks(&self.power, self.len),
            vis: chunks(&self.vis, self.len),
            dir: chunks(&self.dir, self.len),
            ring_cos: self
                .spread
                .then(|| self.ring_cos[..self.len].as_chunks::<LANES>().0),
        }
    }
}

/// [`TriangleCut`]'s arrays while a merged cut is written, all of one length.
struct Columns<'a> {
    node: &'a mut [u32],
    ring_cos: &'a mut [f32],
    power: [&'a mut [f32]; 3],
    vis: [&'a mut [f32]; 3],
    dir: [&'a mut [f32]; 3],
}

impl Columns<'_> {
    /// Write cluster `n` of a pass over a record (`TriangleCut::walk`): tree node `node`
    /// (with its leftmost leaf) lit by light-cut node `p` (`tables` those of `light`), with
    /// the union's visibility `q`, unless `p` holds no light. Returns the clusters written
    /// (0 or 1). `|C'|` as `MergedNode::leaves` (exact in f32 below 2^24 lights).
    #[inline(always)]
    fn lit(
        &mut self,
        (light, tables): (&LightCut, &LightTables),
        spread: bool,
        n: usize,
        (node, leftleaf): (u32, u32),
        p: usize,
        q: [u16; 3],
    ) -> usize {
        let power = light.value[p] * ((node - leftleaf) / 2 + 1) as f32;
        if power == Vec3::ZERO {
            return 0;
        }
        let mut info = tables.nodes[node as usize];
        if !spread {
            info.ring_cos = 1.0;
        }
        self.put(n, node, power, q, info);
        1
    }

    /// Write cluster `n`: tree node `node`, `power = |C'| <L O>`, quantised visibility
    /// means `q`, direction and rule `info`.
    #[inline(always)]
    fn put(&mut self, n: usize, node: u32, power: Vec3, q: [u16; 3], info: NodeInfo) {
        assert!(
            n < self.node.len(),
            "a merged cut longer than its four cuts"
        );
        self.node[n] = node;
        self.ring_cos[n] = info.ring_cos;
        for j in 0..3 {
            self.vis[j][n] = dequantise(q[j]);
            self.power[j][n] = power[j];
            self.dir[j][n] = info.dir[j];
        }
    }
}

/// `alpha^2` (at least `MIN_ALPHA^2`) and the fragment-constant factor of the GGX lobe
/// `G1(v) / (4 n.v) / (pi a^2)` (with `D = 1 / (pi a^2 s^2)`,
/// `s = (1 - (n.h)^2) / a^2 + (n.h)^2`, the rest per direction in `lanes::ggx`).
fn ggx_constants(n: Vec3, v: Vec3, alpha: f32) -> (f32, f32) {
    let a2 = {
        let a = alpha.max(microfacet::MIN_ALPHA);
        a * a
    };
    let ci = n.dot(v);
    let tan2 = a2 * (1.0 - ci * ci) / (ci * ci);
    let g1 = 2.0 / (1.0 + (1.0 + tan2.max(0.0)).sqrt());
    (a2, g1 / (4.0 * ci) / (PI * a2))
}
