//! `relight eval --method sh`: SH PRT renders against Mitsuba 3, error per SH order.
//!
//! For each scene and environment: one shadowed SH bake at the highest order asked for (the
//! SH basis is hierarchical, so the first `n^2` coefficients of an order-`N` transfer are the
//! order-`n` transfer: lower orders are frames with `sh_order = n`), one Mitsuba 3 render at
//! `max_depth = 2` (direct lighting with shadows: exactly what shadowed transfer holds) with
//! two seeds (their mean is the reference, their difference its noise), then relit renders
//! at every order, compared over the pixels entirely covered by geometry (background and
//! silhouettes excluded: the background is the environment itself, not PRT). Prints a
//! markdown table and writes it with the images.

use crate::reference::{coverage_mask, mean_lum, mitsuba_python, stem, with_width, Job};
use crate::{output, EvalError, Result};
use relight_method::sh::{Sh, ShFrameSettings};
use relight_method::{FrameOptions, FrameSettings};
use relight_render::compare::{self, Metrics};
use relight_render::tonemap::ToneMap;
use relight_scene::scene_file::{EnvDesc, SceneDesc};
use relight_sphere::sh::Window;
use std::fmt::Write as _;
use std::path::PathBuf;

/// The experiment's inputs.
#[derive(Clone, Debug)]
pub struct ShEval {
    /// Scene descriptions (JSON).
    pub scenes: Vec<PathBuf>,
    /// Environments to light every scene with, in turn (empty: each scene's own).
    pub envs: Vec<PathBuf>,
    /// SH orders to evaluate (one bake at the highest).
    pub orders: Vec<usize>,
    /// Bake directions per vertex.
    pub samples: u32,
    /// Mitsuba samples per pixel per seed.
    pub spp: u32,
    /// Image width (the height keeps the camera's aspect); `None`: the scene's.
    pub width: Option<u32>,
    /// Output folder.
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

/// The name of an environment description in tables.
pub fn env_name(e: &EnvDesc) -> String {
    match e {
        EnvDesc::File { path, .. } => stem(path),
        EnvDesc::Sky { .. } => "sky".into(),
        EnvDesc::Constant { .. } => "constant".into(),
    }
}

/// A scene lit by the environment map at `path` instead of its own.
pub fn with_env_file(mut desc: SceneDesc, path: &std::path::Path) -> SceneDesc {
    desc.environment = EnvDesc::File {
        path: path.to_path_buf(),
        layout: None,
        scale: None,
        rotate_y_deg: None,
    };
    desc
}

/// Run the experiment; returns the rows (also written as results.md / results.json).
///
/// # Errors
/// Missing Mitsuba, unreadable scenes, bake or write failures.
pub fn run(e: &ShEval) -> Result<Vec<EvalRow>> {
    let max_order = crate::max_order(&e.orders)?;
    if e.scenes.is_empty() {
        return Err(EvalError::Options(
            "--method sh needs at least one scene".into(),
        ));
    }
    let python = mitsuba_python()?;
    output::create_dir(&e.out)?;
    let envs: Vec<Option<&PathBuf>> = if e.envs.is_empty() {
        vec![None]
    } else {
        e.envs.iter().map(Some).collect()
    };
    let mut rows = Vec::new();
    for scene_path in &e.scenes {
        let base = with_width(SceneDesc::read(scene_path)?, e.width);
        for env in &envs {
            let desc = match env {
                Some(p) => with_env_file(base.clone(), p),
                None => base.clone(),
            };
            let env_name = env_name(&desc.environment);
            let tag = format!("{}_{}", stem(scene_path), env_name);
            let scene = desc.build(scene_path)?;
            eprintln!(
                "eval: {tag}: baking order {max_order} ({} vertices)",
                scene.mesh.vertex_count()
            );
            let settings = crate::shadowed(max_order, e.samples);
            let baked = crate::bake::<Sh>(&desc, &scene, scene_path, &settings)?;
            let dir = e.out.join(&tag);
            let mask = coverage_mask(&scene);
            let job = Job::mitsuba(&python, &scene, &dir, e.spp, 2);
            let r = job.reference([1, 2], &mask)?;
            let tm = ToneMap::Exponential {
                gamma: 1.0 / mean_lum(&r.mean, &mask).max(1e-6) as f32,
            };
            output::image(&dir.join("mitsuba.exr"), &r.mean, &tm)?;
            output::image(&dir.join("mitsuba.png"), &r.mean, &tm)?;
            let opts = FrameOptions {
                supersample: 4,
                background: true,
            };
            for &order in &e.orders {
                let render = |window| -> Result<_> {
                    let s = FrameSettings::Sh(ShFrameSettings {
                        window,
                        sh_order: Some(order),
                    });
                    let mut f = baked.frame(&s)?;
                    f.set_environment(&scene.env)?;
                    Ok(f.render(&scene.camera, &opts).image)
                };
                let img = render(Window::None)?;
                let img_h = render(Window::Hann)?;
                let m: Metrics = compare::metrics(&img, &r.mean, Some(&mask));
                let mh = compare::metrics(&img_h, &r.mean, Some(&mask));
                output::image(&dir.join(format!("sh_order{order:02}.png")), &img, &tm)?;
                output::image(&dir.join(format!("sh_order{order:02}.exr")), &img, &tm)?;
                rows.push(EvalRow {
                    scene: stem(scene_path),
                    env: env_name.clone(),
                    order,
                    rel_rmse: m.rel_rmse,
                    rel_rmse_hann: mh.rel_rmse,
                    mean_abs_lum_err: m.mean_abs_lum_err,
                    std_abs_lum_err: m.std_abs_lum_err,
                    reference_noise: r.noise,
                });
            }
        }
    }
    output::results(&e.out, &table(&rows), &rows)?;
    Ok(rows)
}

fn table(rows: &[EvalRow]) -> String {
    let mut md = String::from(
        "| scene | environment | SH order | relative RMSE | relative RMSE (Hann) | mean abs. lum. error | std abs. lum. error | reference noise |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
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
    md
}
