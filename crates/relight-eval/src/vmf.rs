//! `relight eval --method vmf`: Laurijssen & Dutré 2009's evaluation (section 6, Tables 1-2,
//! Fig. 7 and 9), at reduced sizes.
//!
//! * **Tables 1-2**: per case (default: the teapot with Blinn-Phong exponents 4, 16, 32, 64
//!   and 128, the bunny on a diffuse plane at exponent 64, and spot at exponent 32), the
//!   initial and final vertex counts of the adaptive spatial refinement (section 4.3), the
//!   mean views per vertex of the angular refinement (section 4.2), the bake time, the size
//!   of the transfer data at 16 bits per float (the paper's Table 2 unit), the frame time of
//!   the evaluation image and of a 512 x 512 frame, and the relative RMSE against relight's
//!   path tracer with the same Blinn-Phong BRDF (`max_depth = 3`: the bake's direct lighting
//!   and one bounce), with the reference's own noise floor (the standard error of its pixel
//!   means, from the per-pixel sample variance).
//! * **The uniform-refinement comparison** (section 6.1, Fig. 7d): on the glossiest teapot,
//!   the initial mesh, the adaptive refinement and a uniform refinement of every triangle down
//!   to the adaptive's minimum area ([`uniform_refinement`]), each with its vertices, bake
//!   time and error against the same reference.
//! * **Against Mitsuba 3** (Blinn-Phong is not a Mitsuba BSDF): the first case with the GGX
//!   plastic of the `sg` evaluation instead of its materials, baked again, against Mitsuba's
//!   `roughplastic` (two seeds; their half difference is the reference noise).
//! * **Side by side with `sg`** (Green 2005): the first case baked with `sg`'s defaults,
//!   scored against the same path-traced reference: error, bake time, storage, frame times.
//!
//! Metrics are over the pixels fully covered by geometry (as every evaluation).

use crate::reference::{coverage_mask, mean_lum, mitsuba_python, stem, with_width, Job};
use crate::{output, EvalError, Result};
use relight_bake::vmf::subdivide::AdaptiveMesh;
use relight_bake::vmf::VmfBakeSettings;
use relight_method::sg::{Sg, SgSettings};
use relight_method::vmf::Vmf;
use relight_method::{Baked, FrameOptions, FrameSettings, Method, MethodKind};
use relight_render::compare;
use relight_render::pathtrace::{render_with_variance, PtSettings};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::material::Material;
use relight_scene::scene::Scene;
use relight_scene::scene_file::SceneDesc;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The example scenes of the default cases: the teapot (its exponent set per case), the
/// bunny on a diffuse plane, and spot on the same plane.
pub const DEFAULT_SCENES: [&str; 3] = ["vmf_teapot.json", "vmf_bunny.json", "vmf_spot.json"];

/// The paper's teapot exponents (Table 1).
pub const PAPER_EXPONENTS: [f32; 5] = [4.0, 16.0, 32.0, 64.0, 128.0];

/// Bytes per stored slice at 16 bits per float: 6 lobes of 7 floats (axis, kappa, RGB).
pub const SLICE_BYTES_F16: usize = 6 * 7 * 2;

/// Path-traced bounces after the first hit of the reference (`max_depth = 3`): what the bake
/// transports (direct lighting and one bounce, the paper's section 5.1).
pub const REFERENCE_MAX_DEPTH: i32 = 3;

/// One evaluated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Name in the tables and the output folder.
    pub name: String,
    /// Scene file.
    pub scene: PathBuf,
    /// Blinn-Phong exponent given to every Blinn-Phong material of the scene, if any.
    pub exponent: Option<f32>,
}

/// The default cases: the teapot at each of `exponents`, then (unless `teapot_only`) the
/// bunny and spot scenes as they are, from the folder `examples`.
///
/// # Errors
/// [`EvalError::Options`] naming a scene file that does not exist.
pub fn default_cases(examples: &Path, exponents: &[f32], teapot_only: bool) -> Result<Vec<Case>> {
    let n = if teapot_only { 1 } else { DEFAULT_SCENES.len() };
    let files = crate::reference::example_scenes(examples, &DEFAULT_SCENES[..n])?;
    let mut cases: Vec<Case> = exponents
        .iter()
        .map(|&e| Case {
            name: format!("teapot_e{e}"),
            scene: files[0].clone(),
            exponent: Some(e),
        })
        .collect();
    cases.extend(files[1..].iter().map(|f| Case {
        name: stem(f),
        scene: f.clone(),
        exponent: None,
    }));
    Ok(cases)
}

