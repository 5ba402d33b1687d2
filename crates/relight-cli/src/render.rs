//! `relight render`: relight a baked bundle under an environment, from a camera. No baking.

use crate::common::{parse_tonemap, write_image};
use crate::store::ShBake;
use anyhow::{bail, Context, Result};
use glam::Vec3;
use relight_render::raster::{self, RasterOptions};
use relight_render::{shade_sh, Image};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use relight_scene::scene_file::{self, parse_layout};
use relight_sphere::sh::{self, Window};
use relight_sphere::sh_rotate::ShRotation;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `relight render`.
#[derive(clap::Args)]
pub struct Args {
    /// The baked bundle.
    pub bundle: PathBuf,
    /// Method: `sh` (SH PRT of the whole environment), `hybrid` (SH part + cap lights with
    /// shadow maps; options prefixed "Hybrid:") or `sg` (view-dependent glossy PRT, needs a
    /// bundle baked with --method sg; options under "SG render").
    #[arg(long, default_value = "sh")]
    pub method: String,
    #[command(flatten)]
    pub hybrid: crate::hybrid::HybridOpts,
    #[command(flatten)]
    pub sg: crate::sg::SgRenderOpts,
    /// Environment map (default: the one of the baked scene).
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Layout of --env (latlong, cube, probe); detected from the aspect ratio when absent.
    #[arg(long)]
    pub layout: Option<String>,
    /// Rotate the environment about +Y by this many degrees (Mitsuba `to_world` rotate).
    #[arg(long, alias = "rotate-y", allow_hyphen_values = true)]
    pub rotate_env: Option<f32>,
    /// Multiply the environment's radiance.
    #[arg(long)]
    pub env_scale: Option<f32>,
    /// Camera as `ox,oy,oz/tx,ty,tz[/fov]` (look_at with +Y up; fov horizontal, degrees).
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Image width (default: the baked scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the baked scene's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel along each axis (n x n), like Mitsuba's box filter for n > 1.
    #[arg(long, default_value_t = 2)]
    pub supersample: u32,
    /// Draw the environment behind the objects.
    #[arg(long)]
    pub background: bool,
    /// Window the lighting's SH against ringing: none, hann, lanczos, sloan[:LAMBDA].
    #[arg(long, default_value = "none")]
    pub window: String,
    /// Tone map for PNG outputs: linear[:EXPOSURE], reinhard[:EXPOSURE], exp[:GAMMA].
    #[arg(long, default_value = "exp:1")]
    pub tonemap: String,
    /// Output images (.exr linear, .hdr, .png tone-mapped); repeat for several.
    #[arg(short, long, required = true)]
    pub out: Vec<PathBuf>,
}

/// Parse `ox,oy,oz/tx,ty,tz[/fov]` over a base camera.
pub fn parse_camera(s: &str, base: &Camera) -> Result<Camera> {
    let parts: Vec<&str> = s.split('/').collect();
    let vec3 = |p: &str| -> Result<[f32; 3]> {
        let v: Vec<f32> = p
            .split(',')
            .map(|x| x.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("--camera '{s}': '{p}' is not three numbers"))?;
        match v[..] {
            [x, y, z] => Ok([x, y, z]),
            _ => bail!("--camera '{s}': '{p}' is not three numbers"),
        }
    };
    if !(2..=3).contains(&parts.len()) {
        bail!("--camera '{s}': expected ox,oy,oz/tx,ty,tz[/fov]");
    }
    let mut c = *base;
    c.origin = vec3(parts[0])?;
    c.target = vec3(parts[1])?;
    c.up = [0.0, 1.0, 0.0];
    if let Some(f) = parts.get(2) {
        c.fov_deg = f
            .trim()
            .parse()
            .with_context(|| format!("--camera '{s}': fov '{f}' is not a number"))?;
    }
    Ok(c)
}

/// Parse an SH window name.
pub fn parse_window(s: &str) -> Result<Window> {
    Ok(match s.split_once(':') {
        None if s == "none" => Window::None,
        None if s == "hann" => Window::Hann,
        None if s == "lanczos" => Window::Lanczos,
        None if s == "sloan" => Window::Sloan { lambda: 0.001 },
        Some(("sloan", l)) => Window::Sloan {
            lambda: l
                .parse()
                .ok()
                .filter(|x: &f32| *x >= 0.0)
                .with_context(|| format!("--window '{s}': bad lambda"))?,
        },
        _ => bail!("unknown --window '{s}' (none, hann, lanczos, sloan[:LAMBDA])"),
    })
}

/// SH lighting in the world frame: project the map, window, rotate by `world_from_env`, scale.
pub fn world_light(env: &Environment, order: usize, window: Window) -> Vec<Vec3> {
    let mut c = sh::project_env(&env.map, order);
    sh::apply_window(&mut c, order, window);
    let mut c = ShRotation::new(order, env.world_from_env()).apply(&c);
    c.iter_mut().for_each(|v| *v *= env.scale);
    c
}

/// Relight and rasterise a bake under `env` from `camera`.
pub fn relight(
    bake: &ShBake,
    env: &Environment,
    camera: &Camera,
    window: Window,
    supersample: u32,
    background: bool,
) -> (Image, RelightTimes) {
    let t0 = Instant::now();
    let light = world_light(env, bake.transfer.order, window);
    let t1 = Instant::now();
    let albedo = (bake.transfer.channels == 1).then_some(&bake.albedo[..]);
    let radiance = shade_sh::shade(&bake.transfer, albedo, &light);
    let t2 = Instant::now();
    let img = raster::render_with(
        &bake.mesh,
        camera,
        &radiance,
        background.then_some(env),
        &RasterOptions { supersample },
    )
    .image;
    let t3 = Instant::now();
    (
        img,
        RelightTimes {
            project_ms: (t1 - t0).as_secs_f64() * 1e3,
            shade_ms: (t2 - t1).as_secs_f64() * 1e3,
            raster_ms: (t3 - t2).as_secs_f64() * 1e3,
        },
    )
}

/// Where the time of one relit frame goes.
pub struct RelightTimes {
    /// Environment projection to SH (only when the environment changes).
    pub project_ms: f64,
    /// Per-vertex dot products (every frame).
    pub shade_ms: f64,
    /// Rasterisation.
    pub raster_ms: f64,
}

/// Run `relight render`.
pub fn run(a: Args) -> Result<()> {
    let tm = parse_tonemap(&a.tonemap)?;
    let window = parse_window(&a.window)?;
    if a.method == "sg" {
        let b = crate::store::SgBundle::read(&a.bundle)?;
        let (env, camera) = frame_setup(&a, &b.scene)?;
        let (img, t) =
            crate::sg::relight_sg(&b, &env, &camera, &a.sg, a.supersample, a.background)?;
        println!(
            "SG: {} vertices, {} lobes per vertex and view, diffuse SH order {}: prefilter {:.1} ms (once per environment), per-vertex {:.2} ms, raster + per-pixel {:.1} ms",
            b.mesh.vertex_count(),
            b.bake.direct.lobe_count + b.bake.indirect.as_ref().map_or(0, |l| l.lobe_count),
            b.bake.diffuse.order,
            t.prefilter_ms,
            t.frame.vertex_ms,
            t.frame.pixel_ms
        );
        return write_all(&a.out, &img, &tm);
    }
    let bake = ShBake::read(&a.bundle)?;
    let (env, camera) = frame_setup(&a, &bake.scene)?;
    let img = match a.method.as_str() {
        "sh" => {
            let (img, t) = relight(&bake, &env, &camera, window, a.supersample, a.background);
            println!(
                "SH order {}, {} vertices: projection {:.1} ms (once per environment), relight {:.2} ms, raster {:.1} ms",
                bake.transfer.order, bake.transfer.vertex_count, t.project_ms, t.shade_ms, t.raster_ms
            );
            img
        }
        "hybrid" => {
            let (img, t, dec) = crate::hybrid::relight_hybrid(
                &bake,
                &env,
                &camera,
                &a.hybrid,
                a.supersample,
                a.background,
            )?;
            println!(
                "hybrid: {} lights + SH order {}: decomposition {:.1} ms (once per environment), SH relight {:.2} ms, shadow maps + shading {:.1} ms",
                dec.lights.len(),
                a.hybrid.sh_order.unwrap_or(bake.transfer.order),
                t.decompose_ms,
                t.shade_ms,
                t.render_ms
            );
            img
        }
        m => bail!("unknown --method '{m}' (sh, hybrid, sg)"),
    };
    write_all(&a.out, &img, &tm)
}

/// The environment and camera of a frame: the baked scene's, overridden by the flags.
fn frame_setup(a: &Args, scene: &scene_file::SceneDesc) -> Result<(Environment, Camera)> {
    let mut env = match &a.env {
        Some(p) => {
            let layout = match &a.layout {
                Some(l) => {
                    Some(parse_layout(l).with_context(|| format!("unknown --layout '{l}'"))?)
                }
                None => None,
            };
            Environment::new(relight_scene::io::load_env(p, layout)?)
        }
        None => scene_file::build_env(&scene.environment).with_context(|| {
            format!(
                "{}: loading the baked scene's environment (pass --env to use another)",
                a.bundle.display()
            )
        })?,
    };
    if let Some(r) = a.rotate_env {
        env.rotate_y_deg = r;
    }
    if let Some(s) = a.env_scale {
        env.scale = s;
    }
    let mut camera = scene.camera;
    if let Some(c) = &a.camera {
        camera = parse_camera(c, &camera)?;
    }
    camera.width = a.width.unwrap_or(camera.width);
    camera.height = a.height.unwrap_or(camera.height);
    camera
        .validate()
        .map_err(|e| anyhow::anyhow!("camera: {e}"))?;
    if a.supersample == 0 || a.supersample > 16 {
        bail!("--supersample {} is not in 1..=16", a.supersample);
    }
    Ok((env, camera))
}

/// Write `img` to every output.
fn write_all(out: &[PathBuf], img: &Image, tm: &relight_render::tonemap::ToneMap) -> Result<()> {
    for o in out {
        write_image(o, img, tm)?;
        println!("wrote {}", o.display());
    }
    Ok(())
}
