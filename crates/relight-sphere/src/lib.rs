//! # relight-sphere: the spherical toolkit (pure math, no IO)
//!
//! ## Conventions (stated once, here; every crate of relight follows them)
//!
//! * **World frame**: right-handed, **+Y up**. Directions are unit [`Vec3`] (f32).
//!   Transforms are named `dst_from_src` (`world_from_object`, `env_from_world`).
//! * **Spherical angles**: `theta` is the polar angle measured from +Y (`cos theta = d.y`);
//!   `phi` is the azimuth of Mitsuba 3's environment map: `phi = atan2(d.x, -d.z)`, so that
//!   `d = (sin phi sin theta, cos theta, -cos phi sin theta)`.
//! * **Latlong environment maps follow Mitsuba 3's `envmap` emitter** (default `to_world`):
//!   `u = phi / 2pi (mod 1)`, `v = theta / pi`; `u = 0` is -Z, `u = 0.25` is +X, `u = 0.5` is +Z,
//!   `u = 0.75` is -X. Column `i` of a `W`-wide image is centred at `u = (i + 0.5) / W`
//!   (horizontal wrap), but **row `j` of an `H`-high image sits at `theta = pi j / (H - 1)`**:
//!   row 0 is exactly +Y, row `H - 1` exactly -Y. Lookups are bilinear. See [`envmap`].
//! * **Radiance** is linear RGB (Rec. 709 primaries), f32 in memory. Environment maps hold the
//!   radiance *arriving from* a direction.
//! * **Spherical harmonics** (`sh`): real, orthonormal over the unit sphere, evaluated with the
//!   Cartesian formulas of Ramamoorthi & Hanrahan (2001) / Sloan directly on the **world** (x, y, z):
//!   `Y_0^0 = 0.282095`, `Y_1^{-1} = 0.488603 y`, `Y_1^0 = 0.488603 z`, `Y_1^1 = 0.488603 x`, ...
//!   i.e. the Legendre polar axis of the recurrence is world +Z and **no Condon-Shortley phase**
//!   appears in the real basis (it cancels). This is the convention of R&H's published
//!   coefficient tables, so those compare directly. Flat index `l(l+1)+m`; "order n" means bands
//!   `0..n-1`, i.e. `n^2` coefficients.
//! * **Cube maps**: faces in the order +X, -X, +Y, -Y, +Z, -Z with the OpenGL face orientation
//!   (see [`cubemap`]).
//!
//! ## Modules
//! * [`envmap`]: environment maps (latlong, cube, probe), bilinear lookup, exact quadrature
//!   weights; [`env_sampler`]: [`EnvSampler`] importance sampling;
//!   grids: [`latlong`], [`cubemap`], [`probe`], [`icosphere`];
//! * [`sh`]: real SH evaluation, projection, zonal convolution, windows, with its children
//!   [`sh::rotate`] (rotation of any order) and [`sh::project`] (exact latlong projection);
//!   [`sh_product`]: triple-product tensor; [`basis`]: the [`basis::SphericalBasis`] trait;
//! * [`decompose`]: environment = SH part + cap lights (hybrid thesis 4.3);
//! * [`sg`], [`sg_fit`]: spherical Gaussians and their Levenberg-Marquardt fitter;
//!   [`half_vector`]: lobes in the half-vector domain and their tabulated integration; [`vmf`]:
//!   von Mises-Fisher lobes (stable normaliser, L2 distance, sampling, EM estimation);
//! * [`warp`]: sample warps, low-discrepancy points, the [`Rng`]; [`quadrature`]: Gauss-Legendre.
//!
//! ## Example
//! ```
//! use relight_sphere::{sh, sh::rotate::ShRotation, EnvMap, Mat3, Vec3};
//! // A sky brighter towards +Y, as a 64 x 33 latlong map.
//! let map = EnvMap::latlong_from_fn(64, 33, |d| Vec3::splat(1.0 + d.y.max(0.0)));
//! // Order-3 SH projection (9 RGB coefficients) and the irradiance seen by an upward normal.
//! let radiance = sh::project_env(&map, 3);
//! let irradiance = sh::irradiance_from_radiance(&radiance);
//! let e_up = sh::eval_rgb(&irradiance, Vec3::Y);
//! // Exact: int (1 + max(0, y)) max(0, y) dw = pi + 2 pi / 3.
//! let exact = std::f32::consts::PI * (1.0 + 2.0 / 3.0);
//! assert!((e_up.x - exact).abs() < 0.02 * exact);
//! // Rotating the lighting by R turns it into the coefficients of L(R^T d).
//! let rot = ShRotation::new(3, Mat3::from_rotation_x(std::f32::consts::PI));
//! let flipped = rot.apply(&radiance);
//! assert!((sh::eval_rgb(&flipped, -Vec3::Y) - sh::eval_rgb(&radiance, Vec3::Y)).length() < 1e-4);
//! ```

pub use glam::{Mat3, Quat, Vec2, Vec3};

pub mod basis;
pub mod cubemap;
pub mod decompose;
pub mod env_prefilter;
pub mod env_sampler;
pub mod envmap;
pub mod haar;
pub mod half_vector;
pub mod icosphere;
pub mod latlong;
pub mod probe;
pub mod quadrature;
pub mod sg;
pub mod sg_fit;
pub mod sg_kernel;
pub mod sh;
pub mod sh_product;
pub mod vmf;
pub mod warp;

#[cfg(test)]
mod chi2;

pub use basis::{ShBasis, SphericalBasis};
pub use env_sampler::EnvSampler;
pub use envmap::{luminance, EnvLayout, EnvMap, TexelInfo};
pub use sh::rotate::ShRotation;
pub use warp::Rng;

/// SH rotation under its former top-level path (`relight_sphere::sh_rotate::ShRotation`, used
/// by `relight-cli`); the module is [`sh::rotate`], a child of [`sh`] since it builds on its
/// index conventions while [`sh::project_env`] builds on it.
pub use sh::rotate as sh_rotate;