/// The cases of scene files given on the command line: each as it is.
pub fn scene_cases(scenes: &[PathBuf]) -> Vec<Case> {
    scenes
        .iter()
        .map(|s| Case {
            name: stem(s),
            scene: s.clone(),
            exponent: None,
        })
        .collect()
}

/// The bake settings of the evaluation when the command line gives none: adaptive angular
/// refinement from level 1 up to level 3 (the paper allows 5), adaptive spatial refinement
/// with the same threshold (section 6.1: "both angularly and spatially we use the same
/// threshold"), triangles split down to 1/16 of the mean area (two levels), 200 splits per
/// iteration (the paper's), 256 paths per slice, one bounce, seed 1. With `quick`: level 2 at
/// most, 1/4 of the mean area (one level), 64 paths.
pub fn eval_settings(quick: bool) -> VmfBakeSettings {
    VmfBakeSettings {
        view_level: if quick { 2 } else { 3 },
        min_view_level: 1,
        angular_threshold: 0.05,
        spatial_threshold: 0.05,
        spatial_min_area: if quick { 0.25 } else { 1.0 / 16.0 },
        spatial_batch: 200,
        paths: if quick { 64 } else { 256 },
        seed: 1,
        progress: true,
        ..Default::default()
    }
}

/// The options of `relight eval --method vmf` (with `relight bake --method vmf`'s, whose
/// defaults become [`eval_settings`]'s when not given).
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(
    feature = "cli",
    command(next_help_heading = "vMF evaluation (eval --method vmf)")
)]
pub struct VmfEvalArgs {
    /// vMF: a short run: the teapot at exponent 64 only (unless --exponents), level 2 views at
    /// most, 64 paths, one level of splits, images 128 pixels wide, no `sg` or Mitsuba.
    #[cfg_attr(feature = "cli", arg(long))]
    pub quick: bool,
    /// vMF: the teapot's Blinn-Phong exponents, comma-separated (default: the paper's 4, 16,
    /// 32, 64, 128).
    #[cfg_attr(feature = "cli", arg(long, value_delimiter = ','))]
    pub exponents: Vec<f32>,
    /// vMF: the teapot only (not the bunny and spot scenes).
    #[cfg_attr(feature = "cli", arg(long))]
    pub teapot_only: bool,
    /// vMF: skip the uniform-refinement comparison (on the teapot of the highest exponent).
    #[cfg_attr(feature = "cli", arg(long))]
    pub no_uniform: bool,
    /// vMF: skip the side-by-side `sg` bake of the first case.
    #[cfg_attr(feature = "cli", arg(long))]
    pub no_sg: bool,
    /// vMF: skip the GGX comparison against Mitsuba 3.
    #[cfg_attr(feature = "cli", arg(long))]
    pub no_mitsuba: bool,
    /// The bake's options (`relight bake --method vmf`'s; those not given take
    /// [`eval_settings`]'s values).
    #[cfg_attr(feature = "cli", command(flatten))]
    pub bake: VmfBakeSettings,
}

