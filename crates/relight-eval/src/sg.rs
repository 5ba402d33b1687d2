//! `relight eval --method sg`: Green 2005's visual evaluations (thesis section 3.4) against
//! Mitsuba 3.
//!
//! * **Fig. 3-4**: a glossy object under a real light probe, rendered from the SG bake (one
//!   Gaussian per glossy component, order-5 SH for the diffuse part, as the figure's caption)
//!   and by Mitsuba 3 with the same BRDF (`roughconductor`, `roughplastic`, GGX). The GGX
//!   conductor is evaluated with interreflections (direct + indirect glossy: for a material
//!   with no diffuse lobe that is all the light, so Mitsuba runs with `max_depth = 2 +` the
//!   bake's bounces); the plastic with direct lighting only (`max_depth = 2`, no indirect
//!   component), because the SG bake, as the paper's, has no diffuse-to-anything
//!   interreflection.
//! * **Fig. 3-5**: SG against prefiltered environment mapping, which ignores visibility. The
//!   baseline is the same bake with `visibility: false` (every texel above the horizon
//!   visible): the same representation, fitter and renderer, so the only difference is
//!   shadowing. The metrics are given over all covered pixels and over the pixels where
//!   visibility matters (the two renders differ by more than 10 % of the reference's mean
//!   luminance), where the baseline shows the highlights the occluder blocks.
//!
//! Metrics are over the pixels fully covered by geometry (as `--method sh`); the Mitsuba
//! reference is the mean of two seeds, and half their difference its own noise.

use crate::reference::{coverage_mask, mean_lum, mitsuba_python, stem, with_width, Job};
use crate::{output, Result};
use glam::Vec3;
use relight_method::sg::{Sg, SgSettings};
use relight_method::{Baked, FrameOptions, FrameSettings};
use relight_render::compare::{self, Metrics};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::material::Material;
use relight_scene::scene::Scene;
use relight_scene::scene_file::SceneDesc;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One experiment: a scene, an optional material override, which components are baked.
#[derive(Clone, Debug)]
pub struct Experiment {
    /// Its name (folder and table row).
    pub name: String,
    /// The scene file.
    pub scene: PathBuf,
    /// Every material of the scene replaced by this one.
    pub material: Option<Material>,
    /// Bake the indirect glossy component (and render the reference with interreflections).
    pub indirect: bool,
    /// Also bake and score the no-visibility baseline (Fig. 3-5).
    pub baseline: bool,
}

/// "Acrylic white"-like plastic of Fig. 3-4 (Ngan et al.'s acquired material is not
/// available; a white GGX plastic of similar gloss stands in).
pub const PLASTIC: Material = Material::GgxPlastic {
    diffuse: Vec3::new(0.8, 0.8, 0.8),
    specular: Vec3::ONE,
    alpha: 0.1,
    ior: 1.49,
};

/// Fig. 3-4 (conductor and plastic on Spot) and Fig. 3-5 (the shadowed highlight), from the
/// example scenes in `examples` (the repository's `examples/` folder).
pub fn default_experiments(examples: &Path) -> Vec<Experiment> {
    let ex = |name: &str, file: &str, material, indirect, baseline| Experiment {
        name: name.into(),
        scene: examples.join(file),
        material,
        indirect,
        baseline,
    };
    vec![
        ex("fig3-4_conductor", "sg_spot.json", None, true, false),
        ex(
            "fig3-4_plastic",
            "sg_spot.json",
            Some(PLASTIC),
            false,
            false,
        ),
        ex(
            "fig3-5_shadowed_highlight",
            "sg_shadowed_highlight.json",
            None,
            false,
            true,
        ),
    ]
}

/// Experiments of user-given scenes: indirect as the settings say, with the baseline.
pub fn scene_experiments(scenes: &[PathBuf], settings: &SgSettings) -> Vec<Experiment> {
    scenes
        .iter()
        .map(|s| Experiment {
            name: stem(s),
            scene: s.clone(),
            material: None,
            indirect: settings.bake.indirect_lobes > 0,
            baseline: true,
        })
        .collect()
}

/// The experiment's inputs.
#[derive(Clone, Debug)]
pub struct SgEval {
    /// The experiments.
    pub experiments: Vec<Experiment>,
    /// The bake's settings (the indirect lobes are dropped where an experiment has none).
    pub settings: SgSettings,
    /// Mitsuba samples per pixel per seed.
    pub spp: u32,
    /// Image width (the height keeps the camera's aspect).
    pub width: Option<u32>,
    /// Output folder.
    pub out: PathBuf,
}

