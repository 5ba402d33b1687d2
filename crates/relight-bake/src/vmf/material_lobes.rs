//! Per-material vMF lobes (paper section 5.1, eq. 9): for one material and one view, the
//! cosine-weighted BRDF slice approximated by one diffuse and one glossy vMF lobe,
//!
//! ```text
//! f_r(v, w) cos(w) = f_d(v, w) + f_g(v, w)  ~  beta_d gamma_d(w) + beta_g gamma_g(w)
//! ```
//!
//! used as the density that importance-samples the first direction of every path of a
//! transfer slice ([`super::slice`]).
//!
//! # The split and the fit
//! * `f_g` is [`Material::glossy_eval`] (the Blinn-Phong specular term, the GGX lobes) and
//!   `f_d = eval - glossy_eval` the rest (Lambert, Blinn-Phong's diffuse term, the plastic's
//!   diffuse base), both cosine included, as [`Material::eval`].
//! * Each term is fitted by moments: `beta = int f dw` (its albedo for this view), `mu` the
//!   direction of `int f(w) w dw`, `kappa = A^{-1}(|int f w dw| / beta)`: the maximum-likelihood
//!   vMF of the density `f / beta`, which is the closed-form one-lobe EM of the toolkit
//!   ([`relight_sphere::vmf::estimate_one_lobe`] with [`KappaEstimate::MaximumLikelihood`]) run
//!   on importance-sampled directions: `f_g` by [`Material::sample_glossy`], `f_d` by the
//!   cosine hemisphere, each from `n` Hammersley points, weight `f / (pdf n)` (the toolkit's
//!   weight convention). The fit is a deterministic function of `(material, view, n)`.
//! * A term that is zero (a Lambert's glossy term, a conductor's diffuse one) gets a lobe of
//!   zero amplitude about the normal with the cosine lobe's concentration
//!   ([`cosine_kappa`]), so sampling stays defined.
//!
//! # Sampling
//! The sampling density is the mixture `p(w) = P_d gamma_d(w) + (1 - P_d) gamma_g(w)` of the
//! two unit lobes, with `P_d` the diffuse share of the channel sums of `beta`, floored at
//! [`DEFENSIVE_DIFFUSE`]: the wide diffuse lobe then bounds `f / p` where the glossy vMF's
//! exponential tail falls below the BRDF's (GGX tails are polynomial). The matching pair is
//! [`MaterialLobes::sample`] / [`MaterialLobes::pdf`]; `p > 0` on the whole sphere, so
//! `f / p` is an unbiased estimator of any integral of `f`.
//!
//! # Frame
//! The local shading frame of the material ([`Material::eval`]): normal +Z, `view` (`wi`
//! there) towards the viewer, lobes over directions towards the light (`wo`).

use glam::{Vec2, Vec3};
use relight_scene::material::{cosine_hemisphere_pdf, sample_cosine_hemisphere, Material};
use relight_sphere::vmf::{
    estimate_one_lobe, kappa_from_mean_cosine, sample_vmf, vmf_pdf, KappaEstimate, VmfLobe,
    WeightedDir, KAPPA_MAX,
};
use relight_sphere::warp::hammersley;

/// Smallest probability of sampling the diffuse lobe (module docs: a defensive mixture).
pub const DEFENSIVE_DIFFUSE: f32 = 0.1;

/// Concentration of the vMF fitted to the clamped cosine lobe `cos(w) / pi`: its mean cosine
/// is 2/3, so `kappa = A^{-1}(2/3)`, about 2.9 (the paper's "min(kappa) ~ 3").
pub fn cosine_kappa() -> f32 {
    kappa_from_mean_cosine(2.0 / 3.0) as f32
}

/// Which term of eq. 9 a direction was sampled from (or, for a path, which BRDF term it
/// scattered by).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Term {
    /// The diffuse term `f_d`.
    Diffuse,
    /// The glossy term `f_g`.
    Glossy,
}

impl Term {
    /// Both terms, in the order of the arrays indexed by [`Term::index`].
    pub const ALL: [Term; 2] = [Term::Diffuse, Term::Glossy];

    /// 0 for diffuse, 1 for glossy.
    pub fn index(self) -> usize {
        match self {
            Term::Diffuse => 0,
            Term::Glossy => 1,
        }
    }
}

/// The two lobes of eq. 9 for one material and view (module docs), in the local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialLobes {
    /// `beta_d gamma_d`: the diffuse term's lobe (amplitude = the term's albedo).
    pub diffuse: VmfLobe,
    /// `beta_g gamma_g`: the glossy term's lobe (amplitude = the term's albedo).
    pub glossy: VmfLobe,
}

/// A direction drawn by [`MaterialLobes::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LobeSample {
    /// Unit direction (local frame; may be below the horizon, where the BRDF is zero).
    pub dir: Vec3,
    /// The lobe it was drawn from.
    pub term: Term,
    /// The mixture density [`MaterialLobes::pdf`] of `dir` (solid angle).
    pub pdf: f32,
}

