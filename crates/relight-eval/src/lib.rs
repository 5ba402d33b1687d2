//! # relight-eval: every method against ground truth, the paper figures, the demo
//!
//! Experiments are libraries so that the CLI only parses their options and prints their
//! tables:
//! * [`reference`](mod@reference): Mitsuba 3 references (two seeds, their noise), cached
//!   across runs, and the coverage mask of the pixels compared;
//! * [`output`]: images with error maps, markdown/JSON tables, HTML;
//! * [`sh`]: SH PRT error per SH order (`relight eval --method sh`);
//! * [`hybrid`]: the hybrid thesis' Table 5.1 (`--method hybrid`);
//! * [`sg`]: Green 2005 Fig. 3-4 and 3-5 (`--method sg`);
//! * [`sg_basis`]: Green 2005 Fig. 3-3, SG vs Haar vs SH (`--method sg-basis`);
//! * [`demo`]: the built-in demo, every method against the path tracer (`relight demo`);
//! * [`bench`](mod@bench): the benchmarks, each against a baseline measured in the same run.

pub mod bench;
pub mod cuts;
pub mod demo;
mod error;
pub mod hybrid;
pub mod output;
pub mod reference;
pub mod sg;
pub mod sg_basis;
pub mod sh;
pub mod vmf;

pub use error::{EvalError, Result};

use relight_method::{BakeContext, BakeInput, Baked, Method};
use relight_scene::scene::Scene;
use relight_scene::scene_file::SceneDesc;
use std::path::Path;

/// Bake every vertex of `scene` (built from `desc`, read from `origin`) with method `M`, with
/// a progress bar: what every experiment starts with.
///
/// # Errors
/// As [`Method::bake`].
pub fn bake<M: Method>(
    desc: &SceneDesc,
    scene: &Scene,
    origin: &Path,
    settings: &M::Settings,
) -> Result<Baked>
where
    Baked: From<M::Baked>,
{
    let input = BakeInput {
        desc,
        scene,
        origin,
    };
    let ctx = BakeContext {
        progress: true,
        ..Default::default()
    };
    Ok(M::bake(input, settings, 0..scene.mesh.vertex_count(), &ctx)?.into())
}

/// The highest of the SH orders to evaluate (one bake at it serves every order).
///
/// # Errors
/// [`EvalError::Options`] for an empty list.
pub fn max_order(orders: &[usize]) -> Result<usize> {
    orders
        .iter()
        .copied()
        .max()
        .ok_or_else(|| EvalError::Options("no SH order to evaluate".into()))
}

/// The shadowed SH settings every diffuse experiment bakes with (seed 1): direct lighting
/// with visibility, what Mitsuba renders at `max_depth = 2`.
pub fn shadowed(order: usize, samples: u32) -> relight_bake::sh::ShBakeSettings {
    relight_bake::sh::ShBakeSettings {
        order,
        samples,
        seed: 1,
        transfer: relight_bake::sh::ShTransferKind::Shadowed,
        ..Default::default()
    }
}
