//! `relight eval --method sh`: SH PRT renders against Mitsuba 3, error per SH order.
//!
//! For each scene and environment: one shadowed SH bake at the highest order asked for (the
//! SH basis is hierarchical, so the first `n^2` coefficients of an order-`N` transfer are the
//! order-`n` transfer), one Mitsuba 3 render at `max_depth = 2` (direct lighting with
//! shadows: exactly what shadowed transfer holds) with two seeds (their mean is the reference,
//! their difference its noise), then relit renders at every order, compared over the pixels
//! entirely covered by geometry (background and silhouettes excluded: the background is the
//! environment itself, not PRT). Prints a markdown table and writes it with the images.

use crate::common::write_image;
use crate::render::relight;
use crate::store::ShBake;
use anyhow::{anyhow, bail, Context, Result};
use relight_bake::sh::{ShBakeSettings, ShTransfer, ShTransferKind};
use relight_render::compare::{self, Metrics};
use relight_render::mitsuba;
use relight_render::raster::{self, RasterOptions};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::scene_file::{EnvDesc, SceneDesc};
use relight_sphere::sh::{sh_count, Window};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `relight eval`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene descriptions (JSON); for `--method hybrid` one scene, default
    /// examples/teapot_table.json.
    pub scenes: Vec<PathBuf>,
    /// Method to evaluate: `sh` (error per SH order) or `hybrid` (the thesis' Table 5.1
    /// experiment: SH-only vs the thesis' hybrid vs relight's hybrid, against Mitsuba).
    #[arg(long, default_value = "sh")]
    pub method: String,
    /// SH order of the bake for `--method hybrid`.
    #[arg(long, default_value_t = 5)]
    pub order: usize,
    #[command(flatten)]
    pub hybrid: crate::hybrid::HybridOpts,
    #[command(flatten)]
    pub hybrid_eval: crate::eval_hybrid::EvalHybridOpts,
    #[command(flatten)]
    pub sg: crate::sg::SgBakeOpts,
    /// Environments to light every scene with, in turn (default: each scene's own).
    #[arg(long)]
    pub env: Vec<PathBuf>,
    /// Lowest SH order.
    #[arg(long, default_value_t = 2)]
    pub min_order: usize,
    /// Highest SH order.
    #[arg(long, default_value_t = 10)]
    pub max_order: usize,
    /// Bake directions per vertex.
    #[arg(long, default_value_t = 1024)]
    pub samples: u32,
    /// Mitsuba samples per pixel (per seed; two seeds are rendered).
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Image width (height keeps the scene camera's aspect).
    #[arg(long)]
    pub width: Option<u32>,
    /// Output folder (images, results.md, results.json).
    #[arg(long, default_value = "out/eval")]
    pub out: PathBuf,
}

/// One row of the evaluation.
#[derive(serde::Serialize)]
pub struct EvalRow {
    /// Scene file stem.
    pub scene: String,
    /// Environment file stem.
    pub env: String,
    /// SH order.
    pub order: usize,
    /// Relative RMSE against Mitsuba (no window).
    pub rel_rmse: f64,
    /// Relative RMSE with a Hann window on the lighting.
    pub rel_rmse_hann: f64,
    /// Mean absolute luminance error (thesis Table 5.1).
    pub mean_abs_lum_err: f64,
    /// Its standard deviation.
    pub std_abs_lum_err: f64,
    /// Relative RMSE of the Mitsuba reference itself (its noise floor).
    pub reference_noise: f64,
}

/// File stem as a string.
pub fn stem(p: &std::path::Path) -> String {
    p.file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string()
}

fn truncate(t: &ShTransfer, order: usize) -> ShTransfer {
    let (n_old, n_new, c) = (sh_count(t.order), sh_count(order), t.channels);
    let mut data = Vec::with_capacity(t.vertex_count * n_new * c);
    for v in 0..t.vertex_count {
        data.extend_from_slice(&t.data[v * n_old * c..(v * n_old + n_new) * c]);
    }
    ShTransfer {
        order,
        kind: t.kind,
        vertex_count: t.vertex_count,
        channels: c,
        data,
    }
}

