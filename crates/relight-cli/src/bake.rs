//! `relight bake`: scene description -> baked bundle, for any method.

use crate::args::{self, arg_names, given, refuse_foreign, Out};
use anyhow::{bail, Context, Result};
use clap::ArgMatches;
use relight_bake::cuts::CutsBakeSettings;
use relight_bake::sg::SgBakeSettings;
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_bake::vmf::VmfBakeSettings;
use relight_method::cuts::Cuts;
use relight_method::job::{bake_to_file, BakeJob};
use relight_method::sg::{MaterialBlend, Sg, SgSettings};
use relight_method::sh::Sh;
use relight_method::shard::Shard;
use relight_method::vmf::Vmf;
use relight_method::{choose, BakeContext, BakeInput, BakeSummary, Baked, Method, MethodKind};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Arguments of `relight bake`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene description (JSON; see crates/relight-scene/src/scene_file.rs) or a model file
    /// (.glb, .gltf, .obj, .ply: see --env and --ground).
    pub scene: PathBuf,
    /// Output bundle (.relight).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Method to bake for (`hybrid` renders the `sh` bake, so it bakes that). Default: chosen
    /// from the scene's materials and printed with the reason: cuts if a material has texture
    /// or normal maps or is glossy, sh if every material is diffuse.
    #[arg(long, value_enum)]
    pub method: Option<MethodKind>,
    /// SH order n (n^2 coefficients, 1..=32): of the transfer (sh), of the diffuse part (sg).
    #[arg(
        long,
        visible_alias = "order",
        alias = "diffuse-order",
        default_value_t = 5
    )]
    pub sh_order: usize,
    /// Indirect bounces: of the interreflected transfer (sh with --transfer interreflected;
    /// default 1), of the indirect glossy paths (sg with --indirect-lobes > 0; default 3),
    /// scatterings after the point (vmf; default 1, the paper's).
    #[arg(long)]
    pub bounces: Option<u32>,
    /// Random seed (the bake is deterministic for a seed, whatever the thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Store the method's float tensors as f16 (half the size).
    #[arg(long)]
    pub f16: bool,
    /// Ray-casting back-end: embree or bvh (default: the fastest in this build).
    #[arg(long)]
    pub backend: Option<String>,
    /// Bake only part I of N (0-based; e.g. `--shard $SLURM_ARRAY_TASK_ID/4`): a part bundle
    /// of the vertices I*V/N..(I+1)*V/N, for `relight merge` (sh with unshadowed or shadowed
    /// transfer; see deploy/slurm/).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
    /// Checkpoint the bake every N vertices into OUT.checkpoint/ (atomic chunk bundles), so
    /// that a killed bake can be finished with --resume (sh with unshadowed or shadowed
    /// transfer).
    #[arg(long, value_name = "N", conflicts_with = "shard", value_parser = clap::value_parser!(u64).range(1..))]
    pub checkpoint_vertices: Option<u64>,
    /// Finish an interrupted checkpointed bake: bake only the chunks missing from
    /// OUT.checkpoint/ (same command and --checkpoint-vertices), then write the bundle an
    /// uninterrupted bake writes, byte for byte.
    #[arg(long)]
    pub resume: bool,
    /// Memory budget, e.g. 2G or 512M: a bake whose rows would not fit is baked in chunks
    /// written to OUT.checkpoint/ and merged by streaming (sh with unshadowed or shadowed
    /// transfer); one that cannot be chunked is refused with the estimate before baking.
    #[arg(long, value_name = "SIZE", value_parser = relight_method::memory::parse_size, conflicts_with = "shard")]
    pub memory_limit: Option<u64>,
    /// How the scene is read.
    #[command(flatten)]
    pub read: args::SceneArgs,
    /// SH options.
    #[command(flatten)]
    pub sh: ShBakeSettings,
    /// SG options.
    #[command(flatten)]
    pub sg: SgBakeSettings,
    /// SG material blend.
    #[command(flatten)]
    pub blend: BlendArgs,
    /// Cuts options.
    #[command(flatten)]
    pub cuts: CutsBakeSettings,
    /// vMF options.
    #[command(flatten)]
    pub vmf: VmfBakeSettings,
}

/// `relight bake --method sg`'s spatially varying material (thesis 2.3.1).
#[derive(clap::Args, Clone, Debug)]
#[command(next_help_heading = "SG bake (--method sg)")]
pub struct BlendArgs {
    /// Blend the scene's material into this one across the mesh: a material as JSON (e.g.
    /// '{"type": "ggx_plastic", "diffuse": [0.1, 0.6, 0.1], "specular": [1, 1, 1], "alpha":
    /// 0.05, "ior": 1.5}') or a .json file holding one.
    #[arg(long, value_name = "MATERIAL_JSON")]
    pub blend_to: Option<String>,
    /// Axis of the blend, x,y,z: the scene's material at the lowest vertex along it, the
    /// --blend-to material at the highest.
    #[arg(long, default_value = "0,1,0", allow_hyphen_values = true)]
    pub blend_axis: String,
}

