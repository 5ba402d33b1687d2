//! `relight eval --method hybrid`: the thesis' experiment (chapter 5, Table 5.1) reproduced.
//!
//! A scene (by default the Utah teapot on a small table, `examples/teapot_table.json`) is lit
//! in turn by each environment, with diffuse materials and direct lighting only (Mitsuba
//! `max_depth = 2`, shadowed SH transfer), and rendered four ways:
//! * `mitsuba`: Mitsuba 3, two seeds (their mean is the reference, their difference its noise);
//! * `sh`: SH PRT of the whole environment;
//! * `hybrid-thesis`: the thesis' hybrid: SH part keeps the lights' energy, point lights with
//!   hard PCF shadow maps;
//! * `hybrid`: relight's hybrid: caps removed before the SH projection, area lights the size of
//!   the radiance each cap removed, with soft shadows and the exact cosine over that disc.
//!
//! Metrics over the pixels fully covered by geometry: Table 5.1's mean and standard deviation
//! of the absolute per-pixel luminance error, and the relative RMSE.
//!
//! Error budget (docs/RESULTS.md, hybrid): every row also carries the reference's own noise
//! *in the metric* ([`crate::reference::Reference::lum_noise`]), the mean absolute luminance
//! error a perfect renderer would score against the two seeds' mean. Several SH orders come
//! from one bake (the SH basis is hierarchical), and `reference_spp` renders a second, better
//! reference (two more seeds) against which every method is measured again, with the first
//! reference's own error against it.

mod report;

use crate::reference::{coverage_mask, mitsuba_python, stem, with_width, Job};
use crate::sh::with_env_file;
use crate::{output, Result};
use relight_method::hybrid::{HybridFrame, HybridSettings};
use relight_method::sh::{Sh, ShFrameSettings};
use relight_method::{Baked, Frame, FrameOptions, FrameSettings};
use relight_render::compare::{self, Metrics};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::scene_file::SceneDesc;
use std::path::{Path, PathBuf};

/// The environments of the experiment when none are given, relative to the shared data
/// folder: the thesis' Grace, St Peter's, Eucalyptus Grove and Uffizi, plus Pisa (sunlit
/// courtyard).
pub const PROBES: [&str; 5] = [
    "data/envmaps/debevec/grace_cross.hdr",
    "data/envmaps/debevec/stpeters_cross.hdr",
    "data/envmaps/debevec/rnl_cross.hdr",
    "data/envmaps/debevec_latlong_256x128/uffizi.hdr",
    "data/envmaps/debevec_latlong_256x128/pisa.hdr",
];

/// The [`PROBES`] in the shared data folder `data` (else `$RELIGHT_SHARED`).
///
/// # Errors
/// [`crate::EvalError::Options`] when neither is given.
pub fn default_probes(data: Option<&Path>) -> crate::Result<Vec<PathBuf>> {
    let data = data
        .map(Path::to_path_buf)
        .or_else(|| std::env::var_os("RELIGHT_SHARED").map(PathBuf::from))
        .ok_or_else(|| {
            crate::EvalError::Options(
                "no --env given: the default probes need the shared data folder (--data DIR or $RELIGHT_SHARED)".into(),
            )
        })?;
    Ok(PROBES.iter().map(|p| data.join(p)).collect())
}

/// The experiment's inputs.
#[derive(Clone, Debug)]
pub struct HybridEval {
    /// The scene.
    pub scene: PathBuf,
    /// The environments, in turn.
    pub envs: Vec<PathBuf>,
    /// SH orders (one bake at the highest).
    pub orders: Vec<usize>,
    /// Bake directions per vertex.
    pub samples: u32,
    /// Mitsuba samples per pixel per seed.
    pub spp: u32,
    /// A second, better reference with this many spp per seed (seeds 3 and 4).
    pub reference_spp: Option<u32>,
    /// Image width (the height keeps the camera's aspect).
    pub width: Option<u32>,
    /// relight's hybrid (the thesis' is the same with `thesis: true`); its `sh_order` is
    /// replaced by each of `orders`.
    pub settings: HybridSettings,
    /// Output folder.
    pub out: PathBuf,
}

/// Errors against the better reference (`reference_spp`).
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
    /// Mean absolute luminance error of the `spp` reference against it (the first
    /// reference's measured noise plus the better one's).
    pub reference_err: f64,
}

/// One environment's result at one SH order.
#[derive(serde::Serialize)]
pub struct HybridRow {
    /// Environment file stem.
    pub env: String,
    /// SH order of the SH part.
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
    /// The reference's noise in Table 5.1's metric: the mean error a noiseless renderer would
    /// score.
    pub lum_noise: f64,
    /// Errors against the better reference, when one was rendered.
    pub better: Option<BetterReference>,
}

/// Method names in the order of [`HybridRow`]'s arrays.
pub const METHODS: [&str; 3] = ["sh", "hybrid-thesis", "hybrid"];

fn triple(m: &[Metrics], f: impl Fn(&Metrics) -> f64) -> [f64; 3] {
    [f(&m[0]), f(&m[1]), f(&m[2])]
}

