//! `relight render`: relight a baked bundle under an environment, from a camera. No baking.

use crate::args::{self, arg_names, refuse_foreign, EnvArgs, Out};
use anyhow::{Context, Result};
use clap::ArgMatches;
use relight_method::cuts::CutsFrameSettings;
use relight_method::hybrid::HybridSettings;
use relight_method::sg::SgFrameSettings;
use relight_method::sh::ShFrameSettings;
use relight_method::vmf::VmfFrameSettings;
use relight_method::{choose, read_any, FrameOptions, FrameSettings, MethodKind};
use relight_render::write_image;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `relight render`.
#[derive(clap::Args)]
pub struct Args {
    /// The baked bundle.
    pub bundle: PathBuf,
    /// Output images (.exr linear, .hdr, .png tone-mapped); repeat for several. All are
    /// checked before rendering and written together.
    #[arg(short, long, required = true)]
    pub out: Vec<PathBuf>,
    /// Method (default: the bundle's: sg for an sg bake, cuts for a cuts bake, vmf for a vmf
    /// bake; an sh bake is shown with hybrid when a bright light stands out of the
    /// environment, else with sh, and with sh when --window is given). The choice is printed.
    #[arg(long, value_enum)]
    pub method: Option<MethodKind>,
    #[command(flatten)]
    pub env: EnvArgs,
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
    /// Tone map for PNG outputs: linear, reinhard or exp, each with an optional parameter
    /// (linear:EXPOSURE, reinhard:EXPOSURE, exp:GAMMA). Default: automatic exposure, the
    /// frame's log-average luminance mapped to the key 0.18 and Reinhard's L / (1 + L)
    /// (Reinhard et al. 2002, eq. 1-3); EXR and HDR outputs stay linear.
    #[arg(long)]
    pub tonemap: Option<String>,
    /// SH order of the lighting (sh) or of the environment's SH part (hybrid); at most the
    /// bake's (default: the bake's).
    #[arg(long, visible_alias = "order")]
    pub sh_order: Option<usize>,
    /// Window of the lighting's SH against ringing (sh): none, hann, lanczos, sloan or
    /// sloan:LAMBDA.
    #[arg(long, default_value = "none")]
    pub window: String,
    /// Hybrid options.
    #[command(flatten)]
    pub hybrid: HybridSettings,
    /// SG options.
    #[command(flatten)]
    pub sg: SgFrameSettings,
    /// Cuts options.
    #[command(flatten)]
    pub cuts: CutsFrameSettings,
    /// vMF options.
    #[command(flatten)]
    pub vmf: VmfFrameSettings,
    /// Render the frame on the GPU (wgpu, Vulkan; sh, hybrid, sg and cuts).
    /// Needs a build with `--features gpu` and a Vulkan driver (Debian: mesa-vulkan-drivers).
    #[arg(long)]
    pub gpu: bool,
}

/// The frame settings of `method` from the options.
fn frame_settings(a: &Args, method: MethodKind) -> Result<FrameSettings> {
    Ok(match method {
        MethodKind::Sh => FrameSettings::Sh(ShFrameSettings {
            window: args::window(&a.window)?,
            sh_order: a.sh_order,
        }),
        MethodKind::Hybrid => FrameSettings::Hybrid(HybridSettings {
            sh_order: a.sh_order,
            ..a.hybrid
        }),
        MethodKind::Sg => FrameSettings::Sg(a.sg),
        MethodKind::Cuts => FrameSettings::Cuts(a.cuts.clone()),
        MethodKind::Vmf => FrameSettings::Vmf(a.vmf),
    })
}

