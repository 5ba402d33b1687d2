//! `relight decompose ENV`: split an environment into a low-order SH part and a few cap lights
//! (hybrid thesis 4.3, `relight_sphere::decompose`), print the lights and write a picture.

use crate::common::{ext_of, parse_tonemap};
use anyhow::{bail, Context, Result};
use relight_render::text::draw_label;
use relight_render::tonemap::ToneMap;
use relight_scene::scene_file::parse_layout;
use relight_sphere::decompose::{DecomposeSettings, Decomposer, Decomposition};
use relight_sphere::{latlong, luminance, sh, EnvMap, Vec2, Vec3};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `relight decompose`.
#[derive(clap::Args)]
pub struct Args {
    /// Environment map (.hdr / .exr; latlong, vertical cross, stacked cube faces or probe).
    pub env: PathBuf,
    /// Layout (latlong, cube, probe); detected from the aspect ratio when absent.
    #[arg(long)]
    pub layout: Option<String>,
    /// SH order n of the slowly varying part (n^2 coefficients).
    #[arg(long, default_value_t = 3)]
    pub sh_order: usize,
    /// Elbow threshold (thesis Fig. 4.5): keep a light while its luminance exceeds this
    /// fraction of the running total.
    #[arg(long, default_value_t = 0.05)]
    pub threshold: f32,
    /// Cap radius R of every light, degrees.
    #[arg(long, default_value_t = 5.0)]
    pub light_radius: f32,
    /// At most this many lights.
    #[arg(long, default_value_t = 8)]
    pub max_lights: usize,
    /// Keep the lights' energy in the SH part too (the thesis' behaviour, double counting).
    #[arg(long)]
    pub no_remove_caps: bool,
    /// Picture (.png): original, SH part, residual (env - SH), SH + lights as caps.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Width of each latlong panel of the picture, pixels.
    #[arg(long, default_value_t = 512)]
    pub panel_width: usize,
    /// Tone map of the picture (`linear[:E]`, `reinhard[:E]`, `exp[:GAMMA]`); default Reinhard
    /// with the exposure that maps the mean radiance to 0.5.
    #[arg(long)]
    pub tonemap: Option<String>,
}

/// Decompose, print the lights, write the picture.
pub fn run(a: Args) -> Result<()> {
    let settings = DecomposeSettings {
        sh_order: a.sh_order,
        threshold: a.threshold,
        light_radius_deg: a.light_radius,
        max_lights: a.max_lights,
        remove_caps: !a.no_remove_caps,
        ..Default::default()
    };
    settings
        .validate()
        .map_err(|e| anyhow::anyhow!("invalid option: {e}"))?;
    if let Some(o) = &a.output {
        if ext_of(o) != "png" {
            bail!("{}: the picture must be a .png", o.display());
        }
        if !(16..=8192).contains(&a.panel_width) {
            bail!("--panel-width {} is not in 16..=8192", a.panel_width);
        }
    }
    let tonemap = a.tonemap.as_deref().map(parse_tonemap).transpose()?;
    let layout = match &a.layout {
        Some(l) => Some(
            parse_layout(l)
                .with_context(|| format!("unknown layout '{l}' (latlong, cube, probe)"))?,
        ),
        None => None,
    };
    let map = relight_scene::io::load_env(&a.env, layout)?;
    let t0 = Instant::now();
    let dec = Decomposer::new(&settings, map.layout(), map.width(), map.height())
        .with_context(|| format!("{}", a.env.display()))?;
    let t1 = Instant::now();
    let d = dec
        .run(&map)
        .with_context(|| format!("{}", a.env.display()))?;
    let t2 = Instant::now();
    print_report(
        &a,
        &map,
        &d,
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
    );
    if let Some(out) = &a.output {
        let tm = tonemap.unwrap_or_else(|| auto_tonemap(&map));
        let (w, px) = picture(&map, &d, a.panel_width, &tm);
        relight_scene::io::write_png_srgb8(out, w, px.len() / w, &px)?;
        println!("wrote {}", out.display());
    }
    Ok(())
}

/// Elevation above the horizon and Mitsuba azimuth `phi = atan2(x, -z)`, degrees.
fn elevation_azimuth(d: Vec3) -> (f32, f32) {
    let el = d.y.clamp(-1.0, 1.0).asin().to_degrees();
    let az = d.x.atan2(-d.z).to_degrees().rem_euclid(360.0);
    (el, az)
}

