//! `relight decompose ENV`: split an environment into a low-order SH part and a few cap lights
//! (hybrid thesis 4.3), print the lights and write a picture. The extraction options and their
//! defaults are those of `relight render --method hybrid`.

use crate::args::{self, Out};
use anyhow::{ensure, Context, Result};
use relight_method::hybrid::LightExtraction;
use relight_render::decompose_picture::{auto_tonemap, picture};
use relight_sphere::decompose::{Decomposer, Decomposition};
use relight_sphere::{luminance, sh, Vec3};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `relight decompose`.
#[derive(clap::Args)]
pub struct Args {
    /// Environment map (.hdr / .exr; latlong, vertical cross or angular probe).
    pub env: PathBuf,
    /// Layout (latlong, cube, probe); detected from the aspect ratio when absent.
    #[arg(long)]
    pub layout: Option<String>,
    /// SH order n of the slowly varying part (n^2 coefficients). Default 3 here; `render
    /// --method hybrid` uses the bake's order unless given.
    #[arg(long, visible_alias = "order", default_value_t = 3)]
    pub sh_order: usize,
    /// How lights are extracted (same options and defaults as `render --method hybrid`).
    #[command(flatten)]
    pub lights: LightExtraction,
    /// Keep the lights' energy in the SH part too (the thesis' behaviour, double counting;
    /// `render --method hybrid --thesis`).
    #[arg(long)]
    pub thesis: bool,
    /// Picture (.png): original, SH part, residual (env - SH), SH + lights as caps.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Width of each latlong panel of the picture, pixels.
    #[arg(long, default_value_t = 512)]
    pub panel_width: usize,
    /// Tone map of the picture (`linear[:E]`, `reinhard[:E]`, `exp[:GAMMA]`); default Reinhard
    /// with the exposure that maps the mean radiance to 0.5.
    #[arg(long)]
    pub tonemap: Option<String>,
}

/// Decompose, print the lights, write the picture.
pub fn run(a: Args, out: &Out) -> Result<()> {
    let settings = a.lights.decompose_settings(a.sh_order, !a.thesis)?;
    if let Some(o) = &a.out {
        relight_bundle::output::check_outputs(&[o], &["png"], &[&a.env])?;
        ensure!(
            (16..=8192).contains(&a.panel_width),
            "--panel-width {} is not in 16..=8192",
            a.panel_width
        );
    }
    let tonemap = a.tonemap.as_deref().map(args::tonemap).transpose()?;
    let map = relight_scene::io::load_env(&a.env, args::layout(a.layout.as_deref())?)?;
    let t0 = Instant::now();
    let dec = Decomposer::new(&settings, map.layout(), map.width(), map.height())
        .with_context(|| a.env.display().to_string())?;
    let t1 = Instant::now();
    let d = dec.run(&map).with_context(|| a.env.display().to_string())?;
    let t2 = Instant::now();
    ensure!(
        d.sh.iter().all(|c| c.is_finite()) && d.lights.iter().all(|l| l.power.is_finite()),
        "{}: the decomposition overflows: the map's radiance is beyond f32",
        a.env.display()
    );
    out.line(format!(
        "# decomposition of {} ({:?} {} x {}): SH order {}, cap radius {} deg, threshold {}, {}",
        a.env.display(),
        map.layout(),
        map.width(),
        map.height(),
        a.sh_order,
        a.lights.light_radius,
        a.lights.threshold,
        if a.thesis {
            "caps kept in the SH part (thesis)"
        } else {
            "caps removed from the SH part"
        }
    ));
    let ms = |x: Instant, y: Instant| (y - x).as_secs_f64() * 1e3;
    out.line(format!(
        "# tables {:.1} ms, decomposition {:.2} ms",
        ms(t0, t1),
        ms(t1, t2)
    ));
    report(&a, &d, out);
    if let Some(o) = &a.out {
        let tm = tonemap.unwrap_or_else(|| auto_tonemap(&map));
        let px = picture(&map, &d, a.panel_width, &tm);
        relight_scene::io::write_png_srgb8(o, a.panel_width, px.len() / a.panel_width, &px)?;
        out.line(format!("wrote {}", o.display()));
    }
    Ok(())
}

fn report(a: &Args, d: &Decomposition, out: &Out) {
    out.line("#  i    dir x    dir y    dir z  elev(deg)  azim(deg)   power r      power g      power b    share%  size(deg)");
    let mut lights = vec![];
    for (i, l) in d.lights.iter().enumerate() {
        // Elevation and Mitsuba azimuth (degrees) from the latlong's (u, v).
        let uv = relight_sphere::latlong::dir_to_uv(l.dir);
        let (el, az) = (90.0 - 180.0 * uv.y, 360.0 * uv.x);
        let share = 100.0 * l.luminance / d.total_luminance.max(f32::MIN_POSITIVE);
        out.line(format!(
            "{i:4} {:8.4} {:8.4} {:8.4} {el:10.2} {az:10.2} {:12.5e} {:12.5e} {:12.5e} {share:8.2} {:10.2}",
            l.dir.x, l.dir.y, l.dir.z, l.power.x, l.power.y, l.power.z, l.extent.to_degrees()
        ));
        lights.push(json!({"dir": l.dir.to_array(), "elevation_deg": el, "azimuth_deg": az,
            "power": l.power.to_array(), "share_percent": share, "size_deg": l.extent.to_degrees()}));
    }
    if d.lights.is_empty() {
        out.line("# no lights (nothing stands out of the SH part)");
    }
    out.line("# SH part (real orthonormal, R&H 2001 basis on world x, y, z):  l  m  r g b");
    for l in 0..a.sh_order as i32 {
        for m in -l..=l {
            let v = d.sh[sh::sh_index(l, m)];
            out.line(format!(
                "# {l:3} {m:3} {:12.6} {:12.6} {:12.6}",
                v.x, v.y, v.z
            ));
        }
    }
    let sh0 = d.sh[0] * (4.0 * std::f32::consts::PI).sqrt();
    let power: Vec3 = d.lights.iter().map(|l| l.power).sum();
    out.line(format!(
        "# energy (luminance of int L dw): env {:.5e}, SH part {:.5e}, lights {:.5e}, double counted {:.5e}",
        d.total_luminance,
        luminance(sh0),
        luminance(power),
        luminance(d.double_counted())
    ));
    out.summary(json!({
        "command": "decompose", "env": a.env, "sh_order": a.sh_order, "lights": lights,
        "sh": d.sh.iter().map(|c| c.to_array()).collect::<Vec<_>>(),
        "total_luminance": d.total_luminance, "picture": a.out,
    }));
}
