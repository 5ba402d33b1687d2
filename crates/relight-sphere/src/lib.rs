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

pub use glam::{Mat3, Quat, Vec2, Vec3};
pub mod envmap;
