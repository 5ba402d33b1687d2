//! # relight-eval: every method against ground truth, the paper figures, the demo
//!
//! Experiments are libraries so that the CLI only parses their options and prints their
//! tables:
//! * [`reference`]: Mitsuba 3 references (two seeds, their noise), cached across runs, and
//!   the coverage mask of the pixels compared;
//! * [`output`]: images with error maps, markdown/JSON tables, HTML;
//! * [`sh`]: SH PRT error per SH order (`relight eval --method sh`);
//! * [`hybrid`]: the hybrid thesis' Table 5.1 (`--method hybrid`);
//! * [`sg`]: Green 2005 Fig. 3-4 and 3-5 (`--method sg`);
//! * [`sg_basis`]: Green 2005 Fig. 3-3, SG vs Haar vs SH (`--method sg-basis`);
//! * [`demo`]: the built-in demo, every method against the path tracer (`relight demo`);
//! * [`bench`]: the benchmarks, each against a baseline measured in the same run.

pub mod bench;
pub mod demo;
mod error;
pub mod hybrid;
pub mod output;
pub mod reference;
pub mod sg;
pub mod sg_basis;
pub mod sh;

pub use error::{EvalError, Result};
