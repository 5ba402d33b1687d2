//! One triangle's merged cut (Cheslack-Postava et al. 2008, sec. 3.2 merge, sec. 4.2 Eq. 5):
//! the per-triangle frame [`super::CutsShader::render_merged`], the merge of the three vertex
//! cuts with the light cut done once per triangle and band of rows and summed per fragment.

use super::cache::{Cluster, MergedCache};
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
    /// `sum_k power_k vis_k[j]` per corner (the Lambert sum without a per-cluster BRDF).
    pub(super) sums: [Vec3; 3],
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
    /// together), for the cluster spread if `spread`; each kept cluster also pushed onto
    /// `record` if given (`shade_cuts::cache`; the light cut then has at most 65,536 nodes).
    pub(super) fn build(
        &mut self,
        shader: &CutsShader<'_>,
        light: &LightCut,
        tri: u32,
        spread: bool,
        mut record: Option<&mut Vec<Cluster>>,
    ) {
        self.sums = [Vec3::ZERO; 3];
        self.spread = spread;
        let [a, b, c] = shader.mesh.indices[tri as usize];
        let cuts = [
            shader.bake.cuts.cut(a as usize),
            shader.bake.cuts.cut(b as usize),
            shader.bake.cuts.cut(c as usize),
        ];
        self.reserve(light.len() + cuts.iter().map(|c| c.index.len()).sum::<usize>());
        let keys = [
            CutKeys::from(light),
            cuts[0].into(),
            cuts[1].into(),
            cuts[2].into(),
        ];
        let mut n = 0;
        let mut sums = [Vec3::ZERO; 3];
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
            if let Some(r) = record.as_deref_mut() {
                debug_assert!(pos[0] <= u16::MAX as usize);
                r.push(Cluster {
                    node: node.index,
                    light: pos[0] as u16,
                    vis: q,
                });
            }
            let dir = light.direction(node.index);
            self.node[n] = node.index;
            self.ring_cos[n] = if spread {
                light.rule_cos(node.index)
            } else {
                1.0
            };
            for j in 0..3 {
                let v = dequantise(q[j]);
                sums[j] += power * v;
                self.vis[j][n] = v;
                self.power[j][n] = power[j];
                self.dir[j][n] = dir[j];
            }
            n += 1;
        });
        self.finish(n, sums);
    }

    /// Triangle `tri`'s merged cut into `self` from its record `cut` (`shade_cuts::cache`,
    /// whose tables `cache` holds) instead of the traversal: the same arithmetic in the same
    /// order as [`TriangleCut::build`], so the same bits.
    pub(super) fn expand(
        &mut self,
        light: &LightCut,
        cache: &MergedCache,
        cut: &[Cluster],
        spread: bool,
    ) {
        self.spread = spread;
        self.reserve(cut.len());
        let mut sums = [Vec3::ZERO; 3];
        for (n, c) in cut.iter().enumerate() {
            let node = c.node as usize;
            let info = cache.nodes[node];
            let power = light.value[c.light as usize] * cache.leaves[node];
            self.node[n] = c.node;
            self.ring_cos[n] = if spread { info.ring_cos } else { 1.0 };
            for j in 0..3 {
                let v = dequantise(c.vis[j]);
                sums[j] += power * v;
                self.vis[j][n] = v;
                self.power[j][n] = power[j];
                self.dir[j][n] = info.dir[j];
            }
        }
        self.finish(cut.len(), sums);
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

    /// `n` clusters written, their `sums`: pad the last lane group with zero clusters.
    fn finish(&mut self, n: usize, sums: [Vec3; 3]) {
        self.sums = sums;
        self.len = n.next_multiple_of(LANES);
        for a in [&mut self.power, &mut self.vis, &mut self.dir] {
            a.iter_mut().for_each(|x| x[n..self.len].fill(0.0));
        }
        self.ring_cos[n..self.len].fill(1.0);
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