impl VmfEval {
    /// The evaluation of `args` and `(scenes, examples, spp, width)`: the cases (`scenes`
    /// as they are, else the defaults from `examples`), `args.bake` where `given(field)` says
    /// the command line set it and [`eval_settings`] elsewhere, `spp` for both references,
    /// the output folder `out`.
    ///
    /// # Errors
    /// [`EvalError::Options`] for a missing default scene or a bad exponent.
    pub fn from_args(
        args: &VmfEvalArgs,
        given: impl Fn(&str) -> bool,
        (scenes, examples, spp, width): (&[PathBuf], &Path, u32, Option<u32>),
        out: &Path,
    ) -> Result<VmfEval> {
        if let Some(e) = args
            .exponents
            .iter()
            .find(|e| !(e.is_finite() && **e > 0.0))
        {
            return Err(EvalError::Options(format!("--exponents: {e} is not > 0")));
        }
        let exponents = match (args.exponents.is_empty(), args.quick) {
            (false, _) => args.exponents.clone(),
            (true, true) => vec![64.0],
            (true, false) => PAPER_EXPONENTS.to_vec(),
        };
        let cases = if scenes.is_empty() {
            default_cases(examples, &exponents, args.teapot_only || args.quick)?
        } else {
            scene_cases(scenes)
        };
        let uniform_case = (!args.no_uniform).then(|| {
            let top = exponents.iter().copied().fold(f32::MIN, f32::max);
            cases
                .iter()
                .find(|c| c.exponent == Some(top))
                .unwrap_or(&cases[0])
                .name
                .clone()
        });
        Ok(VmfEval {
            settings: merge_settings(&eval_settings(args.quick), &args.bake, given),
            uniform_case: uniform_case.filter(|_| !cases.is_empty()),
            cases,
            sg: !(args.no_sg || args.quick),
            mitsuba: !(args.no_mitsuba || args.quick),
            spp,
            mitsuba_spp: spp,
            width: width.or(args.quick.then_some(128)),
            supersample: 2,
            out: out.to_path_buf(),
        })
    }
}

/// `base` with the fields of `cli` for which `given(name)` holds (clap's ids are the field
/// names), progress kept on.
///
/// # Panics
/// Never for these plain settings (serde round trip of a struct of numbers).
pub fn merge_settings(
    base: &VmfBakeSettings,
    cli: &VmfBakeSettings,
    given: impl Fn(&str) -> bool,
) -> VmfBakeSettings {
    let mut b = serde_json::to_value(base).expect("settings serialise");
    let c = serde_json::to_value(cli).expect("settings serialise");
    if let (Some(b), Some(c)) = (b.as_object_mut(), c.as_object()) {
        for (k, v) in c {
            if given(k) {
                b.insert(k.clone(), v.clone());
            }
        }
    }
    VmfBakeSettings {
        progress: true,
        ..serde_json::from_value(b).expect("the same fields")
    }
}

/// The experiment's inputs.
#[derive(Clone, Debug)]
pub struct VmfEval {
    /// The cases, in order; the first is also baked with `sg`, and with GGX for Mitsuba.
    pub cases: Vec<Case>,
    /// The vMF bake settings of every case.
    pub settings: VmfBakeSettings,
    /// The case of the uniform-refinement comparison (by name), if any.
    pub uniform_case: Option<String>,
    /// Bake the first case with `sg` too.
    pub sg: bool,
    /// Score the first case with GGX against Mitsuba 3 (needs Mitsuba).
    pub mitsuba: bool,
    /// Path-traced reference samples per pixel.
    pub spp: u32,
    /// Mitsuba samples per pixel per seed.
    pub mitsuba_spp: u32,
    /// Image width (the height keeps the camera's aspect).
    pub width: Option<u32>,
    /// Supersampling of the evaluation image (n x n samples per pixel).
    pub supersample: u32,
    /// Output folder.
    pub out: PathBuf,
}

/// One row of Tables 1-2 (or of the comparisons).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// Table: `tables`, `uniform`, `mitsuba` or `sg`.
    pub table: String,
    /// Case name.
    pub case: String,
    /// Method (`vmf` or `sg`) and variant (`adaptive`, `initial mesh`, `uniform`).
    pub variant: String,
    /// Vertices of the scene's mesh.
    pub initial_vertices: usize,
    /// Vertices of the bake (after spatial refinement).
    pub final_vertices: usize,
    /// Mean views (slices) per vertex (vmf).
    pub views_per_vertex: f64,
    /// Bake wall time, seconds.
    pub bake_seconds: f64,
    /// Transfer data at 16 bits per float, MiB (vmf: slices x 6 lobes x 7 floats).
    pub transfer_mib_f16: f64,
    /// The whole bundle written with `--f16` (mesh, scene and transfer), MiB.
    pub bundle_mib_f16: f64,
    /// Frame time of the evaluation image (supersampled), ms.
    pub frame_ms: f64,
    /// Frame time at 512 x 512, one sample per pixel, ms.
    pub frame_512_ms: f64,
    /// Relative RMSE against the reference.
    pub rel_rmse: f64,
    /// The reference's own relative noise.
    pub reference_noise: f64,
    /// The reference (`path tracer` or `Mitsuba`).
    pub reference: String,
}