/// One row of the results.
#[derive(serde::Serialize)]
pub struct Row {
    /// Experiment name.
    pub experiment: String,
    /// Mesh vertices.
    pub vertices: usize,
    /// Bake wall time.
    pub bake_seconds: f64,
    /// Frame time (per-vertex + per-pixel).
    pub frame_ms: f64,
    /// Mean relative L2 error of the direct fits.
    pub fit_error_direct: f64,
    /// Lobe flips after the flood fill.
    pub flips: u64,
    /// Lobe flips after relaxation.
    pub flips_after_relaxation: u64,
    /// Mitsuba's `max_depth`.
    pub mitsuba_max_depth: i32,
    /// Relative RMSE of SG against Mitsuba.
    pub rel_rmse: f64,
    /// Mean absolute luminance error.
    pub mean_abs_lum_err: f64,
    /// The reference's own relative noise.
    pub reference_noise: f64,
    /// No-visibility baseline (Fig. 3-5): relative RMSE over all covered pixels.
    pub baseline_rel_rmse: Option<f64>,
    /// Pixels where visibility matters.
    pub shadowed_pixels: Option<usize>,
    /// Relative RMSE of SG there.
    pub sg_rel_rmse_shadowed: Option<f64>,
    /// Relative RMSE of the baseline there.
    pub baseline_rel_rmse_shadowed: Option<f64>,
    /// Mean luminance there: reference, SG, baseline.
    pub mean_lum_shadowed: Option<[f64; 3]>,
}

/// Run the experiments; returns the rows (also written as results.md / results.json).
///
/// # Errors
/// Missing Mitsuba, unreadable inputs, bake, render or write failures.
pub fn run(e: &SgEval) -> Result<Vec<Row>> {
    let python = mitsuba_python()?;
    output::create_dir(&e.out)?;
    let mut rows = Vec::new();
    for ex in &e.experiments {
        rows.push(run_one(e, ex, &python)?);
    }
    output::results(&e.out, &table(&rows, e), &rows)?;
    Ok(rows)
}

/// Bake `scene` with `settings` and render it under its own environment and camera.
fn bake_and_render(
    desc: &SceneDesc,
    scene: &Scene,
    origin: &Path,
    settings: &SgSettings,
) -> Result<(Baked, Image, f64)> {
    let baked = crate::bake::<Sg>(desc, scene, origin, settings)?;
    let mut frame = baked.frame(&FrameSettings::default_for(relight_method::MethodKind::Sg))?;
    frame.set_environment(&scene.env)?;
    let opts = FrameOptions {
        supersample: 4,
        background: false,
    };
    let out = frame.render(&scene.camera, &opts);
    let ms = out.times.vertex_ms + out.times.pixel_ms;
    drop(frame);
    Ok((baked, out.image, ms))
}