/// Run `relight eval`.
pub fn run(a: Args) -> Result<()> {
    match a.method.as_str() {
        "sh" if a.scenes.is_empty() => bail!("--method sh needs at least one scene"),
        "sh" => {}
        "hybrid" => return run_hybrid(&a),
        "sg-basis" => return crate::eval_sg_basis::run(&a.out),
        "sg" => return crate::eval_sg::run(&a),
        m => bail!("unknown --method '{m}' (sh, hybrid, sg, sg-basis)"),
    }
    if a.min_order < 1 || a.min_order > a.max_order || a.max_order > relight_sphere::sh::MAX_ORDER {
        bail!(
            "orders {}..={} are not a valid range in 1..={}",
            a.min_order,
            a.max_order,
            relight_sphere::sh::MAX_ORDER
        );
    }
    let python = mitsuba::mitsuba_python().map_err(|e| {
        anyhow!("Mitsuba 3 is needed for `relight eval` (run scripts/setup.sh): {e}")
    })?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut rows: Vec<EvalRow> = Vec::new();
    for scene_path in &a.scenes {
        let base = SceneDesc::read(scene_path)?;
        let envs: Vec<Option<PathBuf>> = if a.env.is_empty() {
            vec![None]
        } else {
            a.env.iter().cloned().map(Some).collect()
        };
        for env in envs {
            let mut desc = base.clone();
            if let Some(e) = &env {
                desc.environment = EnvDesc::File {
                    path: e.clone(),
                    layout: None,
                    scale: None,
                    rotate_y_deg: None,
                };
            }
            if let Some(w) = a.width {
                desc.camera.height =
                    (w as u64 * desc.camera.height as u64 / desc.camera.width as u64).max(1) as u32;
                desc.camera.width = w;
            }
            let env_name = match &desc.environment {
                EnvDesc::File { path, .. } => stem(path),
                EnvDesc::Sky { .. } => "sky".into(),
                EnvDesc::Constant { .. } => "constant".into(),
            };
            let tag = format!("{}_{}", stem(scene_path), env_name);
            let scene = desc.build(scene_path)?;
            eprintln!(
                "eval: {tag}: baking order {} ({} vertices)",
                a.max_order,
                scene.mesh.vertex_count()
            );
            let settings = ShBakeSettings {
                order: a.max_order,
                samples: a.samples,
                seed: 1,
                kind: ShTransferKind::Shadowed,
                threads: None,
                progress: true,
            };
            let baked: ShBake = crate::bake::bake_scene(
                &desc,
                &scene,
                &settings,
                crate::bake::parse_backend(None)?,
                false,
                scene_path,
            )?;
            let dir = a.out.join(&tag);
            let (reference, mask, noise) = mask_and_reference(&python, &scene, &dir, a.spp)?;
            let tm = ToneMap::Exponential {
                gamma: 1.0 / mean_lum(&reference, &mask).max(1e-6) as f32,
            };
            write_image(&dir.join("mitsuba.exr"), &reference, &tm)?;
            write_image(&dir.join("mitsuba.png"), &reference, &tm)?;
            for order in a.min_order..=a.max_order {
                let mut b = ShBake {
                    transfer: truncate(&baked.transfer, order),
                    ..clone_bake(&baked)
                };
                b.settings.order = order;
                let (img, _) = relight(&b, &scene.env, &scene.camera, Window::None, 4, true);
                let (img_h, _) = relight(&b, &scene.env, &scene.camera, Window::Hann, 4, true);
                let m: Metrics = compare::metrics(&img, &reference, Some(&mask));
                let mh = compare::metrics(&img_h, &reference, Some(&mask));
                write_image(&dir.join(format!("sh_order{order:02}.png")), &img, &tm)?;
                write_image(&dir.join(format!("sh_order{order:02}.exr")), &img, &tm)?;
                rows.push(EvalRow {
                    scene: stem(scene_path),
                    env: env_name.clone(),
                    order,
                    rel_rmse: m.rel_rmse,
                    rel_rmse_hann: mh.rel_rmse,
                    mean_abs_lum_err: m.mean_abs_lum_err,
                    std_abs_lum_err: m.std_abs_lum_err,
                    reference_noise: noise,
                });
            }
        }
    }
    let mut md = String::from(
        "| scene | environment | SH order | relative RMSE | relative RMSE (Hann) | mean abs. lum. error | std abs. lum. error | reference noise |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in &rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} % | {:.2} % | {:.4} | {:.4} | {:.2} % |",
            r.scene,
            r.env,
            r.order,
            100.0 * r.rel_rmse,
            100.0 * r.rel_rmse_hann,
            r.mean_abs_lum_err,
            r.std_abs_lum_err,
            100.0 * r.reference_noise
        );
    }
    write_results(&a.out, &md, &rows)
}

/// Print the markdown table and write it as `out/results.md` with the rows as
/// `out/results.json` (atomically).
pub fn write_results(out: &std::path::Path, md: &str, rows: &impl serde::Serialize) -> Result<()> {
    println!("{md}");
    relight_bundle::write_atomic(&out.join("results.md"), md.as_bytes())?;
    relight_bundle::write_atomic(
        &out.join("results.json"),
        serde_json::to_string_pretty(rows)?.as_bytes(),
    )?;
    println!("wrote {}", out.join("results.md").display());
    Ok(())
}