/// [`VmfEval::from_args`], then [`run`]: `relight eval --method vmf`.
///
/// # Errors
/// As those two.
pub fn run_args(
    args: &VmfEvalArgs,
    given: impl Fn(&str) -> bool,
    common: (&[PathBuf], &Path, u32, Option<u32>),
    out: &Path,
) -> Result<()> {
    run(&VmfEval::from_args(args, given, common, out)?).map(drop)
}

/// Run the experiments; returns the rows (also written as results.md / results.json).
///
/// # Errors
/// Missing Mitsuba (when asked), unreadable inputs, bake, render or write failures.
pub fn run(e: &VmfEval) -> Result<Vec<Row>> {
    if e.cases.is_empty() {
        return Err(EvalError::Options("no case to evaluate".into()));
    }
    if let Some(u) = &e.uniform_case {
        if !e.cases.iter().any(|c| &c.name == u) {
            return Err(EvalError::Options(format!(
                "uniform comparison on {u}: not among the cases"
            )));
        }
    }
    let python = if e.mitsuba {
        Some(mitsuba_python()?)
    } else {
        None
    };
    output::create_dir(&e.out)?;
    let mut rows = Vec::new();
    for (k, case) in e.cases.iter().enumerate() {
        run_case(e, case, k == 0, python.as_deref(), &mut rows)?;
    }
    output::results(&e.out, &table(&rows, e), &rows)?;
    Ok(rows)
}

/// The scene of a case: its file at the evaluation's width, its exponent applied.
fn case_scene(case: &Case, width: Option<u32>) -> Result<(SceneDesc, Scene)> {
    let desc = with_width(SceneDesc::read(&case.scene)?, width);
    let mut scene = desc.build(&case.scene)?;
    if let Some(e) = case.exponent {
        set_exponent(&mut scene.materials, e);
    }
    Ok((desc, scene))
}

/// Give every Blinn-Phong material the exponent `e`.
pub fn set_exponent(materials: &mut [Material], e: f32) {
    for m in materials {
        if let Material::BlinnPhong { exponent, .. } = m {
            *exponent = e;
        }
    }
}

/// A path-traced reference of `scene` and its relative noise over `mask`: the standard error
/// of the pixel means pooled as the relative RMSE pools errors,
/// `sqrt(mean var) / sqrt(mean ref^2)`, which is the expected relative RMSE of the
/// reference against the converged image.
pub fn path_traced(scene: &Scene, spp: u32, mask: &[bool]) -> (Image, f64) {
    let caster = relight_scene::accel::build_default(&scene.mesh);
    let (img, var) = render_with_variance(
        scene,
        caster.as_ref(),
        &PtSettings {
            spp,
            max_depth: REFERENCE_MAX_DEPTH,
            seed: 7,
            show_background: false,
            progress: true,
            ..Default::default()
        },
    );
    let (mut v, mut r2) = (0.0f64, 0.0f64);
    for ((c, s), &m) in img.pixels.iter().zip(&var.pixels).zip(mask) {
        if m {
            v += (s.x + s.y + s.z) as f64;
            r2 += c.length_squared() as f64;
        }
    }
    let noise = if r2 > 0.0 { (v / r2).sqrt() } else { 0.0 };
    (img, noise)
}