fn run_one(e: &SgEval, ex: &Experiment, python: &Path) -> Result<Row> {
    let desc = with_width(SceneDesc::read(&ex.scene)?, e.width);
    let mut scene = desc.build(&ex.scene)?;
    if let Some(m) = ex.material {
        scene.materials.iter_mut().for_each(|x| *x = m);
    }
    let mut settings = e.settings;
    if !ex.indirect {
        settings.bake.indirect_lobes = 0;
    }
    let dir = e.out.join(&ex.name);
    eprintln!(
        "eval sg: {}: baking {} vertices",
        ex.name,
        scene.mesh.vertex_count()
    );
    let (baked, img, frame_ms) = bake_and_render(&desc, &scene, &ex.scene, &settings)?;
    let depth = if settings.bake.indirect_lobes > 0 {
        2 + settings.bake.max_depth as i32
    } else {
        2
    };
    let mask = coverage_mask(&scene);
    let job = Job::mitsuba(python, &scene, &dir, e.spp, depth);
    let r = job.reference([1, 2], &mask)?;
    let mean_y = mean_lum(&r.mean, &mask);
    let tm = ToneMap::Exponential {
        gamma: 1.0 / mean_y.max(1e-6) as f32,
    };
    let m: Metrics = compare::metrics(&img, &r.mean, Some(&mask));
    let scale = 0.25 * mean_y as f32;
    output::image_set(&dir, "mitsuba", &r.mean, None, &tm, scale)?;
    output::image_set(&dir, "sg", &img, Some(&r.mean), &tm, scale)?;
    let Baked::Sg(sg) = &baked else {
        unreachable!("an sg bake")
    };
    let s = &sg.bake.stats;
    let mut row = Row {
        experiment: ex.name.clone(),
        vertices: scene.mesh.vertex_count(),
        bake_seconds: sg.record.seconds,
        frame_ms,
        fit_error_direct: s.mean_relative_error[0],
        flips: s.flips,
        flips_after_relaxation: s.flips_after_relaxation,
        mitsuba_max_depth: depth,
        rel_rmse: m.rel_rmse,
        mean_abs_lum_err: m.mean_abs_lum_err,
        reference_noise: r.noise,
        baseline_rel_rmse: None,
        shadowed_pixels: None,
        sg_rel_rmse_shadowed: None,
        baseline_rel_rmse_shadowed: None,
        mean_lum_shadowed: None,
    };
    if ex.baseline {
        let mut o = settings;
        o.bake.visibility = false;
        eprintln!("eval sg: {}: baking the no-visibility baseline", ex.name);
        let (_, bimg, _) = bake_and_render(&desc, &scene, &ex.scene, &o)?;
        output::image_set(&dir, "envmap", &bimg, Some(&r.mean), &tm, scale)?;
        let mb = compare::metrics(&bimg, &r.mean, Some(&mask));
        // Where visibility matters: the two bakes differ by over 10 % of the mean luminance.
        let region: Vec<bool> = (0..mask.len())
            .map(|i| {
                let d = compare::luminance(bimg.pixels[i]) - compare::luminance(img.pixels[i]);
                mask[i] && d.abs() as f64 > 0.1 * mean_y
            })
            .collect();
        let n = region.iter().filter(|&&r| r).count();
        row.baseline_rel_rmse = Some(mb.rel_rmse);
        row.shadowed_pixels = Some(n);
        if n > 0 {
            let there = |i: &Image| compare::metrics(i, &r.mean, Some(&region)).rel_rmse;
            row.sg_rel_rmse_shadowed = Some(there(&img));
            row.baseline_rel_rmse_shadowed = Some(there(&bimg));
            row.mean_lum_shadowed = Some([
                mean_lum(&r.mean, &region),
                mean_lum(&img, &region),
                mean_lum(&bimg, &region),
            ]);
        }
    }
    Ok(row)
}

fn table(rows: &[Row], e: &SgEval) -> String {
    let s = &e.settings.bake;
    let mut md = String::new();
    let _ = writeln!(
        md,
        "SG (Green 2005) against Mitsuba 3, {} spp x 2 seeds; {} direct + {} indirect lobes, \
         direct 6x{}x{}, indirect 6x{}x{}, diffuse SH order {}\n",
        e.spp,
        s.direct_lobes,
        s.indirect_lobes,
        s.direct_res,
        s.direct_res,
        s.indirect_res,
        s.indirect_res,
        s.diffuse_order
    );
    md.push_str(
        "| experiment | vertices | bake s | frame ms | fit error | flips (after relax.) | Mitsuba max_depth | rel. RMSE SG | reference noise | rel. RMSE no-visibility | shadowed px | rel. RMSE there: SG / no-vis. | mean lum. there: ref / SG / no-vis. |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let lum = r
            .mean_lum_shadowed
            .map(|l| format!("{:.4} / {:.4} / {:.4}", l[0], l[1], l[2]))
            .unwrap_or_else(|| "-".into());
        let _ = writeln!(
            md,
            "| {} | {} | {:.1} | {:.1} | {:.3} | {} ({}) | {} | {:.1} % | {:.1} % | {} | {} | {} / {} | {} |",
            r.experiment,
            r.vertices,
            r.bake_seconds,
            r.frame_ms,
            r.fit_error_direct,
            r.flips,
            r.flips_after_relaxation,
            r.mitsuba_max_depth,
            100.0 * r.rel_rmse,
            100.0 * r.reference_noise,
            output::pct(r.baseline_rel_rmse),
            r.shadowed_pixels.map_or("-".into(), |n| n.to_string()),
            output::pct(r.sg_rel_rmse_shadowed),
            output::pct(r.baseline_rel_rmse_shadowed),
            lum
        );
    }
    md
}
