//! `relight eval --method cuts`: Cheslack-Postava et al. 2008's evaluation (sec. 5) against
//! Mitsuba 3.
//!
//! * **Fig. 9's table**: per scene (default: the bunny under Grace Cathedral, the dragon under
//!   an outdoor dawn, the teapot on a table under St Peter's; each on a floor that takes its
//!   shadow), the bake's vertices, time, storage and mean visibility-cut length, for the
//!   geometric light tree (Eq. 11) and, with `--data-driven`, the data-driven tree (Eq. 12-13);
//!   then per illumination-cut budget (128, 256, 512 by default) the frame time and the
//!   relative RMSE against Mitsuba (direct lighting: `max_depth = 2`, as the method has no
//!   interreflection).
//! * **Fig. 10**: error against the light-cut size (the same rows), and materials edited
//!   after the bake: the same bundle rendered with a GGX conductor and a GGX plastic instead
//!   of the scene's materials (`render --material`), each scored against Mitsuba rendering
//!   the scene with that material. Nothing is re-baked: the bake holds visibility only.
//!
//! Metrics are over the pixels fully covered by geometry; the Mitsuba reference is the mean
//! of two seeds and half their difference its own noise (`reference_noise`): a relative RMSE
//! near it is as close as the reference can tell. Frame times: the evaluation's image (4 x 4
//! supersampled) and a 512 x 512 frame at one sample per pixel (the target) of the
//! same camera, on this machine's cores.

use crate::reference::{coverage_mask, mean_lum, mitsuba_python, stem, with_width, Job};
use crate::{output, Result};
use glam::Vec3;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::samples::sample_power;
use relight_bake::cuts::CutsBakeSettings;
use relight_bake::cuts::LightTreeKind;
use relight_method::cuts::{Cuts, CutsFrameSettings};
use relight_method::{Baked, FrameOptions, FrameSettings, Method};
use relight_render::compare;
use relight_render::tonemap::ToneMap;
use relight_scene::material::Material;
use relight_scene::scene_file::SceneDesc;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

pub mod terms;

/// The example scenes of the default experiments (Fig. 9's bunny, dragon and teapot).
pub const DEFAULT_SCENES: [&str; 3] = ["bunny_grace.json", "cuts_dragon.json", "teapot_table.json"];

/// The materials the bake is re-rendered with (Fig. 10's edited materials).
pub const EDITED: [(&str, Material); 2] = [
    (
        "ggx_conductor",
        Material::GgxConductor {
            specular: Vec3::new(0.95, 0.75, 0.45),
            alpha: 0.2,
        },
    ),
    ("ggx_plastic", crate::sg::PLASTIC),
];

/// The experiment's inputs.
#[derive(Clone, Debug)]
pub struct CutsEval {
    /// Scene files.
    pub scenes: Vec<PathBuf>,
    /// The bake's settings (the tree is each of [`CutsEval::trees`] in turn).
    pub settings: CutsBakeSettings,
    /// Light trees to bake with.
    pub trees: Vec<LightTreeKind>,
    /// Illumination-cut budgets to render with.
    pub light_cuts: Vec<usize>,
    /// Also render the [`EDITED`] materials (geometric tree only).
    pub edited_materials: bool,
    /// Mitsuba samples per pixel per seed.
    pub spp: u32,
    /// Image width (the height keeps the camera's aspect).
    pub width: Option<u32>,
    /// Output folder.
    pub out: PathBuf,
}

/// The light trees to evaluate: `given`, else the geometric and the data-driven tree.
pub fn trees(given: Option<LightTreeKind>) -> Vec<LightTreeKind> {
    given.map_or(
        vec![LightTreeKind::Geometric, LightTreeKind::DataDriven],
        |t| vec![t],
    )
}

/// One row: a bake, a material and a light-cut budget.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// Scene name.
    pub scene: String,
    /// Light tree.
    pub tree: String,
    /// `scene` (its own materials) or the edited material's name.
    pub material: String,
    /// Mesh vertices.
    pub vertices: usize,
    /// Bake wall time, seconds.
    pub bake_seconds: f64,
    /// Bundle size, MiB.
    pub storage_mib: f64,
    /// Mean visibility-cut length, nodes.
    pub mean_cut: f64,
    /// Cuts stopped at the cap.
    pub capped: usize,
    /// Illumination-cut budget.
    pub light_cut: usize,
    /// The illumination cut's length (at most the budget).
    pub light_cut_nodes: usize,
    /// Frame time at the evaluation's image (4 x 4 supersampled), ms.
    pub frame_ms: f64,
    /// Frame time at 512 x 512, 1 sample per pixel, ms.
    pub frame_512_ms: f64,
    /// Relative RMSE against Mitsuba.
    pub rel_rmse: f64,
    /// Relative RMSE against Mitsuba of the same bake and light cut rendered with each
    /// glossy cluster's BRDF evaluated at its direction alone (`--cluster-spread false`; the
    /// frame's default averages it over the cluster's spread).
    pub rel_rmse_one_direction: f64,
    /// Mean absolute luminance error.
    pub mean_abs_lum_err: f64,
    /// The reference's own relative noise.
    pub reference_noise: f64,
}

