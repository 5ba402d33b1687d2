//! `relight bake`: scene description -> baked bundle.

use crate::store::{kind_name, RecordedSettings, ShBake};
use anyhow::{anyhow, bail, Context, Result};
use relight_bake::sh::{self, ShBakeSettings, ShTransferKind};
use relight_scene::accel::{self, Backend};
use relight_scene::scene::Scene;
use relight_scene::scene_file::SceneDesc;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `relight bake`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene description (JSON; see crates/relight-scene/src/scene_file.rs).
    pub scene: PathBuf,
    /// Output bundle.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Method: `sh` (diffuse SH PRT) or `sg` (Green 2005 view-dependent glossy PRT with
    /// spherical Gaussians; options under "SG bake").
    #[arg(long, default_value = "sh")]
    pub method: String,
    /// SH order n (n^2 coefficients), 1..=32.
    #[arg(long, default_value_t = 5)]
    pub order: usize,
    /// Transfer: unshadowed, shadowed or interreflected.
    #[arg(long, default_value = "shadowed")]
    pub transfer: String,
    /// Interreflection bounces (with --transfer interreflected).
    #[arg(long, default_value_t = 1)]
    pub bounces: u32,
    /// Directions per vertex.
    #[arg(long, default_value_t = 1024)]
    pub samples: u32,
    /// Random seed (the bake is deterministic for a seed, whatever the thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Store the transfer as f16 (half the size).
    #[arg(long)]
    pub f16: bool,
    /// Ray-casting back-end: embree or bvh (default: the fastest available).
    #[arg(long)]
    pub backend: Option<String>,
    #[command(flatten)]
    pub sg: crate::sg::SgBakeOpts,
}

/// Parse a transfer kind.
pub fn parse_kind(s: &str, bounces: u32) -> Result<ShTransferKind> {
    Ok(match s {
        "unshadowed" => ShTransferKind::Unshadowed,
        "shadowed" => ShTransferKind::Shadowed,
        "interreflected" => ShTransferKind::Interreflected { bounces },
        _ => bail!("unknown --transfer '{s}' (unshadowed, shadowed, interreflected)"),
    })
}

/// Parse a back-end name.
pub fn parse_backend(s: Option<&str>) -> Result<Backend> {
    Ok(match s {
        None => Backend::available()[0],
        Some("embree") => Backend::Embree,
        Some("bvh") => Backend::Bvh,
        Some(o) => bail!("unknown --backend '{o}' (embree, bvh)"),
    })
}

/// Bake a loaded scene.
pub fn bake_scene(
    desc: &SceneDesc,
    scene: &Scene,
    settings: &ShBakeSettings,
    backend: Backend,
    f16: bool,
    origin: &Path,
) -> Result<ShBake> {
    let t0 = Instant::now();
    let caster = accel::build(&scene.mesh, backend)
        .map_err(|e| anyhow!("{}: cannot build the ray caster: {e}", origin.display()))?;
    let transfer = sh::bake(&scene.mesh, &scene.materials, caster.as_ref(), settings)
        .with_context(|| format!("baking {}", origin.display()))?;
    let albedo = relight_bake::transport::vertex_albedo(&scene.mesh, &scene.materials);
    let bounces = match settings.kind {
        ShTransferKind::Interreflected { bounces } => bounces,
        _ => 0,
    };
    Ok(ShBake {
        scene: desc.clone(),
        mesh: scene.mesh.clone(),
        materials: scene.materials.clone(),
        albedo,
        transfer,
        settings: RecordedSettings {
            order: settings.order,
            transfer: kind_name(settings.kind).into(),
            bounces,
            samples: settings.samples,
            seed: settings.seed,
            f16,
            backend: caster.name().into(),
            seconds: t0.elapsed().as_secs_f64(),
        },
    })
}

/// Run `relight bake`.
pub fn run(a: Args) -> Result<()> {
    if a.method == "sg" {
        return crate::sg::run_bake(&a);
    }
    if a.method != "sh" {
        bail!("unknown --method '{}' (sh, sg)", a.method);
    }
    let desc = SceneDesc::read(&a.scene)?;
    let scene = desc.build(&a.scene)?;
    let settings = ShBakeSettings {
        order: a.order,
        samples: a.samples,
        seed: a.seed,
        kind: parse_kind(&a.transfer, a.bounces)?,
        threads: None,
        progress: true,
    };
    settings.validate()?;
    eprintln!(
        "baking {} ({} vertices, {} triangles): SH order {}, {} transfer, {} samples",
        a.scene.display(),
        scene.mesh.vertex_count(),
        scene.mesh.triangle_count(),
        a.order,
        a.transfer,
        a.samples
    );
    let baked = bake_scene(
        &desc,
        &scene,
        &settings,
        parse_backend(a.backend.as_deref())?,
        a.f16,
        &a.scene,
    )?;
    baked.to_bundle()?.write(&a.out)?;
    let size = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    println!(
        "wrote {} ({:.2} MiB) in {:.2} s with {}",
        a.out.display(),
        size as f64 / (1 << 20) as f64,
        baked.settings.seconds,
        baked.settings.backend
    );
    Ok(())
}