/// Mitsuba 3 reference of `scene` (max_depth 2, `spp` x 2 seeds, mean of the two) exported and
/// rendered under `dir`, the mask of pixels fully covered by geometry (4 x 4 supersampled
/// coverage, like Mitsuba's box filter), and the reference's own relative noise.
pub fn mask_and_reference(
    python: &std::path::Path,
    scene: &relight_scene::scene::Scene,
    dir: &std::path::Path,
    spp: u32,
) -> Result<(Image, Vec<bool>, f64)> {
    mask_and_reference_at_depth(python, scene, dir, spp, 2)
}

/// The pixels of `scene`'s camera fully covered by geometry (4 x 4 supersampled coverage,
/// like Mitsuba's box filter): where methods are compared.
pub fn coverage_mask(scene: &relight_scene::scene::Scene) -> Vec<bool> {
    let ones = vec![glam::Vec3::ONE; scene.mesh.vertex_count()];
    raster::render_with(
        &scene.mesh,
        &scene.camera,
        &ones,
        None,
        &RasterOptions { supersample: 4 },
    )
    .full_coverage_mask()
}

/// [`mask_and_reference`] with Mitsuba's `max_depth` (2 = direct only, -1 = unlimited).
pub fn mask_and_reference_at_depth(
    python: &std::path::Path,
    scene: &relight_scene::scene::Scene,
    dir: &std::path::Path,
    spp: u32,
    max_depth: i32,
) -> Result<(Image, Vec<bool>, f64)> {
    let json = mitsuba::export_mitsuba(scene, &dir.join("mitsuba"), spp, max_depth)
        .map_err(|e| anyhow!("{}: {e}", dir.display()))?;
    eprintln!("eval: {}: Mitsuba 3, {spp} spp x 2 seeds", dir.display());
    let (imgs, report) =
        mitsuba::render_mitsuba(python, &json, &dir.join("mitsuba"), &[1, 2], None)
            .map_err(|e| anyhow!("{}: {e}", dir.display()))?;
    eprintln!("eval: {}: {report}", dir.display());
    let reference = Image {
        width: imgs[0].width,
        height: imgs[0].height,
        pixels: imgs[0]
            .pixels
            .iter()
            .zip(&imgs[1].pixels)
            .map(|(x, y)| (*x + *y) * 0.5)
            .collect(),
    };
    let mask = coverage_mask(scene);
    let noise = compare::metrics(&imgs[0], &imgs[1], Some(&mask)).rel_rmse / 2.0;
    Ok((reference, mask, noise))
}

/// Mean luminance of `img` over the pixels where `mask` is set (0 for an empty mask).
pub fn mean_lum(img: &Image, mask: &[bool]) -> f64 {
    let (s, n) = img
        .pixels
        .iter()
        .zip(mask)
        .filter(|(_, &m)| m)
        .fold((0.0, 0usize), |(s, n), (c, _)| {
            (s + compare::luminance(*c) as f64, n + 1)
        });
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

fn clone_bake(b: &ShBake) -> ShBake {
    ShBake {
        scene: b.scene.clone(),
        mesh: b.mesh.clone(),
        materials: b.materials.clone(),
        albedo: b.albedo.clone(),
        transfer: b.transfer.clone(),
        settings: b.settings.clone(),
    }
}

/// The environments of the hybrid experiment when none are given: the thesis' Grace, St
/// Peter's, Eucalyptus Grove and Uffizi, plus Pisa (sunlit courtyard) from ../shared.
pub const HYBRID_PROBES: [&str; 5] = [
    "data/envmaps/debevec/grace_cross.hdr",
    "data/envmaps/debevec/stpeters_cross.hdr",
    "data/envmaps/debevec/rnl_cross.hdr",
    "data/envmaps/debevec_latlong_256x128/uffizi.hdr",
    "data/envmaps/debevec_latlong_256x128/pisa.hdr",
];

fn run_hybrid(a: &Args) -> Result<()> {
    let scene = match a.scenes.as_slice() {
        [] => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/teapot_table.json"),
        [s] => s.clone(),
        _ => bail!("--method hybrid evaluates one scene at a time"),
    };
    let envs: Vec<PathBuf> = if a.env.is_empty() {
        let shared = relight_scene::testdata::shared_dir()
            .context("no --env given and ../shared (the default probes) is not present")?;
        HYBRID_PROBES.iter().map(|p| shared.join(p)).collect()
    } else {
        a.env.clone()
    };
    crate::eval_hybrid::run(
        &scene,
        &envs,
        a.order,
        a.samples,
        a.spp,
        a.width,
        &a.hybrid,
        &a.hybrid_eval,
        &a.out,
    )?;
    Ok(())
}
