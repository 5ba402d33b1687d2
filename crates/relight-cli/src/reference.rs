//! `relight reference` (path-traced ground truth) and `relight export-mitsuba`.

use crate::args::{self, Out};
use anyhow::{anyhow, Result};
use relight_render::pathtrace::{self, PtSettings};
use relight_render::{mitsuba, write_image};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Most samples per pixel of `relight reference` (2^20).
const MAX_SPP: u32 = 1 << 20;

/// Arguments of `relight reference`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene description (JSON) or a model file (.glb, .gltf, .obj, .ply).
    pub scene: PathBuf,
    /// Output images (.exr, .hdr, .png); repeat for several.
    #[arg(short, long, required = true)]
    pub out: Vec<PathBuf>,
    /// Samples per pixel (at least 1).
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Longest path, Mitsuba semantics: 2 = direct only, 3 = one indirect bounce, -1 = unlimited.
    #[arg(long, default_value_t = -1, allow_negative_numbers = true)]
    pub max_depth: i32,
    /// Random seed (deterministic for a seed).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Draw the environment behind the objects (as `render --background`; black without).
    #[arg(long)]
    pub background: bool,
    /// Tone map for PNG outputs (as `relight render`'s; default: the same automatic
    /// exposure).
    #[arg(long)]
    pub tonemap: Option<String>,
    /// How the scene is read.
    #[command(flatten)]
    pub read: args::SceneArgs,
    /// A point or spot light besides the environment.
    #[command(flatten)]
    pub light: relight_method::cuts::local::PointLightArgs,
}

/// Run `relight reference`.
pub fn run(a: Args, out: &Out) -> Result<()> {
    if let Some(t) = &a.tonemap {
        args::tonemap(t)?;
    }
    let s = PtSettings {
        spp: a.spp,
        max_depth: a.max_depth,
        seed: a.seed,
        threads: None,
        show_background: a.background,
        progress: true,
    };
    s.validate(MAX_SPP).map_err(anyhow::Error::msg)?;
    args::check_image_outputs(&a.out, &[&a.scene])?;
    let (_, scene) = a.read.load(&a.scene)?;
    let opts = relight_method::FrameOptions {
        supersample: 1,
        background: a.background,
    };
    relight_method::check_frame_options(&opts, &scene.camera)?;
    let t0 = Instant::now();
    let caster = relight_scene::accel::build(&scene.mesh, args::backend(None)?)
        .map_err(|e| anyhow!("{}: {e}", a.scene.display()))?;
    let lights = a.light.lights_in(&scene.mesh, caster.as_ref())?;
    let (img, _) = pathtrace::render_with_lights(&scene, caster.as_ref(), &s, &lights);
    let tm = args::png_tonemap(a.tonemap.as_deref(), &img, &a.out, out)?;
    for o in &a.out {
        write_image(o, &img, &tm)?;
        out.line(format!("wrote {}", o.display()));
    }
    let secs = t0.elapsed().as_secs_f64();
    out.line(format!(
        "path traced {}x{} at {} spp in {secs:.2} s",
        img.width, img.height, s.spp
    ));
    out.summary(json!({"command": "reference", "scene": a.scene, "outputs": a.out, "spp": a.spp, "max_depth": a.max_depth, "seconds": secs}));
    Ok(())
}

/// Arguments of `relight export-mitsuba`.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// Scene description (JSON) or a model file (.glb, .gltf, .obj, .ply).
    pub scene: PathBuf,
    /// Output folder (PLY meshes, EXR environment, scene.json for tools/mitsuba_reference.py).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Samples per pixel for Mitsuba.
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Mitsuba max_depth (2 = direct only, -1 = unlimited).
    #[arg(long, default_value_t = -1, allow_negative_numbers = true)]
    pub max_depth: i32,
    /// How the scene is read.
    #[command(flatten)]
    pub read: args::SceneArgs,
    /// A point or spot light besides the environment (Mitsuba `point` / `spot` emitter).
    #[command(flatten)]
    pub light: relight_method::cuts::local::PointLightArgs,
}

/// Run `relight export-mitsuba`.
pub fn export(a: ExportArgs, out: &Out) -> Result<()> {
    let (_, scene) = a.read.load(&a.scene)?;
    std::fs::create_dir_all(&a.out).map_err(|e| anyhow!("{}: {e}", a.out.display()))?;
    let caster = relight_scene::accel::build_default(&scene.mesh);
    let lights = a.light.lights_in(&scene.mesh, caster.as_ref())?;
    let json = mitsuba::export_mitsuba_lit(&scene, &a.out, a.spp, a.max_depth, &lights)
        .map_err(|e| anyhow!("exporting to {}: {e}", a.out.display()))?;
    out.line(format!("wrote {}", json.display()));
    out.line(format!(
        "render it with: python tools/mitsuba_reference.py {} out.exr",
        json.display()
    ));
    out.summary(serde_json::json!({"command": "export-mitsuba", "scene_json": json}));
    Ok(())
}
