//! `relight eval --method hybrid`: the thesis' experiment (chapter 5, Table 5.1) reproduced.
//!
//! A scene (by default the Utah teapot on a small table, `examples/teapot_table.json`) is lit
//! in turn by each environment, with diffuse materials and direct lighting only (Mitsuba
//! `max_depth = 2`, shadowed SH transfer), and rendered four ways:
//! * `mitsuba`: Mitsuba 3, two seeds (their mean is the reference, their difference its noise);
//! * `sh`: SH PRT of the whole environment (order `--order`);
//! * `hybrid-thesis`: the thesis' hybrid: SH part keeps the lights' energy, point lights with
//!   hard PCF shadow maps;
//! * `hybrid`: relight's hybrid: caps removed before the SH projection, area lights the size of
//!   the radiance each cap removed, with soft shadows and the exact cosine over that disc.
//!
//! Metrics over the pixels fully covered by geometry: Table 5.1's mean and standard deviation
//! of the absolute per-pixel luminance error, and the relative RMSE.
//!
//! Error budget (docs/RESULTS.md section 5): every row also carries the reference's own noise
//! *in the metric*, `mean |Y(seed 1) - Y(seed 2)| / 2`. For Gaussian pixel noise of standard
//! deviation `s` per seed this is `E|Y_mean - Y_true| = (s / sqrt 2) sqrt(2 / pi)`, exactly the
//! mean absolute luminance error a perfect renderer would score against the two seeds' mean.
//! `--orders` evaluates several SH orders from one bake (the SH basis is hierarchical: the
//! first `n^2` coefficients of an order-`N` transfer are the order-`n` transfer), and
//! `--reference-spp` renders a second, better reference (two more seeds) against which every
//! method is measured again, with the first reference's own error against it.

use crate::common::write_image;
use crate::eval::stem;
use crate::hybrid::{relight_hybrid, HybridOpts};
use crate::render::relight;
use crate::store::ShBake;
use anyhow::{anyhow, bail, Context, Result};
use relight_bake::sh::{ShBakeSettings, ShTransfer, ShTransferKind};
use relight_render::compare::{self, Metrics};
use relight_render::mitsuba;
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::scene_file::{EnvDesc, SceneDesc};
use relight_sphere::sh::{sh_count, Window};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options of `relight eval --method hybrid` beyond the hybrid method's own.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct EvalHybridOpts {
    /// Hybrid eval: SH orders to evaluate, comma-separated (default: `--order`); one bake at
    /// the highest, truncated to each.
    #[arg(long, value_delimiter = ',')]
    pub orders: Vec<usize>,
    /// Hybrid eval: also render a better Mitsuba reference with this many spp per seed (two
    /// seeds, 3 and 4) and report every method's error against it.
    #[arg(long)]
    pub reference_spp: Option<u32>,
}

/// Errors against the better reference (`--reference-spp`).
#[derive(serde::Serialize, Clone, Debug)]
pub struct BetterReference {
    /// Its samples per pixel per seed.
    pub spp: u32,
    /// Table 5.1 mean absolute luminance error of `[sh, hybrid-thesis, hybrid]` against it.
    pub mean_abs_lum_err: [f64; 3],
    /// Relative RMSE, same order.
    pub rel_rmse: [f64; 3],
    /// Its own noise in the metric, `mean |Y(s3) - Y(s4)| / 2`.
    pub lum_noise: f64,
    /// Mean absolute luminance error of the `--spp` reference against it (the first
    /// reference's measured noise plus the better one's).
    pub reference_err: f64,
}

