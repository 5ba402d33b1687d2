//! # relight-scene: everything a scene is made of
//!
//! Mesh and environment IO (`io`), triangle meshes ([`mesh`]), materials and their BRDFs
//! ([`material`], with texture and normal maps: [`material::maps`], [`texture`]), cameras ([`camera`]), the procedural sun-and-sky (`sky`) and ray casting
//! ([`accel`]). Conventions are those of `relight_sphere` (Mitsuba 3's, +Y up).

pub mod accel;
pub mod camera;
pub mod material;
pub mod mesh;
pub mod scene;
pub mod scene_file;
pub mod shapes;
pub mod texture;

pub use relight_sphere::{Mat3, Vec2, Vec3};
pub mod error;
pub mod io;
pub mod meshops;
pub mod sky;
