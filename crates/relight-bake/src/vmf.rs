//! View-dependent glossy PRT with von Mises-Fisher lobes: Laurijssen & Dutré 2009, "Adaptive
//! Precomputation of Glossy Interreflections" ("the paper"; `/work/shared/papers/`), sections
//! 3 and 5. The lobes themselves, their sampling and their EM live in
//! [`relight_sphere::vmf`] (read its docs for the definition and the paper's typos).
//!
//! # Light transport model (paper section 3, eq. 1-5)
//! `L_o(x, s_o) = int T(x, s_i, s_o) L_s(s_i) ds_i` (eq. 2) with `T` the transfer from the
//! distant environment `L_s`. For a surface point `x` and a view `s_o`, the **transfer slice**
//! `T_{x, s_o}(s_i)` is approximated by a sum of vMF lobes `sum_j alpha_j gamma_j(s_i)` (eq. 4-5),
//! one per light-path class (section 5.1): direct, indirect diffuse, indirect glossy.
//!
//! # Conventions (stated once, here)
//! * **Lobes** follow the toolkit: `alpha` is a lobe's integral, so shading a slice under a
//!   constant environment `L` is `L sum_j alpha_j`, and under a vMF light its inner product.
//! * **Local frame** of a point: [`relight_sphere::warp::Frame::from_normal`] of its unit
//!   shading normal (normal = +Z), the frame of [`relight_scene::material::Material::eval`];
//!   views are given in it (the paper's section 4.3: views relative to the local frame), as
//!   unit vectors pointing **towards the viewer** (`wi` of `Material::eval`).
//! * **Transfer slices** hold their lobes in the **world** frame (the frame of the
//!   environment), over directions **towards the light**.
//! * **Weights** of path samples are RGB, already divided by the number of paths `M` traced
//!   for the slice (escaped or not), as [`relight_sphere::vmf::WeightedDir`] expects: a
//!   class's weight sum is its Monte Carlo transfer integral.
//! * The cosine-weighted BRDF at any point is split into the terms `f_d` and `f_g` of eq. 9
//!   ([`material_lobes`]); a slice keeps the transfer through `f_d` at `x` and through `f_g`
//!   at `x` apart (the paper's `T_d` and `T_g`, eq. 3).
//!
//! Modules: [`material_lobes`] (eq. 9, the sampling density), [`mod@slice`] (eq. 13-15, a transfer
//! slice from traced paths), [`interp`] (eq. 6, slices between views or vertices),
//! [`refine`] (section 4.2, adaptive angular refinement), [`mod@bake`] (the slices of every
//! vertex for its level of views), [`subdivide`] and [`spatial`] (section 4.3, adaptive
//! spatial refinement).

pub mod bake;
pub mod diffuse_sh;
pub mod interp;
pub mod material_lobes;
pub mod refine;
pub mod slice;
pub mod spatial;
pub mod subdivide;

pub use bake::{
    bake, bake_vertices, view_counts, views_of_level, InvalidVmfBake, VmfBake, VmfBakeSettings,
};
pub use interp::{blend_lobes, blend_slices, slice_distance, ViewTable};
pub use material_lobes::{MaterialLobes, Term};
pub use slice::{PathClass, SliceSettings, TransferSlice};