/// Run `relight render`.
pub fn run(a: Args, m: &ArgMatches, out: &Out) -> Result<()> {
    if a.gpu && !cfg!(feature = "gpu") {
        anyhow::bail!(
            "--gpu: this relight was built without the GPU renderer; rebuild it with \
             `cargo build --release --features gpu` (it then needs a Vulkan driver at run \
             time: on Debian `apt-get install mesa-vulkan-drivers libvulkan1`)"
        );
    }
    if let Some(t) = &a.tonemap {
        args::tonemap(t)?;
    }
    let mut inputs = vec![a.bundle.as_path()];
    inputs.extend(a.env.env.as_deref());
    args::check_image_outputs(&a.out, &inputs)?;
    let mut baked = read_any(&a.bundle)?;
    let desc = &baked.scene().desc;
    let env = a.env.build(desc, &a.bundle)?;
    let (method, why) = match a.method {
        Some(method) => (method, None),
        None => {
            let c = choose::choose_frame_method(&baked, &env, args::given(m, "window"))?;
            (c.method, Some(c.why))
        }
    };
    if let Some(why) = &why {
        eprintln!("method: {} ({why})", method.name());
    }
    refuse_foreign(
        m,
        method,
        &[
            (&[MethodKind::Sh], args::named(&["window"])),
            (
                &[MethodKind::Sh, MethodKind::Hybrid],
                args::named(&["sh_order"]),
            ),
            (&[MethodKind::Hybrid], arg_names::<HybridSettings>()),
            (&[MethodKind::Sg], arg_names::<SgFrameSettings>()),
            (&[MethodKind::Cuts], arg_names::<CutsFrameSettings>()),
            (&[MethodKind::Vmf], arg_names::<VmfFrameSettings>()),
        ],
    )?;
    let mut settings = frame_settings(&a, method)?;
    let mut camera = desc.camera;
    if let FrameSettings::Cuts(cuts) = &mut settings {
        relight_method::cuts::apply_material_edits(&mut baked, cuts)
            .with_context(|| a.bundle.display().to_string())?;
    }
    if let Some(c) = &a.camera {
        camera = args::camera(c, &camera)?;
    }
    camera.width = a.width.unwrap_or(camera.width);
    camera.height = a.height.unwrap_or(camera.height);
    camera
        .validate()
        .map_err(|e| anyhow::anyhow!("camera: {e}"))?;
    let opts = FrameOptions {
        supersample: a.supersample,
        background: a.background,
    };
    relight_method::check_frame_options(&opts, &camera)?;
    #[cfg(feature = "gpu")]
    if a.gpu {
        let f = relight_gpu::render_once(&baked, &settings, &a.bundle, &env, &camera, &opts)
            .with_context(|| format!("--gpu --method {}", method.name()))?;
        out.line(&f.line);
        let tm = args::png_tonemap(a.tonemap.as_deref(), &f.output.image, &a.out, out)?;
        write_all(&a.out, &f.output.image, &tm)?;
        for o in &a.out {
            out.line(format!("wrote {}", o.display()));
        }
        out.summary(json!({
            "command": "render",
            "method": method.name(),
            "bundle": a.bundle,
            "outputs": a.out,
            "width": f.output.image.width,
            "height": f.output.image.height,
            "summary": f.line,
            "gpu": {"prepare": f.prepare, "frame": f.output.stats},
        }));
        return Ok(());
    }
    let mut frame = baked
        .frame_of(&settings, &a.bundle)
        .with_context(|| format!("--method {}", method.name()))?;
    let prep = frame.set_environment(&env)?;
    let f = frame.render(&camera, &opts);
    out.line(format!(
        "{}: environment {:.1} ms and per-vertex shading {:.2} ms (once per environment), per-vertex {:.2} ms and raster + per-pixel {:.1} ms per frame",
        frame.summary(),
        prep.environment_ms,
        prep.shade_ms,
        f.times.vertex_ms,
        f.times.pixel_ms
    ));
    let tm = args::png_tonemap(a.tonemap.as_deref(), &f.image, &a.out, out)?;
    write_all(&a.out, &f.image, &tm)?;
    for o in &a.out {
        out.line(format!("wrote {}", o.display()));
    }
    out.summary(json!({
        "command": "render",
        "method": method.name(),
        "method_reason": why,
        "tonemap": tm.to_string(),
        "bundle": a.bundle,
        "outputs": a.out,
        "width": f.image.width,
        "height": f.image.height,
        "summary": frame.summary(),
        "prepare_ms": prep,
        "frame_ms": f.times,
    }));
    Ok(())
}

/// Write `image` to every output, all or none: on a failure, the ones already written are
/// removed.
fn write_all(
    outs: &[PathBuf],
    image: &relight_render::Image,
    tm: &relight_render::tonemap::ToneMap,
) -> Result<()> {
    for (i, o) in outs.iter().enumerate() {
        if let Err(e) = write_image(o, image, tm) {
            outs[..i].iter().for_each(|w| drop(std::fs::remove_file(w)));
            return Err(e.into());
        }
    }
    Ok(())
}