/// The frame of `baked` under the scene's environment: the evaluation image
/// (`supersample`) and its time, and the 512 x 512 one-sample frame time.
fn frame(baked: &Baked, scene: &Scene, supersample: u32) -> Result<(Image, f64, f64)> {
    let kind = match baked {
        Baked::Sg(_) => MethodKind::Sg,
        _ => MethodKind::Vmf,
    };
    let mut frame = baked.frame(&FrameSettings::default_for(kind))?;
    frame.set_environment(&scene.env)?;
    let out = frame.render(
        &scene.camera,
        &FrameOptions {
            supersample,
            background: false,
        },
    );
    let mut cam512 = scene.camera;
    (cam512.width, cam512.height) = (512, 512);
    let o512 = frame.render(
        &cam512,
        &FrameOptions {
            supersample: 1,
            background: false,
        },
    );
    Ok((
        out.image,
        out.times.vertex_ms + out.times.pixel_ms,
        o512.times.vertex_ms + o512.times.pixel_ms,
    ))
}

/// What one bake of a case measured (a row without its table, case and reference).
struct Measured {
    variant: String,
    initial_vertices: usize,
    baked: Baked,
    image: Image,
    frame_ms: f64,
    frame_512_ms: f64,
}

/// Bake `scene` with vMF `settings` and render it.
fn vmf_bake(
    e: &VmfEval,
    desc: &SceneDesc,
    scene: &Scene,
    origin: &Path,
    settings: &VmfBakeSettings,
    variant: &str,
) -> Result<Measured> {
    eprintln!(
        "eval vmf: {variant}: baking {} vertices",
        scene.mesh.vertex_count()
    );
    let baked = crate::bake::<Vmf>(desc, scene, origin, settings)?;
    let (image, frame_ms, frame_512_ms) = frame(&baked, scene, e.supersample)?;
    Ok(Measured {
        variant: variant.into(),
        initial_vertices: scene.mesh.vertex_count(),
        baked,
        image,
        frame_ms,
        frame_512_ms,
    })
}

/// The row of a measured bake scored against `reference`.
fn row(
    table: &str,
    case: &str,
    m: &Measured,
    reference: (&Image, f64, &str),
    mask: &[bool],
) -> Result<Row> {
    let metrics = compare::metrics(&m.image, reference.0, Some(mask));
    let (final_vertices, views, transfer, seconds) = match &m.baked {
        Baked::Vmf(v) => (
            v.scene.mesh.vertex_count(),
            v.bake.slices.len() as f64 / v.bake.vertex_count().max(1) as f64,
            (v.bake.slices.len() * SLICE_BYTES_F16) as f64,
            v.record.seconds,
        ),
        Baked::Sg(s) => (
            s.scene.mesh.vertex_count(),
            f64::NAN,
            f64::NAN,
            s.record.seconds,
        ),
        _ => unreachable!("vmf or sg bakes only"),
    };
    const MIB: f64 = (1u64 << 20) as f64;
    Ok(Row {
        table: table.into(),
        case: case.into(),
        variant: m.variant.clone(),
        initial_vertices: m.initial_vertices,
        final_vertices,
        views_per_vertex: views,
        bake_seconds: seconds,
        transfer_mib_f16: transfer / MIB,
        bundle_mib_f16: bundle_bytes_f16(&m.baked)? as f64 / MIB,
        frame_ms: m.frame_ms,
        frame_512_ms: m.frame_512_ms,
        rel_rmse: metrics.rel_rmse,
        reference_noise: reference.1,
        reference: reference.2.into(),
    })
}

/// Bytes of the bundle of `baked` written with `--f16`.
///
/// # Errors
/// As the method's `store`.
pub fn bundle_bytes_f16(baked: &Baked) -> Result<usize> {
    Ok(match baked {
        Baked::Vmf(v) => {
            let mut v = v.clone();
            v.record.f16 = true;
            Vmf::store(&v)?.to_bytes().len()
        }
        Baked::Sg(s) => {
            let mut s = s.clone();
            s.record.f16 = true;
            Sg::store(&s)?.to_bytes().len()
        }
        _ => unreachable!("vmf or sg bakes only"),
    })
}

