//! `relight eval --method hybrid`: the thesis' experiment (chapter 5, Table 5.1) reproduced.
//!
//! A scene (by default the Utah teapot on a small table, `examples/teapot_table.json`) is lit
//! in turn by each environment, with diffuse materials and direct lighting only (Mitsuba
//! `max_depth = 2`, shadowed SH transfer), and rendered four ways:
//! * `mitsuba`: Mitsuba 3, two seeds (their mean is the reference, their difference its noise);
//! * `sh`: SH PRT of the whole environment (order `--order`);
//! * `hybrid-thesis`: the thesis' hybrid: SH part keeps the lights' energy, point lights with
//!   hard PCF shadow maps;
//! * `hybrid`: relight's hybrid: caps removed before the SH projection, area lights with soft
//!   shadows sized to the cap and the exact cosine over the cap.
//!
//! Metrics over the pixels fully covered by geometry: Table 5.1's mean and standard deviation
//! of the absolute per-pixel luminance error, and the relative RMSE.

use crate::common::write_image;
use crate::eval::{mask_and_reference, stem};
use crate::hybrid::{relight_hybrid, HybridOpts};
use crate::render::relight;
use anyhow::{anyhow, Context, Result};
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_render::compare::{self, Metrics};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::scene_file::{EnvDesc, SceneDesc};
use relight_sphere::sh::Window;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One environment's result.
#[derive(serde::Serialize)]
pub struct HybridRow {
    /// Environment file stem.
    pub env: String,
    /// Lights extracted (relight's hybrid).
    pub lights: usize,
    /// Metrics of each method against Mitsuba: `[sh, hybrid-thesis, hybrid]`.
    pub rel_rmse: [f64; 3],
    /// Table 5.1 mean absolute luminance error, same order.
    pub mean_abs_lum_err: [f64; 3],
    /// Table 5.1 standard deviation, same order.
    pub std_abs_lum_err: [f64; 3],
    /// Relative RMSE of the reference itself.
    pub reference_noise: f64,
}

/// Method names in the order of [`HybridRow`]'s arrays.
pub const METHODS: [&str; 3] = ["sh", "hybrid-thesis", "hybrid"];

/// Run the experiment; returns the rows (also written as results.md / results.json / report.html).
#[allow(clippy::too_many_arguments)]
pub fn run(
    scene_path: &Path,
    envs: &[PathBuf],
    order: usize,
    samples: u32,
    spp: u32,
    width: Option<u32>,
    opts: &HybridOpts,
    out: &Path,
) -> Result<Vec<HybridRow>> {
    let python = relight_render::mitsuba::mitsuba_python().map_err(|e| {
        anyhow!("Mitsuba 3 is needed for `relight eval` (run scripts/setup.sh): {e}")
    })?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut base = SceneDesc::read(scene_path)?;
    if let Some(w) = width {
        base.camera.height =
            (w as u64 * base.camera.height as u64 / base.camera.width as u64).max(1) as u32;
        base.camera.width = w;
    }
    // The bake does not depend on the environment: bake once.
    let scene0 = base.build(scene_path)?;
    eprintln!(
        "eval hybrid: baking order {order} ({} vertices)",
        scene0.mesh.vertex_count()
    );
    let settings = ShBakeSettings {
        order,
        samples,
        seed: 1,
        kind: ShTransferKind::Shadowed,
        threads: None,
        progress: true,
    };
    let baked = crate::bake::bake_scene(
        &base,
        &scene0,
        &settings,
        crate::bake::parse_backend(None)?,
        false,
        scene_path,
    )?;
    let thesis_opts = HybridOpts {
        thesis: true,
        ..opts.clone()
    };
    let mut rows = Vec::new();
    for env_path in envs {
        let mut desc = base.clone();
        desc.environment = EnvDesc::File {
            path: env_path.clone(),
            layout: None,
            scale: None,
            rotate_y_deg: None,
        };
        let env_name = stem(env_path);
        let scene = desc.build(scene_path)?;
        let dir = out.join(&env_name);
        let (reference, mask, noise) = mask_and_reference(&python, &scene, &dir, spp)?;
        let (sh_img, _) = relight(&baked, &scene.env, &scene.camera, Window::None, 4, true);
        let (thesis_img, _, _) =
            relight_hybrid(&baked, &scene.env, &scene.camera, &thesis_opts, 4, true)?;
        let (hyb_img, _, dec) = relight_hybrid(&baked, &scene.env, &scene.camera, opts, 4, true)?;
        let imgs: [&Image; 3] = [&sh_img, &thesis_img, &hyb_img];
        let m: Vec<Metrics> = imgs
            .iter()
            .map(|i| compare::metrics(i, &reference, Some(&mask)))
            .collect();
        let mean_y = {
            let (s, n) = reference
                .pixels
                .iter()
                .zip(&mask)
                .filter(|(_, &k)| k)
                .fold((0.0f64, 0usize), |(s, n), (c, _)| {
                    (s + compare::luminance(*c) as f64, n + 1)
                });
            s / n.max(1) as f64
        };
        let tm = ToneMap::Exponential {
            gamma: (std::f64::consts::LN_2 / mean_y.max(1e-9)) as f32,
        };
        write_image(&dir.join("mitsuba.png"), &reference, &tm)?;
        for (name, img) in METHODS.iter().zip(imgs) {
            write_image(&dir.join(format!("{name}.png")), img, &tm)?;
            write_image(&dir.join(format!("{name}.exr")), img, &tm)?;
            // One heat-map scale for all methods of this environment, so they compare.
            let scale = 0.25 * mean_y as f32;
            relight_scene::io::image::write_png_srgb8(
                &dir.join(format!("{name}_error.png")),
                img.width,
                img.height,
                &compare::heatmap_with_scale(img, &reference, scale),
            )?;
        }
        eprintln!(
            "eval hybrid: {env_name}: {} lights; mean |dY| sh {:.4}, thesis {:.4}, hybrid {:.4}; relRMSE {:.1} / {:.1} / {:.1} %",
            dec.lights.len(),
            m[0].mean_abs_lum_err,
            m[1].mean_abs_lum_err,
            m[2].mean_abs_lum_err,
            100.0 * m[0].rel_rmse,
            100.0 * m[1].rel_rmse,
            100.0 * m[2].rel_rmse
        );
        rows.push(HybridRow {
            env: env_name,
            lights: dec.lights.len(),
            rel_rmse: [m[0].rel_rmse, m[1].rel_rmse, m[2].rel_rmse],
            mean_abs_lum_err: [
                m[0].mean_abs_lum_err,
                m[1].mean_abs_lum_err,
                m[2].mean_abs_lum_err,
            ],
            std_abs_lum_err: [
                m[0].std_abs_lum_err,
                m[1].std_abs_lum_err,
                m[2].std_abs_lum_err,
            ],
            reference_noise: noise,
        });
    }
    write_outputs(out, scene_path, order, samples, spp, &rows)?;
    Ok(rows)
}