/// Run the experiment; returns the rows (also written as results.md / results.json /
/// report.html).
///
/// # Errors
/// Missing Mitsuba, unreadable inputs, bake, render or write failures.
pub fn run(e: &HybridEval) -> Result<Vec<HybridRow>> {
    let max_order = crate::max_order(&e.orders)?;
    let python = mitsuba_python()?;
    output::create_dir(&e.out)?;
    let base = with_width(SceneDesc::read(&e.scene)?, e.width);
    // The bake does not depend on the environment: bake once, at the highest order.
    let scene0 = base.build(&e.scene)?;
    eprintln!(
        "eval hybrid: baking order {max_order} ({} vertices)",
        scene0.mesh.vertex_count()
    );
    let settings = crate::shadowed(max_order, e.samples);
    let any = crate::bake::<Sh>(&base, &scene0, &e.scene, &settings)?;
    let Baked::Sh(baked) = &any else {
        unreachable!("an sh bake")
    };
    let opts = FrameOptions {
        supersample: 4,
        background: true,
    };
    let mut rows = Vec::new();
    for env_path in &e.envs {
        let env_name = stem(env_path);
        let scene = with_env_file(base.clone(), env_path).build(&e.scene)?;
        let dir = e.out.join(&env_name);
        let mask = coverage_mask(&scene);
        let job = Job::mitsuba(&python, &scene, &dir, e.spp, 2);
        let r = job.reference([1, 2], &mask)?;
        let better_ref = match e.reference_spp {
            Some(hq) => {
                let better = Job {
                    name: "mitsuba_hq",
                    spp: hq,
                    ..job
                };
                Some((hq, better.reference([3, 4], &mask)?))
            }
            None => None,
        };
        let mean_y = crate::reference::mean_lum(&r.mean, &mask);
        let tm = ToneMap::Exponential {
            gamma: (std::f64::consts::LN_2 / mean_y.max(1e-9)) as f32,
        };
        output::image(&dir.join("mitsuba.png"), &r.mean, &tm)?;
        output::image(&dir.join("mitsuba.exr"), &r.mean, &tm)?;
        // The compared pixels, white (for analysing the EXRs outside relight).
        let mask_px: Vec<[u8; 3]> = mask
            .iter()
            .map(|&k| [if k { 255u8 } else { 0 }; 3])
            .collect();
        relight_scene::io::image::write_png_srgb8(
            &dir.join("mask.png"),
            r.mean.width,
            r.mean.height,
            &mask_px,
        )?;
        if let Some((_, b)) = &better_ref {
            output::image(&dir.join("mitsuba_hq.png"), &b.mean, &tm)?;
            output::image(&dir.join("mitsuba_hq.exr"), &b.mean, &tm)?;
        }
        for &o in &e.orders {
            let sh_settings = FrameSettings::Sh(ShFrameSettings {
                sh_order: Some(o),
                ..Default::default()
            });
            let mut sh_frame = any.frame(&sh_settings)?;
            sh_frame.set_environment(&scene.env)?;
            let sh_img = sh_frame.render(&scene.camera, &opts).image;
            let ours = HybridSettings {
                sh_order: Some(o),
                ..e.settings
            };
            let thesis = HybridSettings {
                thesis: true,
                ..ours
            };
            let mut thesis_frame = HybridFrame::new(baked, &thesis)?;
            thesis_frame.set_environment(&scene.env)?;
            let thesis_img = thesis_frame.render(&scene.camera, &opts).image;
            let mut frame = HybridFrame::new(baked, &ours)?;
            frame.set_environment(&scene.env)?;
            let hyb_img = frame.render(&scene.camera, &opts).image;
            let lights = frame.decomposition().map_or(0, |d| d.lights.len());
            let imgs: [&Image; 3] = [&sh_img, &thesis_img, &hyb_img];
            let m: Vec<Metrics> = imgs
                .iter()
                .map(|i| compare::metrics(i, &r.mean, Some(&mask)))
                .collect();
            // Image names carry the order only when several are evaluated.
            let suffix = report::suffix(&e.orders, o);
            for (name, img) in METHODS.iter().zip(imgs) {
                // One heat-map scale for all methods of this environment, so they compare.
                let scale = 0.25 * mean_y as f32;
                output::image_set(
                    &dir,
                    &format!("{name}{suffix}"),
                    img,
                    Some(&r.mean),
                    &tm,
                    scale,
                )?;
            }
            let better = better_ref.as_ref().map(|(hq, b)| {
                let mb: Vec<Metrics> = imgs
                    .iter()
                    .map(|i| compare::metrics(i, &b.mean, Some(&mask)))
                    .collect();
                BetterReference {
                    spp: *hq,
                    mean_abs_lum_err: triple(&mb, |m| m.mean_abs_lum_err),
                    rel_rmse: triple(&mb, |m| m.rel_rmse),
                    lum_noise: b.lum_noise,
                    reference_err: compare::metrics(&r.mean, &b.mean, Some(&mask)).mean_abs_lum_err,
                }
            });
            let row = HybridRow {
                env: env_name.clone(),
                order: o,
                lights,
                rel_rmse: triple(&m, |m| m.rel_rmse),
                mean_abs_lum_err: triple(&m, |m| m.mean_abs_lum_err),
                std_abs_lum_err: triple(&m, |m| m.std_abs_lum_err),
                reference_noise: r.noise,
                lum_noise: r.lum_noise,
                better,
            };
            report::progress(&row);
            rows.push(row);
        }
    }
    report::write(e, &rows)?;
    Ok(rows)
}
