//! The direct glossy kernel: [`Material::glossy_eval`] of one view against every visible
//! texel of a vertex, rearranged for GGX so that the compiler vectorises it (the hot loop of
//! the tabulation: 92 views x ~3000 texels per vertex).
//!
//! For GGX (Walter et al. 2007) with `h = wi + wo` unnormalised, `|h|^2 = l`:
//! * `D(h / |h|) = l^2 / (pi a^2 q^2)` with `q = (h_x^2 + h_y^2) / a^2 + h_z^2` (no square root);
//! * Smith's `G1(v, m)` does not depend on `m` when both directions are above the horizon
//!   (then `wi.h > 0` and `wo.h > 0` always), so `G1(wi)` is one number per view and `G1(wo)`
//!   one per texel, computed once per vertex;
//! * the plastic's Fresnel term needs `wi.h / |h|`, one square root.
//!
//! Other materials (Blinn-Phong, Ward, glTF) call `glossy_eval` per texel. The kernel agrees with
//! `glossy_eval` to float rounding (tested).

use glam::Vec3;
use relight_scene::material::microfacet::{smith_g1, MIN_ALPHA};
use relight_scene::material::Material;
use std::f32::consts::PI;

/// What is evaluated per (view, texel).
#[derive(Clone, Copy, Debug)]
enum Kind {
    /// `glossy_eval` per texel.
    Generic(Material),
    /// GGX reflection times `specular`, with the plastic's Fresnel term if `ior` is set.
    Ggx {
        alpha: f32,
        specular: Vec3,
        ior: Option<f32>,
    },
}

/// The visible texels of one vertex (shading frame, structure of arrays) and the per-texel
/// factors of its material.
#[derive(Clone, Debug)]
pub(super) struct GlossyKernel {
    kind: Kind,
    idx: Vec<u32>,
    /// The other texels of the cube map (written as zeros).
    hidden: Vec<u32>,
    wo: Vec<Vec3>,
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    /// `G1(wo)` per texel (GGX only).
    g1o: Vec<f32>,
    /// Scalar result per texel, before the RGB reflectance.
    val: Vec<f32>,
}

impl GlossyKernel {
    /// The kernel of material `m` over `visible` texels `(index, direction in the shading
    /// frame)`, in increasing index order, of a cube map of `texels` texels.
    pub(super) fn new(m: &Material, visible: &[(u32, Vec3)], texels: usize) -> Self {
        debug_assert!(visible.windows(2).all(|p| p[0].0 < p[1].0));
        let mut hidden = Vec::with_capacity(texels - visible.len());
        let mut next = visible.iter().map(|&(i, _)| i).peekable();
        for t in 0..texels as u32 {
            if next.peek() == Some(&t) {
                next.next();
            } else {
                hidden.push(t);
            }
        }
        let kind = match *m {
            Material::GgxConductor { specular, alpha } => Kind::Ggx {
                alpha: alpha.max(MIN_ALPHA),
                specular,
                ior: None,
            },
            Material::GgxPlastic {
                specular,
                alpha,
                ior,
                ..
            } => Kind::Ggx {
                alpha: alpha.max(MIN_ALPHA),
                specular,
                ior: Some(ior),
            },
            // glTF: its glossy part is the whole BRDF (Material::diffuse_factors), evaluated
            // per texel.
            Material::Lambert { .. }
            | Material::BlinnPhong { .. }
            | Material::Ward { .. }
            | Material::Gltf { .. } => Kind::Generic(*m),
        };
        let g1o = match kind {
            Kind::Ggx { alpha, .. } => visible
                .iter()
                .map(|&(_, w)| smith_g1(w, Vec3::Z, alpha))
                .collect(),
            Kind::Generic(_) => Vec::new(),
        };
        GlossyKernel {
            kind,
            idx: visible.iter().map(|&(i, _)| i).collect(),
            hidden,
            wo: visible.iter().map(|&(_, w)| w).collect(),
            x: visible.iter().map(|&(_, w)| w.x).collect(),
            y: visible.iter().map(|&(_, w)| w.y).collect(),
            z: visible.iter().map(|&(_, w)| w.z).collect(),
            g1o,
            val: vec![0.0; visible.len()],
        }
    }