/// `mesh` refined uniformly to the density the adaptive refinement may reach: every triangle
/// split 1 to 4 at its edges' midpoints (section 4.3's subdivision, neighbours kept within
/// one level) while its area exceeds `min_area_fraction` of the input's mean triangle area,
/// the adaptive refinement's stopping rule without its error test (Fig. 7d's comparison).
/// The result is conforming (T-vertices resolved).
pub fn uniform_refinement(
    mesh: &relight_scene::mesh::TriMesh,
    min_area_fraction: f32,
) -> relight_scene::mesh::TriMesh {
    let mut am = AdaptiveMesh::new(mesh);
    let n = mesh.triangle_count().max(1);
    let mean = am.live().map(|t| am.area(t) as f64).sum::<f64>() / n as f64;
    let min_area = (mean * min_area_fraction as f64) as f32;
    loop {
        let big: Vec<usize> = am.live().filter(|&t| am.area(t) > min_area).collect();
        if big.is_empty() {
            break;
        }
        for t in big {
            if am.leaves[t].alive {
                am.split(t);
            }
        }
    }
    am.finish()
}

/// Bake, render and score one case, appending its rows.
fn run_case(
    e: &VmfEval,
    case: &Case,
    first: bool,
    python: Option<&Path>,
    rows: &mut Vec<Row>,
) -> Result<()> {
    let (desc, scene) = case_scene(case, e.width)?;
    let dir = e.out.join(&case.name);
    output::create_dir(&dir)?;
    let mask = coverage_mask(&scene);
    eprintln!("eval vmf: {}: path tracer, {} spp", case.name, e.spp);
    let (reference, noise) = path_traced(&scene, e.spp, &mask);
    let mean_y = mean_lum(&reference, &mask);
    let tm = ToneMap::Exponential {
        gamma: 1.0 / mean_y.max(1e-6) as f32,
    };
    let scale = 0.25 * mean_y as f32;
    output::image_set(&dir, "pathtracer", &reference, None, &tm, scale)?;
    let refr = (&reference, noise, "path tracer");
    let adaptive = vmf_bake(e, &desc, &scene, &case.scene, &e.settings, "vmf adaptive")?;
    output::image_set(&dir, "vmf", &adaptive.image, Some(&reference), &tm, scale)?;
    let adaptive_row = row("tables", &case.name, &adaptive, refr, &mask)?;
    rows.push(adaptive_row.clone());
    if e.uniform_case.as_deref() == Some(case.name.as_str()) && e.settings.spatial_threshold > 0.0 {
        let initial = VmfBakeSettings {
            spatial_threshold: 0.0,
            ..e.settings
        };
        let m = vmf_bake(e, &desc, &scene, &case.scene, &initial, "vmf initial mesh")?;
        output::image_set(&dir, "vmf_initial", &m.image, Some(&reference), &tm, scale)?;
        rows.push(row("uniform", &case.name, &m, refr, &mask)?);
        rows.push(Row {
            table: "uniform".into(),
            ..adaptive_row.clone()
        });
        let mut fine = scene.clone();
        fine.mesh = uniform_refinement(&scene.mesh, e.settings.spatial_min_area);
        // The refinement renumbers the triangles: the objects' ranges no longer hold.
        fine.objects = Vec::new();
        let m = vmf_bake(e, &desc, &fine, &case.scene, &initial, "vmf uniform")?;
        let mut r = row("uniform", &case.name, &m, refr, &mask)?;
        r.initial_vertices = scene.mesh.vertex_count();
        output::image_set(&dir, "vmf_uniform", &m.image, Some(&reference), &tm, scale)?;
        rows.push(r);
    }
    if first && e.sg {
        let settings = SgSettings {
            bake: relight_bake::sg::SgBakeSettings {
                seed: 1,
                ..Default::default()
            },
            blend: None,
        };
        eprintln!("eval vmf: {}: sg bake", case.name);
        let baked = crate::bake::<Sg>(&desc, &scene, &case.scene, &settings)?;
        let (image, frame_ms, frame_512_ms) = frame(&baked, &scene, e.supersample)?;
        output::image_set(&dir, "sg", &image, Some(&reference), &tm, scale)?;
        let m = Measured {
            variant: "sg (Green 2005), defaults".into(),
            initial_vertices: scene.mesh.vertex_count(),
            baked,
            image,
            frame_ms,
            frame_512_ms,
        };
        rows.push(Row {
            table: "sg".into(),
            ..adaptive_row.clone()
        });
        rows.push(row("sg", &case.name, &m, refr, &mask)?);
    }
    if let (true, Some(python)) = (first, python) {
        let mut ggx = scene.clone();
        ggx.materials
            .iter_mut()
            .for_each(|m| *m = crate::sg::PLASTIC);
        let job = Job::mitsuba(python, &ggx, &dir, e.mitsuba_spp, REFERENCE_MAX_DEPTH);
        let r = job.reference([1, 2], &mask)?;
        let y = mean_lum(&r.mean, &mask);
        let tm = ToneMap::Exponential {
            gamma: 1.0 / y.max(1e-6) as f32,
        };
        output::image_set(&dir, "mitsuba_ggx", &r.mean, None, &tm, 0.25 * y as f32)?;
        let m = vmf_bake(
            e,
            &desc,
            &ggx,
            &case.scene,
            &e.settings,
            "vmf adaptive, GGX plastic",
        )?;
        output::image_set(
            &dir,
            "vmf_ggx",
            &m.image,
            Some(&r.mean),
            &tm,
            0.25 * y as f32,
        )?;
        rows.push(row(
            "mitsuba",
            &case.name,
            &m,
            (&r.mean, r.noise, "Mitsuba 3"),
            &mask,
        )?);
    }
    Ok(())
}