/// The two terms of a material's cosine-weighted BRDF, `[f_d, f_g]` (module docs), RGB.
/// Zero below either horizon.
pub fn split_eval(material: &Material, view: Vec3, dir: Vec3) -> [Vec3; 2] {
    let f = material.eval(view, dir);
    let g = material.glossy_eval(view, dir);
    [(f - g).max(Vec3::ZERO), g]
}

impl MaterialLobes {
    /// Fit the two lobes of `material` for the unit `view` (local frame) from `n` samples
    /// per term (module docs). A view at or below the horizon gives zero-amplitude lobes.
    ///
    /// # Panics
    /// Debug builds assert `n > 0` and a unit view.
    pub fn fit(material: &Material, view: Vec3, n: u32) -> MaterialLobes {
        debug_assert!(n > 0, "at least one sample per term");
        debug_assert!((view.length() - 1.0).abs() < 1e-3, "unit view");
        let empty = VmfLobe::new(Vec3::Z, cosine_kappa(), Vec3::ZERO);
        let inv_n = 1.0 / n as f32;
        let mut diffuse = Vec::with_capacity(n as usize);
        let mut glossy = Vec::with_capacity(n as usize);
        if view.z > 0.0 {
            for i in 0..n {
                let u = hammersley(i, n);
                let w = sample_cosine_hemisphere(u);
                let pdf = cosine_hemisphere_pdf(w);
                if pdf > 0.0 {
                    let [fd, _] = split_eval(material, view, w);
                    diffuse.push(WeightedDir {
                        dir: w,
                        weight: fd * (inv_n / pdf),
                    });
                }
                if let Some(s) = material.sample_glossy(view, u) {
                    glossy.push(WeightedDir {
                        dir: s.wo,
                        weight: s.weight * inv_n,
                    });
                }
            }
        }
        let fit = |samples: &[WeightedDir], axis_if_empty: Vec3| {
            estimate_one_lobe(samples, KappaEstimate::MaximumLikelihood, KAPPA_MAX).unwrap_or(
                VmfLobe {
                    axis: axis_if_empty,
                    ..empty
                },
            )
        };
        MaterialLobes {
            diffuse: fit(&diffuse, Vec3::Z),
            glossy: fit(&glossy, Vec3::Z),
        }
    }

    /// `beta_d + beta_g`: the mixture's integral (the approximated slice albedo), RGB.
    pub fn integral(&self) -> Vec3 {
        self.diffuse.amplitude + self.glossy.amplitude
    }

    /// The mixture `beta_d gamma_d(w) + beta_g gamma_g(w)` at unit `w`, RGB.
    pub fn eval(&self, w: Vec3) -> Vec3 {
        self.diffuse.eval(w) + self.glossy.eval(w)
    }

    /// Probability `P_d` of sampling the diffuse lobe (module docs): the diffuse share of the
    /// amplitudes' channel sums, at least [`DEFENSIVE_DIFFUSE`]; 1 when both are zero.
    pub fn diffuse_probability(&self) -> f32 {
        let sum = |v: Vec3| (v.x + v.y + v.z).max(0.0);
        let (d, g) = (sum(self.diffuse.amplitude), sum(self.glossy.amplitude));
        if d + g > 0.0 {
            (d / (d + g)).max(DEFENSIVE_DIFFUSE)
        } else {
            1.0
        }
    }

    /// Draw a direction from the mixture density ([`MaterialLobes::pdf`]) with `u` in
    /// `[0, 1)^2`: `u.x` below `P_d` picks the diffuse lobe and is rescaled to `[0, 1)`, so a
    /// stratified `u` stays stratified within each lobe.
    pub fn sample(&self, u: Vec2) -> LobeSample {
        let pd = self.diffuse_probability();
        let (term, ux) = if u.x < pd {
            (Term::Diffuse, u.x / pd)
        } else {
            (Term::Glossy, (u.x - pd) / (1.0 - pd))
        };
        let lobe = match term {
            Term::Diffuse => &self.diffuse,
            Term::Glossy => &self.glossy,
        };
        let dir = sample_vmf(
            lobe.axis,
            lobe.kappa,
            Vec2::new(ux.min(1.0 - f32::EPSILON), u.y),
        );
        LobeSample {
            dir,
            term,
            pdf: self.pdf(dir),
        }
    }

    /// Density of [`MaterialLobes::sample`] at unit `w` (solid angle): `P_d gamma_d(w) +
    /// (1 - P_d) gamma_g(w)`, positive everywhere.
    pub fn pdf(&self, w: Vec3) -> f32 {
        let pd = self.diffuse_probability();
        let mut p = pd * vmf_pdf(self.diffuse.axis, self.diffuse.kappa, w);
        if pd < 1.0 {
            p += (1.0 - pd) * vmf_pdf(self.glossy.axis, self.glossy.kappa, w);
        }
        p
    }
}

#[cfg(test)]
mod tests;