fn print_report(a: &Args, map: &EnvMap, d: &Decomposition, build_s: f64, run_s: f64) {
    println!(
        "# decomposition of {} ({:?} {} x {}): SH order {}, cap radius {} deg, threshold {}, {}",
        a.env.display(),
        map.layout(),
        map.width(),
        map.height(),
        a.sh_order,
        a.light_radius,
        a.threshold,
        if a.no_remove_caps {
            "caps kept in the SH part (thesis)"
        } else {
            "caps removed from the SH part"
        }
    );
    println!(
        "# tables {:.1} ms, decomposition {:.2} ms",
        build_s * 1e3,
        run_s * 1e3
    );
    println!(
        "#  i    dir x    dir y    dir z  elev(deg)  azim(deg)   power r      power g      power b    share%  size(deg)"
    );
    for (i, l) in d.lights.iter().enumerate() {
        let (el, az) = elevation_azimuth(l.dir);
        println!(
            "{i:4} {:8.4} {:8.4} {:8.4} {el:10.2} {az:10.2} {:12.5e} {:12.5e} {:12.5e} {:8.2} {:10.2}",
            l.dir.x,
            l.dir.y,
            l.dir.z,
            l.power.x,
            l.power.y,
            l.power.z,
            100.0 * l.luminance / d.total_luminance.max(f32::MIN_POSITIVE),
            l.extent.to_degrees()
        );
    }
    if d.lights.is_empty() {
        println!("# no lights (nothing stands out of the SH part)");
    }
    println!("# SH part (real orthonormal, R&H 2001 basis on world x, y, z):  l  m  r g b");
    for l in 0..a.sh_order as i32 {
        for m in -l..=l {
            let v = d.sh[sh::sh_index(l, m)];
            println!("# {l:3} {m:3} {:12.6} {:12.6} {:12.6}", v.x, v.y, v.z);
        }
    }
    let sh0 = d.sh[0] * (4.0 * std::f32::consts::PI).sqrt();
    let lights: Vec3 = d.lights.iter().map(|l| l.power).sum();
    println!(
        "# energy (luminance of int L dw): env {:.5e}, SH part {:.5e}, lights {:.5e}, double counted {:.5e}",
        d.total_luminance,
        luminance(sh0),
        luminance(lights),
        luminance(d.double_counted())
    );
}

/// Reinhard with the exposure that maps the map's mean luminance to 0.5.
fn auto_tonemap(map: &EnvMap) -> ToneMap {
    let mean = map.average_luminance();
    ToneMap::Reinhard {
        exposure: if mean > 0.0 { 1.0 / mean } else { 1.0 },
    }
}

/// Four latlong panels stacked: original, SH part, residual (env - SH, negative parts
/// black), SH + lights as caps with their outlines. Returns the width and the pixels.
fn picture(map: &EnvMap, d: &Decomposition, w: usize, tm: &ToneMap) -> (usize, Vec<[u8; 3]>) {
    let h = w / 2;
    let mut px = vec![[0u8; 3]; w * 4 * h];
    let pixel_angle = std::f32::consts::PI / h as f32;
    let labels = [
        "environment",
        "SH part",
        "residual (environment - SH)",
        "SH part + lights",
    ];
    for j in 0..h {
        for i in 0..w {
            let uv = Vec2::new((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
            let dir = latlong::uv_to_dir(uv);
            let env = map.eval(dir);
            let shv = sh::eval_rgb(&d.sh, dir);
            let panels = [env, shv, env - shv, d.radiance(dir)];
            for (k, v) in panels.iter().enumerate() {
                px[(k * h + j) * w + i] = tm.pixel_srgb8(*v);
            }
            // Cap outlines and centres on the last panel.
            for l in &d.lights {
                let a = l.dir.dot(dir).clamp(-1.0, 1.0).acos();
                if (a - l.cap_radius).abs() < pixel_angle || a < 1.5 * pixel_angle {
                    px[(3 * h + j) * w + i] = [255, 0, 255];
                }
            }
        }
    }
    for (k, text) in labels.iter().enumerate() {
        draw_label(&mut px, w, 4, k * h + 4, 1 + w / 512, text);
    }
    (w, px)
}
