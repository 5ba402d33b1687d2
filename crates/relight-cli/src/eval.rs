//! `relight eval`: each method against Mitsuba 3 ground truth (the experiments live in
//! `relight-eval`; this parses their options).

use crate::args::{self, arg_names, named, refuse_foreign, Out};
use anyhow::{bail, ensure, Context, Result};
use clap::ArgMatches;
use relight_bake::cuts::CutsBakeSettings;
use relight_bake::sg::SgBakeSettings;
use relight_eval::reference::example_scenes;
use relight_eval::{cuts, hybrid, sg, sg_basis, sh, vmf};
use relight_method::hybrid::HybridSettings;
use relight_method::sg::SgSettings;
use std::path::PathBuf;

/// The experiments of `relight eval`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum EvalMethod {
    /// SH PRT error per SH order.
    Sh,
    /// The hybrid thesis' Table 5.1: SH vs the thesis' hybrid vs relight's.
    Hybrid,
    /// Green 2005 Fig. 3-4 and 3-5 (SG against Mitsuba, and against environment mapping).
    Sg,
    /// Green 2005 Fig. 3-3: SG vs Haar vs SH on three transport functions (no Mitsuba).
    SgBasis,
    /// Cheslack-Postava 2008 Fig. 9 and 10 (cuts against Mitsuba; materials edited after
    /// the bake).
    Cuts,
    /// Laurijssen & Dutré 2009 Tables 1-2, uniform refinement, path tracer, Mitsuba and sg.
    Vmf,
}

/// Arguments of `relight eval`.
///
/// The SG bake's options are `relight bake --method sg`'s, except that `--direct-lobes`
/// takes a comma-separated list here (`--direct-lobes 1,2,3`): every experiment is baked and
/// scored once per count (read with `direct_lobes`; the bake settings keep the first).
#[derive(clap::Args)]
#[command(mut_arg("direct_lobes", |a| a
    .value_delimiter(',')
    .action(clap::ArgAction::Append)
    .help("Direct lobe counts to evaluate, comma-separated (e.g. 1,2,3): each experiment is baked and scored once per count")))]
pub struct Args {
    /// Scene descriptions (JSON). Default: the method's own experiments, from --examples
    /// (hybrid: teapot_table.json; sg: sg_spot.json and sg_shadowed_highlight.json).
    pub scenes: Vec<PathBuf>,
    /// What to evaluate.
    #[arg(long, value_enum, default_value_t = EvalMethod::Sh)]
    pub method: EvalMethod,
    /// Environments to light every scene with, in turn (sh: default each scene's own;
    /// hybrid: default the thesis' probes from --data).
    #[arg(long)]
    pub env: Vec<PathBuf>,
    /// SH orders to evaluate, e.g. `5`, `3,4,6`, `2-10` (one bake at the highest). Default:
    /// 2-10 for sh, 5 for hybrid.
    #[arg(long, visible_alias = "orders")]
    pub sh_orders: Option<String>,
    /// Bake directions per vertex (sh, hybrid).
    #[arg(long, default_value_t = 1024)]
    pub samples: u32,
    /// Mitsuba samples per pixel (per seed; two seeds are rendered).
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Hybrid: also render a better reference with this many spp per seed and score every
    /// method against it.
    #[arg(long)]
    pub reference_spp: Option<u32>,
    /// Image width (the height keeps the scene camera's aspect).
    #[arg(long)]
    pub width: Option<u32>,
    /// Output folder (images, results.md, results.json).
    #[arg(short, long, default_value = "out/eval")]
    pub out: PathBuf,
    /// Folder of the example scenes the default experiments use.
    #[arg(long, default_value = "examples")]
    pub examples: PathBuf,
    /// The shared data folder (default probes of --method hybrid); default: $RELIGHT_SHARED.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// SG: also compute the error budget of every bake (the error of each approximation of
    /// the frame in turn; renders a direct-lighting reference for experiments with
    /// interreflections).
    #[arg(long)]
    pub budget: bool,
    /// SG: score the error budget on every N-th pixel along each axis only (its per-sample
    /// rows fit a cube map at each of the 16 samples of a pixel: a frame-filling object takes
    /// hours at 1). The frame's rows are scored on the same pixels.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub budget_stride: u32,
    /// SG: run only these of the default experiments (comma-separated names, e.g.
    /// `fig3-4_conductor,teapot_dawn_conductor`).
    #[arg(long, value_delimiter = ',')]
    pub experiments: Vec<String>,
    /// Hybrid options.
    #[command(flatten)]
    pub hybrid: HybridSettings,
    /// SG options.
    #[command(flatten)]
    pub sg: SgBakeSettings,
    /// Cuts: illumination-cut budgets to render each bake with, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [128usize, 256, 512])]
    pub light_cuts: Vec<usize>,
    /// Cuts: score only the scene's own materials (skip re-rendering the bake with the
    /// edited materials, and their Mitsuba references).
    #[arg(long)]
    pub scene_materials_only: bool,
    /// Cuts options (`--cut-tree` given: that tree only; else the geometric and the
    /// data-driven tree in turn).
    #[command(flatten)]
    pub cuts: CutsBakeSettings,
    /// vMF evaluation options (with `relight bake --method vmf`'s).
    #[command(flatten)]
    pub vmf: vmf::VmfEvalArgs,
}