/// Run the experiments; returns the rows (also written as results.md / results.json).
///
/// # Errors
/// Missing Mitsuba, unreadable inputs, bake, render or write failures.
pub fn run(e: &CutsEval) -> Result<Vec<Row>> {
    if e.light_cuts.is_empty() || e.trees.is_empty() || e.light_cuts.contains(&0) {
        return Err(crate::EvalError::Options(format!(
            "light cuts {:?}, light trees {:?}: need at least one of each, and light cuts of at least 1 node",
            e.light_cuts, e.trees
        )));
    }
    let python = mitsuba_python()?;
    output::create_dir(&e.out)?;
    let mut rows = Vec::new();
    let mut terms = Vec::new();
    for path in &e.scenes {
        run_scene(e, path, &python, &mut rows, &mut terms)?;
    }
    let mut md = table(&rows);
    md.push_str(&terms_table(&terms));
    let json = serde_json::to_string_pretty(&terms)
        .map_err(|x| crate::EvalError::Options(format!("cannot write terms.json: {x}")))?;
    relight_bundle::write_atomic(&e.out.join("terms.json"), json.as_bytes())?;
    output::results(&e.out, &md, &rows)?;
    Ok(rows)
}

/// Bakes, renders and scores one scene, appending its rows.
fn run_scene(
    e: &CutsEval,
    path: &Path,
    python: &Path,
    rows: &mut Vec<Row>,
    terms_rows: &mut Vec<(String, terms::TermsRow)>,
) -> Result<()> {
    let name = stem(path);
    let desc = with_width(SceneDesc::read(path)?, e.width);
    let scene = desc.build(path)?;
    // Fig. 8a on this scene's visibility functions.
    let caster = relight_scene::accel::build_default(&scene.mesh);
    eprintln!("eval cuts: {name}: terms against error (Fig. 8a), {TERMS_VERTICES} vertices");
    let t = terms::terms_vs_error(&terms::TermsInput {
        mesh: &scene.mesh,
        caster: caster.as_ref(),
        vertices: TERMS_VERTICES,
        lights: e.settings.lights as usize,
        face: TERMS_FACE,
        function: e.settings.function,
    })?;
    drop(caster);
    terms_rows.extend(t.into_iter().map(|r| (name.clone(), r)));
    let dir = e.out.join(&name);
    let mask = coverage_mask(&scene);
    // The references: the scene's materials, then each edited material.
    let mut materials: Vec<(String, Option<Material>)> = vec![("scene".into(), None)];
    if e.edited_materials {
        materials.extend(EDITED.iter().map(|&(n, m)| (n.to_string(), Some(m))));
    }
    let mut references = Vec::new();
    for (mname, m) in &materials {
        let mut s = scene.clone();
        if let Some(m) = m {
            s.materials.iter_mut().for_each(|x| *x = *m);
        }
        let export = format!("mitsuba_{mname}");
        let job = Job {
            name: &export,
            ..Job::mitsuba(python, &s, &dir, e.spp, 2)
        };
        let r = job.reference([1, 2], &mask)?;
        let mean_y = mean_lum(&r.mean, &mask);
        let tm = ToneMap::Exponential {
            gamma: 1.0 / mean_y.max(1e-6) as f32,
        };
        output::image_set(&dir, &export, &r.mean, None, &tm, 0.25 * mean_y as f32)?;
        references.push((r, tm, mean_y));
    }
    for &tree in &e.trees {
        let settings = CutsBakeSettings { tree, ..e.settings };
        eprintln!(
            "eval cuts: {name}: baking {} vertices, {tree:?} light tree",
            scene.mesh.vertex_count()
        );
        let baked = crate::bake::<Cuts>(&desc, &scene, path, &settings)?;
        let Baked::Cuts(cb) = &baked else {
            unreachable!("a cuts bake")
        };
        let storage = Cuts::store(cb)?.to_bytes().len() as f64 / (1 << 20) as f64;
        let tname = format!("{tree:?}").to_lowercase();
        // The light samples' power, for the illumination cuts' lengths in the table.
        let power = sample_power(&cb.bake.samples, &scene.env)
            .map_err(|x| crate::EvalError::Options(x.to_string()))?;
        for (k, (mname, material)) in materials.iter().enumerate() {
            if k > 0 && tree != LightTreeKind::Geometric {
                continue; // edited materials: the geometric tree's bake only
            }
            let (r, tm, mean_y) = &references[k];
            for &budget in &e.light_cuts {
                let fs = CutsFrameSettings {
                    light_cut: budget,
                    material: material.map(Into::into),
                    ..Default::default()
                };
                let eval_opts = FrameOptions {
                    supersample: 4,
                    background: false,
                };
                let mut frame = baked.frame(&FrameSettings::Cuts(fs.clone()))?;
                frame.set_environment(&scene.env)?;
                let out = frame.render(&scene.camera, &eval_opts);
                let frame_ms = out.times.vertex_ms + out.times.pixel_ms;
                let mut cam512 = scene.camera;
                (cam512.width, cam512.height) = (512, 512);
                let o512 = frame.render(
                    &cam512,
                    &FrameOptions {
                        supersample: 1,
                        background: false,
                    },
                );
                let m = compare::metrics(&out.image, &r.mean, Some(&mask));
                let one_direction = {
                    let mut f = baked.frame(&FrameSettings::Cuts(CutsFrameSettings {
                        cluster_spread: false,
                        ..fs.clone()
                    }))?;
                    f.set_environment(&scene.env)?;
                    let o = f.render(&scene.camera, &eval_opts);
                    compare::metrics(&o.image, &r.mean, Some(&mask)).rel_rmse
                };
                output::image_set(
                    &dir,
                    &format!("cuts_{tname}_{mname}_lc{budget}"),
                    &out.image,
                    Some(&r.mean),
                    tm,
                    0.25 * *mean_y as f32,
                )?;
                rows.push(Row {
                    scene: name.clone(),
                    tree: tname.clone(),
                    material: mname.clone(),
                    vertices: scene.mesh.vertex_count(),
                    bake_seconds: cb.record.seconds,
                    storage_mib: storage,
                    mean_cut: cb.bake.cuts.mean_len(),
                    capped: cb.bake.cuts.capped.len(),
                    light_cut: budget,
                    light_cut_nodes: LightCut::build(&cb.bake.tree, &power, fs.light_sigma, budget)
                        .map_err(|x| crate::EvalError::Options(x.to_string()))?
                        .len(),
                    frame_ms,
                    frame_512_ms: o512.times.vertex_ms + o512.times.pixel_ms,
                    rel_rmse: m.rel_rmse,
                    rel_rmse_one_direction: one_direction,
                    mean_abs_lum_err: m.mean_abs_lum_err,
                    reference_noise: r.noise,
                });
            }
        }
    }
    Ok(())
}

