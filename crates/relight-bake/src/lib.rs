//! # relight-bake: precomputed light transport, one module per method
//!
//! * [`sh`]: diffuse spherical-harmonic PRT (Sloan, Kautz & Snyder 2002; thesis ch. 4.2):
//!   per-vertex transfer vectors, unshadowed, shadowed or interreflected; bakes of a vertex
//!   range for sharded bakes.
//! * [`sg`]: view-dependent glossy PRT with spherical Gaussians (Green 2005): per-vertex,
//!   per-view transport fitted by a flood fill with coherence terms.
//! * [`cuts`]: precomputed visibility cuts (Cheslack-Postava et al. 2008): light samples, light
//!   tree, per-vertex visibility cuts, merging of cuts, illumination cuts.
//! * [`vmf`]: view-dependent glossy PRT with von Mises-Fisher lobes (Laurijssen & Dutré
//!   2009): per-vertex, per-view transfer slices, one lobe per light-path class (bake layer
//!   only; no adaptive refinement yet).
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
//! let settings = ShBakeSettings { transfer: ShTransferKind::Shadowed, ..Default::default() };
//! let transfer = bake(&scene.mesh, &scene.materials, caster.as_ref(), &settings)?;
//! transfer.validate().expect("a fresh bake is valid");
//! # Ok(()) }
//! ```

pub mod cuts;
pub mod sg;
pub mod sh;
pub mod transport;
pub mod vmf;

/// Why a bake could not run: invalid settings or an inconsistent mesh.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A setting is out of range (the message names it).
    #[error("invalid bake settings: {0}")]
    Settings(String),
    /// The mesh or its materials are inconsistent (the message says how).
    #[error("invalid scene for baking: {0}")]
    Scene(String),
    /// The bake would need more memory than the machine has (estimated before any work).
    #[error("the bake needs about {needed_mib} MiB, more than the {available_mib} MiB this machine has: use fewer vertices, a lower SH order or fewer lobes")]
    Memory {
        /// Estimated need, MiB.
        needed_mib: u64,
        /// Physical memory, MiB.
        available_mib: u64,
    },
    /// The cuts method refused its input (environment, lights, sizes).
    #[error(transparent)]
    Cuts(#[from] cuts::CutsError),
    /// The worker thread pool could not be created.
    #[error("could not start {threads} bake threads: {message}")]
    Threads {
        /// Requested thread count.
        threads: usize,
        /// The error of the thread-pool builder.
        message: String,
    },
}

/// Physical memory of this machine in bytes (`MemTotal` of `/proc/meminfo`), if known.
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuse a bake whose estimated memory `bytes` exceeds the machine's physical memory (an
/// allocation that large would abort the process, or swap it to a halt).
///
/// # Errors
/// [`BakeError::Memory`].
pub fn check_memory(bytes: u128) -> Result<(), BakeError> {
    let available = physical_memory().unwrap_or(u64::MAX);
    if bytes > available as u128 {
        return Err(BakeError::Memory {
            needed_mib: u64::try_from(bytes >> 20).unwrap_or(u64::MAX),
            available_mib: available >> 20,
        });
    }
    Ok(())
}
