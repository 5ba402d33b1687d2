//! `relight`: bake a static scene once, then relight it under any environment.
//!
//! The binary only parses arguments and prints: every verb calls `relight-method` (bake,
//! bundles, frames) or `relight-eval` (experiments, demo, benchmarks). Errors are reported
//! with the file and the problem, and a non-zero exit status; `--json` prints one summary
//! object on stdout instead of the human report.

mod args;
mod bake;
mod compare;
mod decompose;
mod eval;
mod info;
mod reference;
mod render;
#[cfg(feature = "view")]
mod view;

use anyhow::{ensure, Result};
use args::Out;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::path::PathBuf;

/// relight: precomputed light transport. Bake once, relight in real time.
#[derive(Parser)]
#[command(name = "relight", version, about, long_about = None)]
struct Cli {
    /// Worker threads, 1 to 8 x the cores (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    /// Print one JSON summary on stdout (what was done, timings, output paths) instead of
    /// the human report; progress and messages stay on stderr.
    #[arg(long, global = true)]
    json: bool,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run the built-in demo (no downloads): every method baked, relit and compared with the
    /// path tracer; writes a contact sheet and an HTML report.
    Demo(DemoArgs),
    /// Bake a scene description (JSON) or a model file (glTF, OBJ, PLY) into a bundle.
    Bake(bake::Args),
    /// Merge the part bundles of a sharded bake (`bake --shard I/N`) into one bundle.
    Merge(bake::MergeArgs),
    /// Render a baked bundle under an environment (no re-baking).
    Render(render::Args),
    /// Render the ground truth of a scene with the reference path tracer.
    Reference(reference::Args),
    /// Export a scene for Mitsuba 3 (see tools/mitsuba_reference.py).
    ExportMitsuba(reference::ExportArgs),
    /// Evaluate a method against Mitsuba 3 ground truth.
    Eval(eval::Args),
    /// Split an environment into low-order SH plus directional cap lights (hybrid, thesis 4.3).
    Decompose(decompose::Args),
    /// Compare two images (EXR/HDR): RMSE, relative RMSE, PSNR, luminance error, heat map.
    Compare(compare::Args),
    /// Describe and check a baked bundle.
    Info(info::Args),
    /// Print SH coefficients of an environment map.
    Project(info::ProjectArgs),
    /// Benchmarks, each against a baseline measured in the same run.
    Bench(BenchArgs),
    /// The interactive viewer: a bundle relit on the GPU, next to a path-traced reference.
    #[cfg(feature = "view")]
    View(relight_view::cli::Args),
    /// The interactive viewer (needs a build with `--features view`).
    #[cfg(not(feature = "view"))]
    View {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Print the command-line reference (every verb, option and default) as Markdown.
    #[command(hide = true)]
    HelpMarkdown,
}

/// Arguments of `relight demo`.
#[derive(clap::Args)]
struct DemoArgs {
    /// Output folder.
    #[arg(short, long, default_value = "out/demo")]
    out: PathBuf,
    /// Image width (height is 3/4 of it), 16..=4096.
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Path-tracer samples per pixel of the references.
    #[arg(long, default_value_t = 256)]
    spp: u32,
    /// SH order of the sh bake.
    #[arg(long, visible_alias = "order", default_value_t = 6)]
    sh_order: usize,
    /// Directions per vertex of the sh bake.
    #[arg(long, default_value_t = 1024)]
    samples: u32,
}

/// Arguments of `relight bench`.
#[derive(clap::Args)]
struct BenchArgs {
    /// Rays per throughput measurement.
    #[arg(long, default_value_t = 2_000_000)]
    rays: usize,
    /// Mesh for the ray benchmark (default: DATA/data/meshes/dragon.obj with DATA the --data folder, else a procedural
    /// 100K-triangle sphere).
    #[arg(long)]
    ray_mesh: Option<PathBuf>,
    /// Mesh for the bake benchmark (default: DATA/data/meshes/bunny_watertight.obj with DATA the --data folder, else a
    /// procedural sphere on a plane).
    #[arg(long)]
    bake_mesh: Option<PathBuf>,
    /// The shared data folder (default: $RELIGHT_SHARED): dragon.obj, bunny_watertight.obj
    /// and armadillo.obj (the SG bake section) are taken from its data/meshes.
    #[arg(long)]
    data: Option<PathBuf>,
    /// Vertices of the relight benchmark.
    #[arg(long, default_value_t = 1_000_000)]
    relight_vertices: usize,
    /// Fewer rays, samples, vertices and repetitions (a quick smoke run).
    #[arg(long)]
    quick: bool,
    /// Run only these sections (comma-separated): rays, sh-bake, shard, relight, projection,
    /// hybrid, prefilter, sg-fit, sg-bake, sg-frame, cuts-bake, cuts-frame, cuts-local, vmf-fit, vmf-bake,
    /// gltf (needs --gltf), gpu (a build with `--features gpu`: GPU frames at 1280 x 720
    /// against the CPU frames).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// A textured GLB for the gltf section, compared with the OBJ of the same stem beside
    /// it (the test assets' spot.glb and spot.obj, under target/relight-gltf-assets/).
    #[arg(long)]
    gltf: Option<PathBuf>,
}

/// Restore the default SIGPIPE action, so `relight ... | head` ends quietly like other Unix
/// tools instead of panicking on a closed stdout (Rust ignores SIGPIPE by default).
/// The command that regenerates `docs/cli.md` (named in its header).
const REGENERATE: &str =
    "cargo run --release -p relight-cli --features view -- help-markdown > docs/cli.md";

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

/// Most worker threads accepted, per core: more only adds start-up time and memory.
const MAX_THREADS_PER_CORE: usize = 8;

fn set_threads(t: usize) -> Result<()> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    ensure!(
        (1..=MAX_THREADS_PER_CORE * cores).contains(&t),
        "--threads {t} is not in 1..={} ({MAX_THREADS_PER_CORE} x the {cores} cores)",
        MAX_THREADS_PER_CORE * cores
    );
    rayon::ThreadPoolBuilder::new()
        .num_threads(t)
        .build_global()
        .map_err(|e| anyhow::anyhow!("--threads {t}: {e}"))
}