fn write_outputs(
    out: &Path,
    scene: &Path,
    order: usize,
    samples: u32,
    spp: u32,
    rows: &[HybridRow],
) -> Result<()> {
    let mut md = String::from(
        "| environment | lights | mean abs. lum. error: SH / thesis hybrid / relight hybrid | std: SH / thesis / relight | relative RMSE: SH / thesis / relight | hybrid vs SH (mean error) | reference noise |\n|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {:.4} / {:.4} / {:.4} | {:.4} / {:.4} / {:.4} | {:.1} / {:.1} / {:.1} % | {:.2}x better | {:.1} % |",
            r.env,
            r.lights,
            r.mean_abs_lum_err[0], r.mean_abs_lum_err[1], r.mean_abs_lum_err[2],
            r.std_abs_lum_err[0], r.std_abs_lum_err[1], r.std_abs_lum_err[2],
            100.0 * r.rel_rmse[0], 100.0 * r.rel_rmse[1], 100.0 * r.rel_rmse[2],
            r.mean_abs_lum_err[0] / r.mean_abs_lum_err[2],
            100.0 * r.reference_noise
        );
    }
    println!("{md}");
    relight_bundle::write_atomic(&out.join("results.md"), md.as_bytes())?;
    relight_bundle::write_atomic(
        &out.join("results.json"),
        serde_json::to_string_pretty(rows)?.as_bytes(),
    )?;
    let mut h = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>relight eval: hybrid</title>\
<style>body{{font-family:sans-serif;margin:2em}}td,th{{padding:3px 8px}}img{{margin:2px}}</style></head><body>\
<h1>Hybrid (thesis 4.3-4.4) vs SH PRT vs Mitsuba 3</h1><p>Scene {}, SH order {order}, shadowed transfer with {samples} \
directions per vertex, direct lighting (Mitsuba max_depth 2, {spp} spp x 2 seeds). Metrics over pixels fully covered by \
geometry; error maps share one scale per environment (25 % of the reference's mean luminance = full scale).</p>{}",
        scene.display(),
        md_to_html(&md)
    );
    for r in rows {
        let _ = write!(h, "<h2>{}</h2><p>", r.env);
        for name in ["mitsuba"].iter().chain(METHODS.iter()) {
            let _ = write!(h, "<figure style=\"display:inline-block\"><img src=\"{}/{name}.png\"><figcaption>{name}</figcaption></figure>", r.env);
        }
        h.push_str("<br>");
        for name in METHODS {
            let _ = write!(h, "<figure style=\"display:inline-block\"><img src=\"{}/{name}_error.png\"><figcaption>{name} error</figcaption></figure>", r.env);
        }
        h.push_str("</p>");
    }
    h.push_str("</body></html>");
    relight_bundle::write_atomic(&out.join("report.html"), h.as_bytes())?;
    println!(
        "wrote {} and {}",
        out.join("results.md").display(),
        out.join("report.html").display()
    );
    Ok(())
}

/// A markdown table as an HTML table.
fn md_to_html(md: &str) -> String {
    let mut h = String::from("<table border=\"1\" style=\"border-collapse:collapse\">");
    for (i, line) in md.lines().enumerate() {
        if i == 1 {
            continue;
        }
        let tag = if i == 0 { "th" } else { "td" };
        h.push_str("<tr>");
        for cell in line.trim_matches('|').split('|') {
            let _ = write!(h, "<{tag}>{}</{tag}>", cell.trim());
        }
        h.push_str("</tr>");
    }
    h.push_str("</table>");
    h
}