/// Vertices of each scene whose visibility functions Fig. 8a's table approximates.
pub const TERMS_VERTICES: usize = 256;
/// Cube face size of its Haar functions (6 x 64 x 64 = 24,576 texels, next to the bake's
/// 32,768 light samples).
pub const TERMS_FACE: usize = 64;

/// Fig. 8a's table: mean relative L2 error per term count, and the terms the cuts need to
/// reach Haar's error.
fn terms_table(rows: &[(String, terms::TermsRow)]) -> String {
    let mut md = String::from(
        "\n## Terms against error (Fig. 8a): visibility cuts and non-linear Haar wavelets\n\n\
         Mean relative L2 error of each vertex's visibility function over 256 vertices: a cut \
         of `m` nodes refined in Eq. 6's order (largest `|C| var` first) or greedily on the \
         total error, and the `m` largest Haar coefficients of a 6 x 64 x 64 cube map; \
         `x Haar` = terms the cut needs to reach Haar's error at `m`, over `m`.\n\n\
         | scene | terms | cut, Eq. 6 order | cut, greedy | Haar | Eq. 6 cut terms / Haar's | greedy cut terms / Haar's |\n\
         |---|---|---|---|---|---|---|\n",
    );
    let ratio = |r: Option<f64>| r.map_or("-".into(), |r| format!("{r:.2}"));
    for (scene, r) in rows {
        let _ = writeln!(
            md,
            "| {scene} | {} | {} | {} | {} | {} | {} |",
            r.terms,
            output::pct(Some(r.cut_eq6)),
            output::pct(Some(r.cut_greedy)),
            output::pct(Some(r.haar)),
            ratio(r.cut_eq6_terms_ratio),
            ratio(r.cut_greedy_terms_ratio),
        );
    }
    md
}

/// The results as markdown: Fig. 9's table, then the error per light cut (Fig. 10).
fn table(rows: &[Row]) -> String {
    let mut md = String::from(
        "# Cuts (Cheslack-Postava et al. 2008) against Mitsuba 3, direct lighting\n\n\
         | scene | tree | material | vertices | bake (s) | storage (MiB) | mean cut | capped \
         | light cut | frame (ms) | 512x512 frame (ms) | rel. RMSE | one direction per cluster (--cluster-spread false) | reference noise |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.1} | {:.2} | {:.1} | {} | {} ({}) | {:.0} | {:.0} | {} | {} | {} |",
            r.scene,
            r.tree,
            r.material,
            r.vertices,
            r.bake_seconds,
            r.storage_mib,
            r.mean_cut,
            r.capped,
            r.light_cut,
            r.light_cut_nodes,
            r.frame_ms,
            r.frame_512_ms,
            output::pct(Some(r.rel_rmse)),
            output::pct(Some(r.rel_rmse_one_direction)),
            output::pct(Some(r.reference_noise)),
        );
    }
    md.push_str(
        "\nThe reference noise is half the relative RMSE between Mitsuba's two seeds: the \
         error of their mean against the truth. Materials other than `scene` were chosen \
         after the bake (`render --material`); the same bundle renders them.\n",
    );
    md
}
