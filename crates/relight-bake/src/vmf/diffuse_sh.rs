//! The diffuse term's transfer as SH (the paper, section 5.2: "any PRT technique could be
//! used to render diffuse materials [SKS02, NRH03]"; docs/RESULTS.md, section vmf).
//!
//! One vMF lobe per class fits the diffuse term badly: the direct class of an open
//! Lambert point is a clamped cosine, and its vMF (kappa about 2.9) is 32 % below it at 60
//! degrees from the normal and 45 % above it at the normal. Measured on the same path samples
//! (`slice/diffuse_tests.rs`, a Lambert plane beside a box under a sharp sun), an SH transfer
//! of order 5 errs 4.4 % (open point) and 10.3 % (five points, shadows included) against one
//! lobe's 23 % and 31 %, and more EM lobes per class are not monotonic (two lobes: 33 % at
//! the open point). So with `diffuse_sh_order = n > 0` the bake keeps, per vertex, the
//! transfer through the diffuse term `f_d` at the vertex (all three classes, the paper's
//! `T_d` of eq. 3) as `n^2` RGB SH coefficients, and the frame renders that term as
//! `sum_k t_k L_k` (Sloan et al. 2002) instead of its three lobes; the glossy term keeps its
//! lobes.
//!
//! # The projection
//! The diffuse term of every material the bake takes is separable in the view:
//! `f_d(v, s) = c(v) g(s)`, with `c = 1` for Lambert and Blinn-Phong (`diffuse / pi cos`) and
//! `c(v) = T(cos v)`, the coating's Fresnel transmission towards the viewer, for the GGX
//! plastic ([`view_factor`]; `relight_scene::material`'s plastic, as Mitsuba's
//! `roughplastic`). So the diffuse transfer is `c(v)` times a view-independent SH vector
//! `t`, and each slice's projection `S_s = sum_i w_i Y_k(s_i)` over its diffuse-term samples
//! (directions `s_i` world, weights `w_i` already divided by the paths, [`super::slice`]) is
//! an unbiased estimate of `c(v_s) t_k`. The bake keeps the least-squares `t` over the slices
//! the vertex computed (every view and level the refinement tried),
//! `t_k = sum_s c_s S_s / sum_s c_s^2`, which is their mean when `c = 1` and weighs the
//! grazing views of a plastic (small `c`, whose division would amplify noise) least. The
//! frame renders `c(v) sum_k t_k L_k`. The GGX conductor has no diffuse term (an all-zero
//! row); a row that is all zero means "use the lobes" ([`VmfBake::diffuse_sh_row`]), which
//! is also how bundles baked before the plastic's SH render its diffuse lobes.
//!
//! SH conventions are `relight_sphere::sh`'s (real, orthonormal, `Y_k` with `k = l(l+1)+m`).

use super::slice::SliceSamples;
use super::Term;
use glam::Vec3;
use relight_scene::material::Material;
use relight_sphere::sh::{eval_sh, sh_count};

/// Largest SH order of the diffuse transfer.
pub const MAX_DIFFUSE_SH_ORDER: u32 = 10;

/// Whether `m`'s diffuse term `f_d` (eq. 9's split) is separable, `c(v) g(s)` (module
/// docs): Lambert, Blinn-Phong and the GGX plastic. The GGX conductor has none; Ward is not a
/// vMF material. The glTF BRDF's diffuse lobe `(1 - F(V.H)) base / pi` depends on the view
/// and the light together through `V.H`, so it is not separable: its whole BRDF is the glossy
/// term (`Material::glossy_eval`), fitted by the lobes like the conductor's, with no SH row.
pub fn separable_diffuse(m: &Material) -> bool {
    matches!(
        m,
        Material::Lambert { .. } | Material::BlinnPhong { .. } | Material::GgxPlastic { .. }
    )
}

/// The view's factor `c(v)` of `m`'s diffuse term for a view at `cos_view` to the normal:
/// the plastic's Fresnel transmission `T(cos_view)` (`Material::eval`'s `t.transmittance(ci)`),
/// 1 for every other material.
pub fn view_factor(m: &Material, cos_view: f32) -> f32 {
    match *m {
        Material::GgxPlastic { alpha, ior, .. } => {
            relight_scene::material::microfacet::PlasticTables::get(alpha, ior)
                .transmittance(cos_view.clamp(0.0, 1.0))
        }
        _ => 1.0,
    }
}

