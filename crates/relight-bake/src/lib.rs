//! # relight-bake: precomputed light transport, one module per method
//!
//! * [`sh`]: diffuse spherical-harmonic PRT (Sloan, Kautz & Snyder 2002; thesis ch. 4.2):
//!   per-vertex transfer vectors, unshadowed, shadowed or interreflected.
//! * [`transport`]: what every baker shares: per-vertex albedo and geometric normals,
//!   per-vertex low-discrepancy hemisphere samples, ray offsets, thread pools.
//!
//! Conventions are those of `relight_sphere` (Mitsuba 3's, +Y up, SH on world x, y, z); each
//! method's module doc states exactly what its transfer includes (albedo, cosine, 1/pi).
//!
//! ```no_run
//! use relight_bake::sh::{bake, ShBakeSettings, ShTransferKind};
//! # fn demo(scene: &relight_scene::scene::Scene) -> Result<(), relight_bake::BakeError> {
//! let caster = relight_scene::accel::build_default(&scene.mesh);
//! let settings = ShBakeSettings { kind: ShTransferKind::Shadowed, ..Default::default() };
//! let transfer = bake(&scene.mesh, &scene.materials, caster.as_ref(), &settings)?;
//! transfer.validate().expect("a fresh bake is valid");
//! # Ok(()) }
//! ```

pub mod sg;
pub mod sh;
pub mod transport;

/// Why a bake could not run: invalid settings or an inconsistent mesh.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A setting is out of range (the message names it).
    #[error("invalid bake settings: {0}")]
    Settings(String),
    /// The mesh or its materials are inconsistent (the message says how).
    #[error("invalid scene for baking: {0}")]
    Scene(String),
    /// The worker thread pool could not be created.
    #[error("could not start {threads} bake threads: {message}")]
    Threads {
        /// Requested thread count.
        threads: usize,
        /// The error of the thread-pool builder.
        message: String,
    },
}