impl BlendArgs {
    /// The blend, if `--blend-to` was given.
    fn blend(&self) -> Result<Option<MaterialBlend>> {
        let Some(to) = &self.blend_to else {
            return Ok(None);
        };
        let axis = args::vec3(&self.blend_axis, "--blend-axis")?;
        Ok(Some(
            MaterialBlend::parse(to, axis.into()).context("--blend-to")?,
        ))
    }
}

/// Check the options against the method (given or chosen) before baking.
fn check_options(a: &Args, method: MethodKind, m: &ArgMatches) -> Result<()> {
    let mut sg = arg_names::<SgBakeSettings>();
    sg.extend(arg_names::<BlendArgs>());
    let foreign = refuse_foreign(
        m,
        method,
        &[
            (
                &[MethodKind::Sh, MethodKind::Hybrid],
                arg_names::<ShBakeSettings>(),
            ),
            (&[MethodKind::Sg], sg),
            (&[MethodKind::Cuts], arg_names::<CutsBakeSettings>()),
            (&[MethodKind::Vmf], arg_names::<VmfBakeSettings>()),
        ],
    );
    if a.method.is_none() {
        foreign.with_context(|| {
            format!(
                "--method {} was chosen from the materials: give --method to bake with another",
                method.name()
            )
        })?;
    } else {
        foreign?;
    }
    if a.shard.is_some_and(|s| s.count > 1) || a.checkpoint_vertices.is_some() {
        let opt = if a.shard.is_some() {
            "--shard"
        } else {
            "--checkpoint-vertices"
        };
        if a.sh.transfer == ShTransferKind::Interreflected {
            bail!("{opt}: interreflected transfer cannot be split (each bounce gathers the previous bounce of every vertex, so every part would trace the whole mesh); bake it whole, or split a shadowed bake");
        }
    }
    if a.resume && a.checkpoint_vertices.is_none() && a.memory_limit.is_none() {
        bail!("--resume finishes a bake checkpointed with --checkpoint-vertices or chunked by --memory-limit: give the same options again");
    }
    let ckpt = relight_method::checkpoint::folder(&a.out);
    if a.checkpoint_vertices.is_none() && a.memory_limit.is_none() && ckpt.exists() {
        bail!(
            "{}: holds a checkpoint of an interrupted bake of {}: rerun the same command with --checkpoint-vertices and --resume to finish it, or delete the folder",
            ckpt.display(),
            a.out.display()
        );
    }
    if given(m, "bounces") {
        match method {
            MethodKind::Sh | MethodKind::Hybrid
                if a.sh.transfer != ShTransferKind::Interreflected =>
            {
                bail!("--bounces applies to --transfer interreflected")
            }
            MethodKind::Sg if a.sg.indirect_lobes == 0 => {
                bail!("--bounces applies to sg bakes with --indirect-lobes above 0")
            }
            _ => {}
        }
    }
    Ok(())
}

/// Run `relight bake`.
pub fn run(a: Args, m: &ArgMatches, out: &Out) -> Result<()> {
    if let Some(method) = a.method {
        check_options(&a, method, m)?;
    }
    relight_bundle::output::check_outputs(&[&a.out], &["relight"], &[&a.scene])?;
    let ctx = BakeContext {
        backend: args::backend(a.backend.as_deref())?,
        f16: a.f16,
        progress: true,
    };
    let (desc, scene) = a.read.load(&a.scene)?;
    let method = match a.method {
        Some(method) => {
            let w = choose::method_warning(method, &desc, &scene.materials, &scene.maps);
            w.into_iter().for_each(|w| eprintln!("{w}"));
            method
        }
        None => {
            let choice = choose::choose_bake_method(&desc, &scene.materials, &scene.maps);
            eprintln!("{choice}; --method chooses another");
            check_options(&a, choice.method, m)?;
            choice.method
        }
    };
    let input = BakeInput {
        desc: &desc,
        scene: &scene,
        origin: &a.scene,
    };
    let what = format!(
        "baking {} ({} vertices, {} triangles)",
        a.scene.display(),
        scene.mesh.vertex_count(),
        scene.mesh.triangle_count()
    );
    let baked: BakeSummary = match method.bake_kind() {
        relight_method::BakeKind::Sh => {
            let s = ShBakeSettings {
                order: a.sh_order,
                seed: a.seed,
                bounces: match a.sh.transfer {
                    ShTransferKind::Interreflected => a.bounces.unwrap_or(1),
                    _ => 0,
                },
                ..a.sh
            };
            bake_with::<Sh>(input, &s, &a, &ctx, &what)?
        }
        relight_method::BakeKind::Sg => {
            let mut s = SgSettings {
                bake: SgBakeSettings {
                    diffuse_order: a.sh_order,
                    max_depth: a.bounces.unwrap_or(SgBakeSettings::default().max_depth),
                    seed: a.seed,
                    ..a.sg
                },
                blend: a.blend.blend()?,
            };
            if !args::sg_lobes_given(m) {
                let why;
                (s, why) = s.with_lobes_for(&scene.materials);
                eprintln!(
                    "sg lobes: {} ({why}; --lobe-kernel, --lobe-domain, --lobe-order choose others)",
                    s.bake.fit.lobes().describe()
                );
            }
            bake_with::<Sg>(input, &s, &a, &ctx, &what)?
        }
        relight_method::BakeKind::Cuts => {
            let s = CutsBakeSettings {
                seed: a.seed,
                ..a.cuts
            };
            bake_with::<Cuts>(input, &s, &a, &ctx, &what)?
        }
        relight_method::BakeKind::Vmf => {
            let s = VmfBakeSettings {
                seed: a.seed,
                max_bounces: a.bounces.unwrap_or(VmfBakeSettings::default().max_bounces),
                ..a.vmf
            };
            bake_with::<Vmf>(input, &s, &a, &ctx, &what)?
        }
    };
    report(&a.out, &baked, out);
    Ok(())
}