/// One environment's result at one SH order.
#[derive(serde::Serialize)]
pub struct HybridRow {
    /// Environment file stem.
    pub env: String,
    /// SH order of the bake (and of the hybrid's SH part unless `--sh-order`).
    pub order: usize,
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
    /// The reference's noise in Table 5.1's metric, `mean |Y(s1) - Y(s2)| / 2` (module docs):
    /// the mean error a noiseless renderer would score.
    pub lum_noise: f64,
    /// Errors against the better reference, when one was rendered.
    pub better: Option<BetterReference>,
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
    eval: &EvalHybridOpts,
    out: &Path,
) -> Result<Vec<HybridRow>> {
    let python = relight_render::mitsuba::mitsuba_python().map_err(|e| {
        anyhow!("Mitsuba 3 is needed for `relight eval` (run scripts/setup.sh): {e}")
    })?;
    let orders = if eval.orders.is_empty() {
        vec![order]
    } else {
        eval.orders.clone()
    };
    let max_order = *orders.iter().max().expect("non-empty");
    if orders.iter().any(|&o| o < 1) || max_order > relight_sphere::sh::MAX_ORDER {
        bail!(
            "--orders {orders:?} must be in 1..={}",
            relight_sphere::sh::MAX_ORDER
        );
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut base = SceneDesc::read(scene_path)?;
    if let Some(w) = width {
        base.camera.height =
            (w as u64 * base.camera.height as u64 / base.camera.width as u64).max(1) as u32;
        base.camera.width = w;
    }
    // The bake does not depend on the environment: bake once, at the highest order.
    let scene0 = base.build(scene_path)?;
    eprintln!(
        "eval hybrid: baking order {max_order} ({} vertices)",
        scene0.mesh.vertex_count()
    );
    let settings = ShBakeSettings {
        order: max_order,
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
        let (seeds, mask) = reference_seeds(&python, &scene, &dir, "mitsuba", spp, &[1, 2])?;
        let reference = mean_image(&seeds[0], &seeds[1]);
        let noise = compare::metrics(&seeds[0], &seeds[1], Some(&mask)).rel_rmse / 2.0;
        let lum_noise = compare::metrics(&seeds[0], &seeds[1], Some(&mask)).mean_abs_lum_err / 2.0;
        let better_ref = match eval.reference_spp {
            Some(hq) => {
                let (s, _) = reference_seeds(&python, &scene, &dir, "mitsuba_hq", hq, &[3, 4])?;
                let hq_noise = compare::metrics(&s[0], &s[1], Some(&mask)).mean_abs_lum_err / 2.0;
                Some((hq, mean_image(&s[0], &s[1]), hq_noise))
            }
            None => None,
        };
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
        write_image(&dir.join("mitsuba.exr"), &reference, &tm)?;
        // The compared pixels, white (for analysing the EXRs outside relight).
        let mask_px: Vec<[u8; 3]> = mask
            .iter()
            .map(|&k| [if k { 255u8 } else { 0 }; 3])
            .collect();
        relight_scene::io::image::write_png_srgb8(
            &dir.join("mask.png"),
            reference.width,
            reference.height,
            &mask_px,
        )?;
        if let Some((_, img, _)) = &better_ref {
            write_image(&dir.join("mitsuba_hq.png"), img, &tm)?;
            write_image(&dir.join("mitsuba_hq.exr"), img, &tm)?;
        }
        for &o in &orders {
            let b = truncated(&baked, o);
            let (sh_img, _) = relight(&b, &scene.env, &scene.camera, Window::None, 4, true);
            let (thesis_img, _, _) =
                relight_hybrid(&b, &scene.env, &scene.camera, &thesis_opts, 4, true)?;
            let (hyb_img, _, dec) = relight_hybrid(&b, &scene.env, &scene.camera, opts, 4, true)?;
            let imgs: [&Image; 3] = [&sh_img, &thesis_img, &hyb_img];
            let m: Vec<Metrics> = imgs
                .iter()
                .map(|i| compare::metrics(i, &reference, Some(&mask)))
                .collect();
            // Image names carry the order only when several are evaluated.
            let suffix = if orders.len() > 1 {
                format!("_order{o}")
            } else {
                String::new()
            };
            for (name, img) in METHODS.iter().zip(imgs) {
                write_image(&dir.join(format!("{name}{suffix}.png")), img, &tm)?;
                write_image(&dir.join(format!("{name}{suffix}.exr")), img, &tm)?;
                // One heat-map scale for all methods of this environment, so they compare.
                let scale = 0.25 * mean_y as f32;
                relight_scene::io::image::write_png_srgb8(
                    &dir.join(format!("{name}{suffix}_error.png")),
                    img.width,
                    img.height,
                    &compare::heatmap_with_scale(img, &reference, scale),
                )?;
            }
            let better = better_ref.as_ref().map(|(hq, img, hq_noise)| {
                let mb: Vec<Metrics> = imgs
                    .iter()
                    .map(|i| compare::metrics(i, img, Some(&mask)))
                    .collect();
                BetterReference {
                    spp: *hq,
                    mean_abs_lum_err: [
                        mb[0].mean_abs_lum_err,
                        mb[1].mean_abs_lum_err,
                        mb[2].mean_abs_lum_err,
                    ],
                    rel_rmse: [mb[0].rel_rmse, mb[1].rel_rmse, mb[2].rel_rmse],
                    lum_noise: *hq_noise,
                    reference_err: compare::metrics(&reference, img, Some(&mask)).mean_abs_lum_err,
                }
            });
            eprintln!(
                "eval hybrid: {env_name} order {o}: {} lights; mean |dY| sh {:.4}, thesis {:.4}, hybrid {:.4} (reference noise {:.4}); relRMSE {:.1} / {:.1} / {:.1} %",
                dec.lights.len(),
                m[0].mean_abs_lum_err,
                m[1].mean_abs_lum_err,
                m[2].mean_abs_lum_err,
                lum_noise,
                100.0 * m[0].rel_rmse,
                100.0 * m[1].rel_rmse,
                100.0 * m[2].rel_rmse
            );
            if let Some(b) = &better {
                eprintln!(
                    "eval hybrid: {env_name} order {o}: against {} spp x 2: mean |dY| sh {:.4}, thesis {:.4}, hybrid {:.4} (its noise {:.4}; {spp}-spp reference's error {:.4})",
                    b.spp, b.mean_abs_lum_err[0], b.mean_abs_lum_err[1], b.mean_abs_lum_err[2], b.lum_noise, b.reference_err
                );
            }
            rows.push(HybridRow {
                env: env_name.clone(),
                order: o,
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
                lum_noise,
                better,
            });
        }
    }
    write_outputs(out, scene_path, &orders, samples, spp, &rows)?;
    Ok(rows)
}

/// Mitsuba 3 renders of `scene` (max_depth 2, `spp` per seed) exported under `dir/name`, one
/// image per seed, and the mask of pixels fully covered by geometry (4 x 4 supersampled
/// coverage, like Mitsuba's box filter).
fn reference_seeds(
    python: &Path,
    scene: &relight_scene::scene::Scene,
    dir: &Path,
    name: &str,
    spp: u32,
    seeds: &[u32],
) -> Result<(Vec<Image>, Vec<bool>)> {
    let before = folder_contents(&dir.join(name));
    let json = mitsuba::export_mitsuba(scene, &dir.join(name), spp, 2)
        .map_err(|e| anyhow!("{}: {e}", dir.display()))?;
    let seed_path = |s: u32| dir.join(format!("{name}_s{s}.exr"));
    // A previous run's renders are reused when the exported scene (geometry, environment,
    // camera, spp: every file Mitsuba reads) is byte-identical: Mitsuba is deterministic for
    // a given seed, so re-rendering would give the same images.
    let reuse = !before.is_empty()
        && before == folder_contents(&dir.join(name))
        && seeds.iter().all(|&s| seed_path(s).is_file());
    let imgs = if reuse {
        eprintln!(
            "eval: {}: reusing the {spp}-spp renders of the identical exported scene",
            dir.display()
        );
        seeds
            .iter()
            .map(|&s| {
                let p = seed_path(s);
                let (w, h, px) = relight_scene::io::image::read_exr(&p)?;
                Ok(Image {
                    width: w,
                    height: h,
                    pixels: px,
                })
            })
            .collect::<Result<Vec<Image>>>()?
    } else {
        eprintln!(
            "eval: {}: Mitsuba 3, {spp} spp x {} seeds",
            dir.display(),
            seeds.len()
        );
        let (imgs, report) = mitsuba::render_mitsuba(python, &json, &dir.join(name), seeds, None)
            .map_err(|e| anyhow!("{}: {e}", dir.display()))?;
        eprintln!("eval: {}: {report}", dir.display());
        imgs
    };
    Ok((imgs, crate::eval::coverage_mask(scene)))
}

/// Every file of a folder (not recursive) by name; empty when it does not exist.
fn folder_contents(dir: &Path) -> std::collections::BTreeMap<std::ffi::OsString, Vec<u8>> {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().is_file())
        .filter_map(|e| Some((e.file_name(), std::fs::read(e.path()).ok()?)))
        .collect()
}