/// Add `scale` times the SH projection (order `order`) of the diffuse-term samples of `s` to
/// `acc` (`order^2` coefficients): `scale = c(v)` of the slice's view for the least-squares
/// sum of the module docs.
///
/// # Panics
/// Debug builds assert `acc` has `order^2` entries.
pub fn accumulate(s: &SliceSamples, order: usize, scale: f32, acc: &mut [Vec3]) {
    debug_assert_eq!(acc.len(), sh_count(order));
    let mut y = vec![0.0f32; sh_count(order)];
    for w in s.classes[Term::Diffuse.index()].iter().flatten() {
        eval_sh(order, w.dir, &mut y);
        for (a, &yk) in acc.iter_mut().zip(&y) {
            *a += w.weight * (scale * yk);
        }
    }
}

/// `sum_k t_k L_k` per channel: the diffuse term's outgoing radiance for the lighting's SH
/// `light` (world frame, at least as many coefficients as `t`).
///
/// # Panics
/// Debug builds assert `light` has at least `t.len()` coefficients.
pub fn radiance(t: &[Vec3], light: &[Vec3]) -> Vec3 {
    debug_assert!(light.len() >= t.len(), "{} < {}", light.len(), t.len());
    t.iter().zip(light).map(|(a, b)| *a * *b).sum()
}

use super::VmfBake;

impl VmfBake {
    /// Coefficients per vertex of the diffuse SH transfer (0 when off).
    pub fn diffuse_sh_len(&self) -> usize {
        sh_count(self.settings.diffuse_sh_order as usize)
    }

    /// The diffuse SH transfer of vertex `x`, or `None` when the bake has none or the vertex
    /// keeps its diffuse lobes (an all-zero row, module docs).
    pub fn diffuse_sh_row(&self, x: usize) -> Option<&[Vec3]> {
        let n = self.diffuse_sh_len();
        if self.settings.diffuse_sh_order == 0 {
            return None;
        }
        let row = &self.diffuse_sh[x * n..(x + 1) * n];
        row.iter().any(|c| *c != Vec3::ZERO).then_some(row)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_sphere::sh::clamped_cosine_zonal;
    use relight_sphere::vmf::WeightedDir;

    /// The projection of cosine-distributed samples of a Lambert point converges to the
    /// clamped cosine's SH (`albedo / pi` times its zonal coefficients about the normal).
    #[test]
    fn projection_of_a_clamped_cosine() {
        let n = 1 << 16;
        let mut s = SliceSamples {
            paths: n,
            normal: Vec3::Z,
            ..Default::default()
        };
        for i in 0..n {
            let u = relight_sphere::warp::hammersley(i, n);
            let d = relight_scene::material::sample_cosine_hemisphere(u);
            // f_d / pdf = albedo for a cosine-sampled Lambert, divided by the paths.
            s.classes[0][0].push(WeightedDir {
                dir: d,
                weight: Vec3::splat(0.5 / n as f32),
            });
        }
        let mut acc = vec![Vec3::ZERO; 25];
        accumulate(&s, 5, 1.0, &mut acc);
        for (k, c) in acc.iter().enumerate() {
            let m_zero = [0, 2, 6, 12, 20].contains(&k);
            assert!(m_zero || c.x.abs() < 2e-3, "coefficient {k}: {c}");
        }
        for l in 0..5i32 {
            // Funk-Hecke: cos+ about +Z has `A_l Y_l0(+Z)` on `Y_l0`, nothing on m != 0.
            let k = (l * (l + 1)) as usize;
            let y_l0 = ((2 * l + 1) as f32 / (4.0 * std::f32::consts::PI)).sqrt();
            let want = 0.5 / std::f32::consts::PI * clamped_cosine_zonal(l as usize) * y_l0;
            assert!(
                (acc[k].x - want).abs() < 2e-3,
                "l {l}: {} vs {want}",
                acc[k].x
            );
        }
    }
}
