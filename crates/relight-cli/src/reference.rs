//! `relight reference` (path-traced ground truth) and `relight export-mitsuba`.

use crate::common::{parse_tonemap, write_image};
use anyhow::{anyhow, Result};
use relight_render::pathtrace::{self, PtSettings};
use relight_scene::scene_file::SceneDesc;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `relight reference`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene description (JSON).
    pub scene: PathBuf,
    /// Output images (.exr, .hdr, .png); repeat for several.
    #[arg(short, long, required = true)]
    pub out: Vec<PathBuf>,
    /// Samples per pixel.
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Longest path, Mitsuba semantics: 2 = direct only, 3 = one indirect bounce, -1 = unlimited.
    #[arg(long, default_value_t = -1, allow_hyphen_values = true)]
    pub max_depth: i32,
    /// Random seed (deterministic for a seed).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Show black instead of the environment behind the objects.
    #[arg(long)]
    pub no_background: bool,
    /// Tone map for PNG outputs.
    #[arg(long, default_value = "exp:1")]
    pub tonemap: String,
}

/// Run `relight reference`.
pub fn run(a: Args) -> Result<()> {
    let tm = parse_tonemap(&a.tonemap)?;
    let desc = SceneDesc::read(&a.scene)?;
    let scene = desc.build(&a.scene)?;
    let t0 = Instant::now();
    let caster = relight_scene::accel::build(&scene.mesh, crate::bake::parse_backend(None)?)
        .map_err(|e| anyhow!("{}: {e}", a.scene.display()))?;
    let s = PtSettings {
        spp: a.spp.max(1),
        max_depth: a.max_depth,
        seed: a.seed,
        threads: None,
        show_background: !a.no_background,
        progress: true,
    };
    let img = pathtrace::render(&scene, caster.as_ref(), &s);
    for o in &a.out {
        write_image(o, &img, &tm)?;
        println!("wrote {}", o.display());
    }
    println!(
        "path traced {}x{} at {} spp in {:.2} s",
        img.width,
        img.height,
        s.spp,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Arguments of `relight export-mitsuba`.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// Scene description (JSON).
    pub scene: PathBuf,
    /// Output folder (PLY meshes, EXR environment, scene.json for tools/mitsuba_reference.py).
    pub dir: PathBuf,
    /// Samples per pixel for Mitsuba.
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Mitsuba max_depth (2 = direct only, -1 = unlimited).
    #[arg(long, default_value_t = -1, allow_hyphen_values = true)]
    pub max_depth: i32,
}

/// Run `relight export-mitsuba`.
pub fn export(a: ExportArgs) -> Result<()> {
    let desc = SceneDesc::read(&a.scene)?;
    let scene = desc.build(&a.scene)?;
    std::fs::create_dir_all(&a.dir).map_err(|e| anyhow!("{}: {e}", a.dir.display()))?;
    let json = relight_render::mitsuba::export_mitsuba(&scene, &a.dir, a.spp, a.max_depth)
        .map_err(|e| anyhow!("exporting to {}: {e}", a.dir.display()))?;
    println!("wrote {}", json.display());
    println!(
        "render it with: python tools/mitsuba_reference.py {} out.exr",
        json.display()
    );
    Ok(())
}