/// Print the tables the experiment wrote: markdown, or one JSON object with its rows.
fn print(a: &Args, out: &Out) -> Result<()> {
    let (md, json) = match a.method {
        EvalMethod::SgBasis => ("fig3-3.md", None),
        _ => ("results.md", Some("results.json")),
    };
    let md = a.out.join(md);
    out.line(std::fs::read_to_string(&md).with_context(|| md.display().to_string())?);
    let rows = match json {
        Some(j) => {
            let p = a.out.join(j);
            let text = std::fs::read_to_string(&p).with_context(|| p.display().to_string())?;
            serde_json::from_str(&text)?
        }
        None => serde_json::Value::Null,
    };
    let method = clap::ValueEnum::to_possible_value(&a.method).map(|v| v.get_name().to_string());
    out.summary(serde_json::json!({"command": "eval", "method": method, "out": a.out, "table": md, "rows": rows}));
    Ok(())
}

/// Run `relight eval`.
pub fn run(a: Args, m: &ArgMatches, out: &Out) -> Result<()> {
    use EvalMethod::*;
    refuse_foreign(
        m,
        a.method,
        &[
            (&[Sh, Hybrid], named(&["sh_orders", "samples", "env"])),
            (&[Hybrid], named(&["reference_spp", "data"])),
            (&[Hybrid], arg_names::<HybridSettings>()),
            (&[Sg], arg_names::<SgBakeSettings>()),
            (&[Sg], named(&["budget", "experiments"])),
            (&[Cuts], arg_names::<CutsBakeSettings>()),
            (&[Cuts], named(&["light_cuts", "scene_materials_only"])),
            (&[Vmf], arg_names::<vmf::VmfEvalArgs>()),
            (
                &[Sh, Hybrid, Sg, Cuts, Vmf],
                named(&["width", "spp", "examples"]),
            ),
        ],
    )?;
    ensure!(
        (1..=1 << 20).contains(&a.spp),
        "--spp {} is not in 1..=1048576",
        a.spp
    );
    if let Some(w) = a.width {
        ensure!((8..=8192).contains(&w), "--width {w} is not in 8..=8192");
    }
    ensure!(
        a.experiments.is_empty() || a.scenes.is_empty(),
        "--experiments selects default experiments; scene files make their own"
    );
    let orders = |default: &str| args::orders(a.sh_orders.as_deref().unwrap_or(default));
    match a.method {
        Sh => {
            sh::run(&sh::ShEval {
                scenes: a.scenes.clone(),
                envs: a.env.clone(),
                orders: orders("2-10")?,
                samples: a.samples,
                spp: a.spp,
                width: a.width,
                out: a.out.clone(),
            })?;
        }
        Hybrid => {
            let scene = match a.scenes.as_slice() {
                [] => example_scenes(&a.examples, &["teapot_table.json"])?.remove(0),
                [s] => s.clone(),
                _ => bail!("--method hybrid evaluates one scene at a time"),
            };
            let envs = if a.env.is_empty() {
                hybrid::default_probes(a.data.as_deref())?
            } else {
                a.env.clone()
            };
            hybrid::run(&hybrid::HybridEval {
                scene,
                envs,
                orders: orders("5")?,
                samples: a.samples,
                spp: a.spp,
                reference_spp: a.reference_spp,
                width: a.width,
                settings: a.hybrid,
                out: a.out.clone(),
            })?;
        }
        Sg => {
            let settings = SgSettings {
                bake: SgBakeSettings { seed: 1, ..a.sg },
                blend: None,
            };
            let experiments = if a.scenes.is_empty() {
                example_scenes(&a.examples, &sg::DEFAULT_SCENES)?;
                sg::select_experiments(sg::default_experiments(&a.examples), &a.experiments)?
            } else {
                sg::scene_experiments(&a.scenes, &settings)
            };
            sg::run(&sg::SgEval {
                experiments,
                settings,
                lobes: m
                    .get_many::<usize>("direct_lobes")
                    .map_or(vec![], |v| v.copied().collect()),
                lobes_by_material: !args::sg_lobes_given(m),
                budget: a.budget,
                budget_stride: a.budget_stride as usize,
                spp: a.spp,
                width: a.width,
                out: a.out.clone(),
            })?;
        }
        SgBasis => sg_basis::run(&a.out)?,
        Cuts => {
            let scenes = if a.scenes.is_empty() {
                example_scenes(&a.examples, &cuts::DEFAULT_SCENES)?
            } else {
                a.scenes.clone()
            };
            cuts::run(&cuts::CutsEval {
                scenes,
                settings: CutsBakeSettings {
                    progress: true,
                    ..a.cuts
                },
                trees: cuts::trees(args::given(m, "tree").then_some(a.cuts.tree)),
                light_cuts: a.light_cuts.clone(),
                edited_materials: !a.scene_materials_only,
                spp: a.spp,
                width: a.width,
                out: a.out.clone(),
            })?;
        }
        Vmf => vmf::run_args(
            &a.vmf,
            |id: &str| args::given(m, id),
            (a.scenes.as_slice(), a.examples.as_path(), a.spp, a.width),
            &a.out,
        )?,
    }
    print(&a, out)
}