/// Check the settings, say what is baked (`what` and the settings), then bake with `M` as the
/// options say ([`relight_method::job`]) and write the bundle.
fn bake_with<M: Method>(
    input: BakeInput,
    settings: &M::Settings,
    a: &Args,
    ctx: &BakeContext,
    what: &str,
) -> Result<BakeSummary>
where
    M::Baked: Into<Baked>,
{
    M::validate(settings)?;
    eprintln!("{what}: {}", M::settings_line(settings));
    let job = BakeJob {
        shard: a.shard,
        checkpoint_vertices: a.checkpoint_vertices,
        memory_limit: a.memory_limit,
        resume: a.resume,
        resident: relight_eval::bench::resident_bytes().unwrap_or(0),
    };
    Ok(bake_to_file::<M>(
        input,
        settings,
        &job,
        ctx,
        &a.out,
        |l| eprintln!("{l}"),
    )?)
}

/// Print what was written.
fn report(path: &Path, baked: &BakeSummary, out: &Out) {
    let r = &baked.record;
    let v = baked.vertices.max(1);
    let size = args::mib(path);
    let peak = relight_eval::bench::peak_rss_mib();
    out.line(format!(
        "wrote {} ({size:.2} MiB, {} bytes per vertex) in {:.2} s with {}{}",
        path.display(),
        (size * (1 << 20) as f64) as usize / v,
        r.seconds,
        r.backend,
        peak.map_or(String::new(), |m| format!(", peak memory {m:.0} MiB"))
    ));
    let mut extra = json!({});
    if let Some((lines, j)) = &baked.describe {
        lines.iter().for_each(|l| out.line(l.clone()));
        extra = j.clone();
    }
    out.summary(json!({
        "command": "bake",
        "shard": r.shard,
        "peak_rss_mib": peak,
        "method": baked.kind.name(),
        "out": path,
        "bytes": std::fs::metadata(path).map_or(0, |m| m.len()),
        "vertices": baked.vertices,
        "triangles": baked.triangles,
        "seconds": r.seconds,
        "backend": r.backend,
        "f16": r.f16,
        "settings": serde_json::from_str::<serde_json::Value>(&baked.settings_json).unwrap_or_default(),
        baked.kind.name(): extra,
    }));
}

/// Arguments of `relight merge`.
#[derive(clap::Args)]
pub struct MergeArgs {
    /// The part bundles of one sharded bake (`relight bake --shard I/N`), in any order.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Output bundle (.relight): byte-identical to the same bake done in one process.
    #[arg(short, long)]
    pub out: PathBuf,
}

/// Run `relight merge`.
pub fn merge(a: MergeArgs, out: &Out) -> Result<()> {
    let inputs: Vec<&Path> = a.parts.iter().map(PathBuf::as_path).collect();
    relight_bundle::output::check_outputs(&[&a.out], &["relight"], &inputs)?;
    let t0 = std::time::Instant::now();
    let whole = relight_method::shard::merge_files(&a.parts, &a.out)?;
    out.line(format!(
        "merged {} parts into {} ({:.2} MiB, {} vertices) in {:.2} s",
        a.parts.len(),
        a.out.display(),
        args::mib(&a.out),
        whole.vertices,
        t0.elapsed().as_secs_f64()
    ));
    out.summary(json!({
        "command": "merge",
        "parts": a.parts,
        "out": a.out,
        "bytes": std::fs::metadata(&a.out).map_or(0, |m| m.len()),
        "vertices": whole.vertices,
        "bake_seconds": whole.record.seconds,
        "seconds": t0.elapsed().as_secs_f64(),
    }));
    Ok(())
}