/// A number with two decimals, `-` when it is not one (`sg` has no vMF transfer).
struct Num(f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_finite() {
            write!(f, "{:.2}", self.0)
        } else {
            f.write_str("-")
        }
    }
}

/// The results as markdown: one table per comparison.
fn table(rows: &[Row], e: &VmfEval) -> String {
    let s = &e.settings;
    let mut md = format!(
        "# vMF (Laurijssen & Dutré 2009): Tables 1-2 and the comparisons\n\n\
         Bake: view levels {}..={} (angular threshold {}), spatial threshold {} down to {} of \
         the mean triangle area in batches of {}, {} paths per slice, {} bounce(s). Frames: \
         {n} x {n} samples per pixel; 512 x 512 at one. Transfer at 16 bits per float: slices \
         x 6 lobes x 7 floats (the paper's Table 2 unit). Errors: relative RMSE over the \
         covered pixels; the reference noise is the reference's own expected relative RMSE.\n",
        s.min_view_level,
        s.view_level,
        s.angular_threshold,
        s.spatial_threshold,
        s.spatial_min_area,
        s.spatial_batch,
        s.paths,
        s.max_bounces,
        n = e.supersample
    );
    for (t, title) in [
        (
            "tables",
            "Tables 1-2: the cases against relight's path tracer (same Blinn-Phong BRDF)",
        ),
        (
            "uniform",
            "Adaptive against uniform spatial refinement (section 6.1, Fig. 7d)",
        ),
        (
            "sg",
            "Side by side with sg (Green 2005) on the same scene and reference",
        ),
        ("mitsuba", "GGX plastic against Mitsuba 3 (roughplastic)"),
    ] {
        let sel: Vec<&Row> = rows.iter().filter(|r| r.table == t).collect();
        if sel.is_empty() {
            continue;
        }
        let _ = write!(
            md,
            "\n## {title}\n\n| case | variant | initial vertices | final vertices | views per vertex | bake (s) | transfer, f16 (MiB) | bundle, f16 (MiB) | frame (ms) | 512x512 frame (ms) | rel. RMSE | reference | reference noise |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
        );
        for r in sel {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {:.1} | {} | {:.2} | {:.0} | {:.0} | {} | {} | {} |",
                r.case,
                r.variant,
                r.initial_vertices,
                r.final_vertices,
                if r.views_per_vertex.is_finite() {
                    format!("{:.1}", r.views_per_vertex)
                } else {
                    "-".into()
                },
                r.bake_seconds,
                Num(r.transfer_mib_f16),
                r.bundle_mib_f16,
                r.frame_ms,
                r.frame_512_ms,
                output::pct(Some(r.rel_rmse)),
                r.reference,
                output::pct(Some(r.reference_noise)),
            );
        }
    }
    md
}

#[cfg(test)]
mod tests;