    /// Write one cube map of direct glossy transport into `out`: `glossy_eval(wi, wo)` at
    /// every visible texel, zero elsewhere (each texel written once: `out` need not be
    /// cleared). `wi` is unit, in the shading frame, above the horizon.
    pub(super) fn eval_view(&mut self, wi: Vec3, out: &mut [Vec3]) {
        debug_assert!(wi.z > 0.0);
        for &i in &self.hidden {
            out[i as usize] = Vec3::ZERO;
        }
        let (alpha, specular, ior) = match self.kind {
            Kind::Generic(m) => {
                for (&i, &wo) in self.idx.iter().zip(&self.wo) {
                    out[i as usize] = m.glossy_eval(wi, wo);
                }
                return;
            }
            Kind::Ggx {
                alpha,
                specular,
                ior,
            } => (alpha, specular, ior),
        };
        let inv_a2 = 1.0 / (alpha * alpha);
        // D G1(wi) G1(wo) / (4 cos_i) = c (l / q)^2 G1(wo).
        let c = smith_g1(wi, Vec3::Z, alpha) * inv_a2 / (PI * 4.0 * wi.z);
        // ggx_d's underflow guard, D m_z > 1e-20, as c' (l / q)^2 h_z / |h| > 1e-20.
        let c_d = inv_a2 / PI;
        let n = self.val.len();
        let (xs, ys, zs, g1o) = (&self.x[..n], &self.y[..n], &self.z[..n], &self.g1o[..n]);
        let val = &mut self.val[..n];
        match ior {
            None => {
                for k in 0..n {
                    let (hx, hy, hz) = (wi.x + xs[k], wi.y + ys[k], wi.z + zs[k]);
                    let l = hx * hx + hy * hy + hz * hz;
                    let q = (hx * hx + hy * hy) * inv_a2 + hz * hz;
                    let r = l / q;
                    let d = c_d * r * r;
                    let keep = d * hz > 1e-20 * l.sqrt();
                    // Unconditional load and select: a load inside the `if` stops LLVM from
                    // vectorising the loop.
                    let v = c * r * r * g1o[k];
                    val[k] = if keep { v } else { 0.0 };
                }
            }
            Some(eta) => {
                let inv_eta2 = 1.0 / (eta * eta);
                for k in 0..n {
                    let (hx, hy, hz) = (wi.x + xs[k], wi.y + ys[k], wi.z + zs[k]);
                    let l = hx * hx + hy * hy + hz * hz;
                    let q = (hx * hx + hy * hy) * inv_a2 + hz * hz;
                    let r = l / q;
                    let d = c_d * r * r;
                    let len = l.sqrt();
                    let keep = d * hz > 1e-20 * len;
                    // microfacet::fresnel_dielectric for cos_i = wi.h > 0 and eta > 1.
                    let ci = (wi.x * hx + wi.y * hy + wi.z * hz) / len;
                    let ct = (1.0 - (1.0 - ci * ci).max(0.0) * inv_eta2).sqrt();
                    // 0.5 (rs^2 + rp^2) over one common denominator (one division, not two).
                    let (rs_n, rs_d) = (ci - eta * ct, ci + eta * ct);
                    let (rp_n, rp_d) = (eta * ci - ct, eta * ci + ct);
                    let (a, b) = (rs_n * rp_d, rp_n * rs_d);
                    let den = rs_d * rp_d;
                    let f = 0.5 * (a * a + b * b) / (den * den);
                    let v = c * r * r * g1o[k] * f;
                    val[k] = if keep { v } else { 0.0 };
                }
            }
        }
        for (&i, &v) in self.idx.iter().zip(&self.val) {
            out[i as usize] = specular * v;
        }
    }
}