fn run(cli: Cli, m: &clap::ArgMatches) -> Result<()> {
    if let Some(t) = cli.threads {
        set_threads(t)?;
    }
    let out = Out { json: cli.json };
    let sub = m.subcommand().map(|(_, s)| s).expect("a subcommand");
    match cli.cmd {
        Cmd::Demo(a) => {
            let (sheet, report) = relight_eval::demo::run(&relight_eval::demo::DemoOptions {
                out: a.out,
                width: a.width,
                spp: a.spp,
                sh_order: a.sh_order,
                samples: a.samples,
            })?;
            out.line(format!("contact sheet: {}", sheet.display()));
            out.line(format!("report:        {}", report.display()));
            out.summary(
                serde_json::json!({"command": "demo", "contact_sheet": sheet, "report": report}),
            );
        }
        Cmd::Bake(a) => bake::run(a, sub, &out)?,
        Cmd::Merge(a) => bake::merge(a, &out)?,
        Cmd::Render(a) => render::run(a, sub, &out)?,
        Cmd::Reference(a) => reference::run(a, &out)?,
        Cmd::ExportMitsuba(a) => reference::export(a, &out)?,
        Cmd::Eval(a) => eval::run(a, sub, &out)?,
        Cmd::Decompose(a) => decompose::run(a, &out)?,
        Cmd::Compare(a) => compare::run(a, &out)?,
        Cmd::Info(a) => info::run(a, &out)?,
        Cmd::Project(a) => info::project(a, &out)?,
        Cmd::Bench(a) => {
            let r = relight_eval::bench::run(&relight_eval::bench::BenchOptions {
                rays: a.rays,
                ray_mesh: a.ray_mesh,
                bake_mesh: a.bake_mesh,
                data: a
                    .data
                    .or_else(|| std::env::var_os("RELIGHT_SHARED").map(PathBuf::from)),
                relight_vertices: a.relight_vertices,
                quick: a.quick,
                only: a.only,
                gltf: a.gltf,
            })?;
            out.line(r.markdown());
            out.summary(serde_json::to_value(&r)?);
        }
        Cmd::HelpMarkdown => println!("{}", relight_clidoc::markdown(Cli::command(), REGENERATE)),
        #[cfg(feature = "view")]
        Cmd::View(mut a) => {
            a.bundle = view::bundle_for(&a.bundle, a.env.as_deref(), &out)?;
            if a.env.as_deref() == Some(std::path::Path::new("sky")) {
                a.env = None; // baked into the bundle: the viewer starts with it
            }
            relight_view::cli::run_cli(a)?
        }
        #[cfg(not(feature = "view"))]
        Cmd::View { .. } => anyhow::bail!("view: this relight was built without the viewer; rebuild it with `cargo build --release --features view` (it then needs a display and a Vulkan driver: on Debian `apt-get install mesa-vulkan-drivers libvulkan1`)"),
    }
    Ok(())
}

fn main() {
    #[cfg(unix)]
    default_sigpipe();
    let m = Cli::command().get_matches();
    let cli = match Cli::from_arg_matches(&m) {
        Ok(c) => c,
        Err(e) => e.exit(),
    };
    if let Err(e) = run(cli, &m) {
        eprintln!("relight: error: {e:#}");
        std::process::exit(1);
    }
}
