//! `relight`: bake a static scene once, then relight it under any environment.
//!
//! Every subcommand lives in its own module; errors are reported with the file and the
//! problem, and a non-zero exit status.

mod bake;
mod bench;
mod common;
mod compare;
mod decompose;
mod demo;
mod eval;
mod eval_hybrid;
mod eval_sg;
mod eval_sg_basis;
mod hybrid;
mod info;
mod reference;
mod render;
mod sg;
mod store;

use clap::{Parser, Subcommand};

/// relight: precomputed light transport. Bake once, relight in real time.
#[derive(Parser)]
#[command(name = "relight", version, about, long_about = None)]
struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run the built-in demo (no downloads): bake, relight, path-trace, compare, report.
    Demo(demo::Args),
    /// Bake a scene description (JSON) into a bundle.
    Bake(bake::Args),
    /// Render a baked bundle under an environment (no re-baking).
    Render(render::Args),
    /// Render the ground truth of a scene with the reference path tracer.
    Reference(reference::Args),
    /// Export a scene for Mitsuba 3 (see tools/mitsuba_reference.py).
    ExportMitsuba(reference::ExportArgs),
    /// Evaluate a method against Mitsuba 3 ground truth (error per SH order).
    Eval(eval::Args),
    /// Split an environment into low-order SH plus directional cap lights (hybrid, thesis 4.3).
    Decompose(decompose::Args),
    /// Compare two images (EXR/HDR): RMSE, relative RMSE, PSNR, luminance error, heat map.
    Compare(compare::Args),
    /// Describe a baked bundle.
    Info(info::Args),
    /// Print SH coefficients of an environment map.
    Project(info::ProjectArgs),
    /// Benchmarks: ray throughput vs Embree, bake overhead, relight vs memory bandwidth.
    Bench(bench::Args),
}

/// Restore the default SIGPIPE action, so `relight ... | head` ends quietly like other Unix
/// tools instead of panicking on a closed stdout (Rust ignores SIGPIPE by default).
#[cfg(unix)]
fn default_sigpipe() {
    extern "C" {
        fn signal(signum: i32, handler: usize) -> usize;
    }
    const SIGPIPE: i32 = 13;
    const SIG_DFL: usize = 0;
    // SAFETY: setting a signal disposition to SIG_DFL at start-up, before any thread exists.
    unsafe {
        signal(SIGPIPE, SIG_DFL);
    }
}

fn main() {
    #[cfg(unix)]
    default_sigpipe();
    let cli = Cli::parse();
    if let Some(t) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(t.max(1))
            .build_global()
        {
            eprintln!("relight: warning: --threads ignored: {e}");
        }
    }
    let result = match cli.cmd {
        Cmd::Demo(a) => demo::run(a),
        Cmd::Bake(a) => bake::run(a),
        Cmd::Render(a) => render::run(a),
        Cmd::Reference(a) => reference::run(a),
        Cmd::ExportMitsuba(a) => reference::export(a),
        Cmd::Eval(a) => eval::run(a),
        Cmd::Decompose(a) => decompose::run(a),
        Cmd::Compare(a) => compare::run(a),
        Cmd::Info(a) => info::run(a),
        Cmd::Project(a) => info::project(a),
        Cmd::Bench(a) => bench::run(a),
    };
    if let Err(e) = result {
        eprintln!("relight: error: {e:#}");
        std::process::exit(1);
    }
}