/// The per-pixel mean of two images of one size.
fn mean_image(a: &Image, b: &Image) -> Image {
    Image {
        width: a.width,
        height: a.height,
        pixels: a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| (*x + *y) * 0.5)
            .collect(),
    }
}

/// `bake` truncated to SH order `order` (the first `order^2` coefficients per vertex).
fn truncated(bake: &ShBake, order: usize) -> ShBake {
    let t = &bake.transfer;
    let (n_old, n_new, c) = (sh_count(t.order), sh_count(order), t.channels);
    let mut data = Vec::with_capacity(t.vertex_count * n_new * c);
    for v in 0..t.vertex_count {
        data.extend_from_slice(&t.data[v * n_old * c..(v * n_old + n_new) * c]);
    }
    let mut settings = bake.settings.clone();
    settings.order = order;
    ShBake {
        scene: bake.scene.clone(),
        mesh: bake.mesh.clone(),
        materials: bake.materials.clone(),
        albedo: bake.albedo.clone(),
        transfer: ShTransfer {
            order,
            kind: t.kind,
            vertex_count: t.vertex_count,
            channels: c,
            data,
        },
        settings,
    }
}

fn write_outputs(
    out: &Path,
    scene: &Path,
    orders: &[usize],
    samples: u32,
    spp: u32,
    rows: &[HybridRow],
) -> Result<()> {
    let mut md = String::from(
        "| environment | SH order | lights | mean abs. lum. error: SH / thesis hybrid / relight hybrid | std: SH / thesis / relight | relative RMSE: SH / thesis / relight | hybrid vs SH (mean error) | reference noise (rel. RMSE) | reference noise floor (mean abs. lum.) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.4} / {:.4} / {:.4} | {:.4} / {:.4} / {:.4} | {:.1} / {:.1} / {:.1} % | {:.2}x better | {:.1} % | {:.4} |",
            r.env,
            r.order,
            r.lights,
            r.mean_abs_lum_err[0], r.mean_abs_lum_err[1], r.mean_abs_lum_err[2],
            r.std_abs_lum_err[0], r.std_abs_lum_err[1], r.std_abs_lum_err[2],
            100.0 * r.rel_rmse[0], 100.0 * r.rel_rmse[1], 100.0 * r.rel_rmse[2],
            r.mean_abs_lum_err[0] / r.mean_abs_lum_err[2],
            100.0 * r.reference_noise,
            r.lum_noise
        );
    }
    if rows.iter().any(|r| r.better.is_some()) {
        md.push_str(
            "\nAgainst the better reference:\n\n| environment | SH order | reference spp x 2 | mean abs. lum. error: SH / thesis hybrid / relight hybrid | relative RMSE: SH / thesis / relight | hybrid vs SH (mean error) | its noise floor (mean abs. lum.) | first reference's error against it |\n|---|---|---|---|---|---|---|---|\n",
        );
        for r in rows {
            let Some(b) = &r.better else { continue };
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.4} / {:.4} / {:.4} | {:.1} / {:.1} / {:.1} % | {:.2}x better | {:.4} | {:.4} |",
                r.env,
                r.order,
                b.spp,
                b.mean_abs_lum_err[0], b.mean_abs_lum_err[1], b.mean_abs_lum_err[2],
                100.0 * b.rel_rmse[0], 100.0 * b.rel_rmse[1], 100.0 * b.rel_rmse[2],
                b.mean_abs_lum_err[0] / b.mean_abs_lum_err[2],
                b.lum_noise,
                b.reference_err
            );
        }
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
<h1>Hybrid (thesis 4.3-4.4) vs SH PRT vs Mitsuba 3</h1><p>Scene {}, SH order {orders:?}, shadowed transfer with {samples} \
directions per vertex, direct lighting (Mitsuba max_depth 2, {spp} spp x 2 seeds). Metrics over pixels fully covered by \
geometry; error maps share one scale per environment (25 % of the reference's mean luminance = full scale).</p>{}",
        scene.display(),
        md_to_html(&md)
    );
    for r in rows {
        let suffix = if orders.len() > 1 {
            format!("_order{}", r.order)
        } else {
            String::new()
        };
        let _ = write!(h, "<h2>{}, SH order {}</h2><p>", r.env, r.order);
        let _ = write!(h, "<figure style=\"display:inline-block\"><img src=\"{}/mitsuba.png\"><figcaption>mitsuba</figcaption></figure>", r.env);
        for name in METHODS {
            let _ = write!(h, "<figure style=\"display:inline-block\"><img src=\"{}/{name}{suffix}.png\"><figcaption>{name}</figcaption></figure>", r.env);
        }
        h.push_str("<br>");
        for name in METHODS {
            let _ = write!(h, "<figure style=\"display:inline-block\"><img src=\"{}/{name}{suffix}_error.png\"><figcaption>{name} error</figcaption></figure>", r.env);
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

/// Markdown tables (and the lines of text between them) as HTML.
fn md_to_html(md: &str) -> String {
    let mut h = String::new();
    let mut in_table = false;
    let mut header = false;
    for line in md.lines() {
        if !line.starts_with('|') {
            if in_table {
                h.push_str("</table>");
                in_table = false;
            }
            if !line.trim().is_empty() {
                let _ = write!(h, "<p>{}</p>", line.trim());
            }
            continue;
        }
        if !in_table {
            h.push_str("<table border=\"1\" style=\"border-collapse:collapse\">");
            in_table = true;
            header = true;
        }
        if line.starts_with("|---") {
            continue;
        }
        let tag = if header { "th" } else { "td" };
        header = false;
        h.push_str("<tr>");
        for cell in line.trim_matches('|').split('|') {
            let _ = write!(h, "<{tag}>{}</{tag}>", cell.trim());
        }
        h.push_str("</tr>");
    }
    if in_table {
        h.push_str("</table>");
    }
    h
}
