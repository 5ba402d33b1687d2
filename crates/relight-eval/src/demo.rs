//! `relight demo`: the built-in demo (no downloads), every method against the path tracer.
//!
//! * **Diffuse scene** (a sphere and a box on a ground plane, Lambert) under the procedural
//!   sun and sky, baked once with diffuse SH PRT (shadowed + one interreflection bounce), then
//!   relit under the sky rotated to several angles without re-baking, with the `sh` and
//!   `hybrid` frames. Ground truth: the reference path tracer at max_depth 3 (direct + one
//!   bounce, as the bake).
//! * **Glossy scene** (a GGX conductor sphere on a small Lambert floor) baked once with `sg`
//!   (Green 2005: one direct lobe per view, no indirect component) and relit under the same
//!   rotations; ground truth at max_depth 2 (direct lighting: what a direct-only SG bake
//!   holds). The sky's sun is the hard case of SG (a 0.5-degree source behind a Gaussian
//!   prefilter), so the error shown is honest, not flattering.
//!
//! Writes the images, a contact sheet PNG and an HTML report, and prints where.

mod report;

use crate::{output, Result};
use glam::Vec3;
use relight_bake::sg::SgBakeSettings;
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_method::hybrid::HybridFrame;
use relight_method::sg::{Sg, SgSettings};
use relight_method::sh::Sh;
use relight_method::{Baked, Frame, FrameOptions, FrameSettings, Method, MethodKind};
use relight_render::compare::{self, Metrics};
use relight_render::pathtrace::{self, PtSettings};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::camera::Camera;
use relight_scene::material::maps::MaterialDesc;
use relight_scene::material::Material;
use relight_scene::scene::Scene;
use relight_scene::scene_file::{EnvDesc, SceneDesc, ShapeDesc};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The demo's options.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    /// Output folder.
    pub out: PathBuf,
    /// Image width (height is 3/4 of it).
    pub width: u32,
    /// Path-tracer samples per pixel of the references.
    pub spp: u32,
    /// SH order of the `sh` bake.
    pub sh_order: usize,
    /// Directions per vertex of the `sh` bake.
    pub samples: u32,
}

/// The sky of both scenes.
fn sky() -> EnvDesc {
    EnvDesc::Sky {
        sun_elevation_deg: 35.0,
        sun_azimuth_deg: 60.0,
        turbidity: 3.0,
        ground_albedo: [0.3, 0.3, 0.3],
        rotate_y_deg: None,
    }
}

fn lambert(r: f32, g: f32, b: f32) -> Option<MaterialDesc> {
    Some(
        Material::Lambert {
            albedo: Vec3::new(r, g, b),
        }
        .into(),
    )
}

/// The camera of both scenes, `width` pixels wide.
fn camera(width: u32) -> Camera {
    Camera {
        origin: [0.6, 2.2, 4.2],
        target: [0.1, 0.35, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_deg: 45.0,
        width,
        height: width * 3 / 4,
    }
}

/// The diffuse scene: a sphere and a box on a ground plane under the procedural sky.
pub fn demo_scene(width: u32) -> SceneDesc {
    SceneDesc {
        shapes: vec![
            ShapeDesc::Plane {
                center: [0.0, 0.0, 0.0],
                size: 6.0,
                divisions: Some(64),
                material: lambert(0.6, 0.6, 0.6),
                name: None,
            },
            ShapeDesc::Sphere {
                center: [-0.6, 0.55, 0.0],
                radius: 0.55,
                rings: Some(48),
                material: lambert(0.8, 0.25, 0.2),
                name: None,
            },
            ShapeDesc::Box {
                min: [0.25, 0.0, -0.55],
                max: [1.15, 0.9, 0.35],
                material: lambert(0.25, 0.45, 0.8),
                name: None,
            },
        ],
        environment: sky(),
        camera: camera(width),
    }
}

/// The glossy scene: a gold-coloured GGX conductor sphere (alpha 0.25) on a Lambert floor.
/// Small (about 1,900 vertices) so that its SG bake (92 views per vertex) takes about a
/// minute on 2 cores.
pub fn glossy_scene(width: u32) -> SceneDesc {
    SceneDesc {
        shapes: vec![
            ShapeDesc::Plane {
                center: [0.0, 0.0, 0.0],
                size: 4.0,
                divisions: Some(16),
                material: lambert(0.6, 0.6, 0.6),
                name: None,
            },
            ShapeDesc::Sphere {
                center: [0.0, 0.7, 0.0],
                radius: 0.7,
                rings: Some(28),
                material: Some(
                    Material::GgxConductor {
                        specular: Vec3::new(0.95, 0.78, 0.45),
                        alpha: 0.25,
                    }
                    .into(),
                ),
                name: None,
            },
        ],
        environment: sky(),
        camera: camera(width),
    }
}

/// One relit frame beside its reference.
struct Panel {
    name: &'static str,
    image: Image,
    metrics: Metrics,
    note: String,
}

/// One sky rotation: the reference of each scene and the panels of the methods.
struct Row {
    rotate: f32,
    reference: Image,
    glossy_reference: Image,
    panels: Vec<Panel>,
    reference_s: f64,
}

/// Bake `desc` with `M`, printing what it took.
fn bake<M: Method>(desc: &SceneDesc, scene: &Scene, settings: &M::Settings) -> Result<Baked>
where
    Baked: From<M::Baked>,
{
    let b = crate::bake::<M>(desc, scene, Path::new("<built-in demo scene>"), settings)?;
    eprintln!(
        "demo: {} bake of {} vertices in {:.1} s",
        b.kind().name(),
        scene.mesh.vertex_count(),
        b.record().seconds
    );
    Ok(b)
}

/// Path-trace `scene` at `max_depth` (Mitsuba semantics).
fn path_trace(scene: &Scene, spp: u32, max_depth: i32) -> Image {
    let caster = relight_scene::accel::build_default(&scene.mesh);
    pathtrace::render(
        scene,
        caster.as_ref(),
        &PtSettings {
            spp,
            max_depth,
            seed: 7,
            threads: None,
            show_background: true,
            progress: true,
        },
    )
}

/// A frame's image and its time.
fn render(frame: &mut dyn Frame, scene: &Scene) -> Result<(Image, f64)> {
    let prep = frame.set_environment(&scene.env)?;
    let opts = FrameOptions {
        supersample: 2,
        background: true,
    };
    let out = frame.render(&scene.camera, &opts);
    let ms = prep.environment_ms + prep.shade_ms + out.times.vertex_ms + out.times.pixel_ms;
    Ok((out.image, ms))
}

/// Run the demo; returns the contact sheet and report paths.
///
/// # Errors
/// An output folder that cannot be written.
pub fn run(o: &DemoOptions) -> Result<(PathBuf, PathBuf)> {
    if !(16..=4096).contains(&o.width) || o.spp == 0 {
        return Err(crate::EvalError::Options(format!(
            "demo: --width {} must be in 16..=4096 and --spp {} at least 1",
            o.width, o.spp
        )));
    }
    let t_start = Instant::now();
    output::create_dir(&o.out)?;
    let origin = Path::new("<built-in demo scene>");
    let desc = demo_scene(o.width);
    let scene = desc.build(origin)?;
    let gdesc = glossy_scene(o.width);
    let gscene = gdesc.build(origin)?;
    eprintln!(
        "demo: diffuse scene {} vertices, glossy scene {} vertices, under the procedural sky",
        scene.mesh.vertex_count(),
        gscene.mesh.vertex_count()
    );
    let sh_settings = ShBakeSettings {
        order: o.sh_order,
        samples: o.samples,
        seed: 1,
        transfer: ShTransferKind::Interreflected,
        bounces: 1,
        ..Default::default()
    };
    let sh = bake::<Sh>(&desc, &scene, &sh_settings)?;
    sh.write(&o.out.join("demo.relight"))?;
    // The lobes `relight bake` chooses for the scene's materials (a GGX conductor: the
    // half-vector GGX lobes).
    let (sg_settings, _) = SgSettings {
        bake: SgBakeSettings {
            indirect_lobes: 0,
            seed: 1,
            ..Default::default()
        },
        blend: None,
    }
    .with_lobes_for(&gscene.materials);
    let sg = bake::<Sg>(&gdesc, &gscene, &sg_settings)?;
    sg.write(&o.out.join("demo_sg.relight"))?;
    let Baked::Sh(sh_baked) = &sh else {
        unreachable!("an sh bake")
    };
    let mut sh_frame = sh.frame(&FrameSettings::default_for(MethodKind::Sh))?;
    let mut hybrid_frame = HybridFrame::new(sh_baked, &Default::default())?;
    let mut sg_frame = sg.frame(&FrameSettings::default_for(MethodKind::Sg))?;
    let mut rows = Vec::new();
    let mut tm = ToneMap::default();
    for rotate in [0.0f32, 120.0, 240.0] {
        let (mut s, mut g) = (scene.clone(), gscene.clone());
        s.env.rotate_y_deg = rotate;
        g.env.rotate_y_deg = rotate;
        let t0 = Instant::now();
        let reference = path_trace(&s, o.spp, 3);
        let glossy_reference = path_trace(&g, o.spp, 2);
        let reference_s = t0.elapsed().as_secs_f64();
        if rows.is_empty() {
            // One exposure for every panel: the automatic exposure of the unrotated reference
            // (`relight render`'s rule).
            tm = ToneMap::auto(&reference);
        }
        let (sh_img, sh_ms) = render(sh_frame.as_mut(), &s)?;
        let (hy_img, hy_ms) = render(&mut hybrid_frame, &s)?;
        let lights = hybrid_frame.decomposition().map_or(0, |d| d.lights.len());
        let (sg_img, sg_ms) = render(sg_frame.as_mut(), &g)?;
        let panel = |name, image: Image, reference: &Image, note: String| Panel {
            name,
            metrics: compare::metrics(&image, reference, None),
            image,
            note,
        };
        let panels = vec![
            panel("sh", sh_img, &reference, format!("{sh_ms:.0} MS")),
            panel(
                "hybrid",
                hy_img,
                &reference,
                format!("{lights} LIGHTS, {hy_ms:.0} MS"),
            ),
            panel("sg", sg_img, &glossy_reference, format!("{sg_ms:.0} MS")),
        ];
        eprintln!(
            "demo: sky rotated {rotate:>5.1} deg: references {reference_s:.1} s; relative RMSE sh {:.1} %, hybrid {:.1} % ({lights} lights), sg {:.1} %",
            100.0 * panels[0].metrics.rel_rmse,
            100.0 * panels[1].metrics.rel_rmse,
            100.0 * panels[2].metrics.rel_rmse
        );
        rows.push(Row {
            rotate,
            reference,
            glossy_reference,
            panels,
            reference_s,
        });
    }
    report::images(&o.out, &rows, &tm)?;
    let sheet = o.out.join("contact_sheet.png");
    report::contact_sheet(&sheet, &rows, &tm, o)?;
    let html = o.out.join("report.html");
    report::html(
        &html,
        o,
        &sh,
        &sg,
        &rows,
        &tm,
        t_start.elapsed().as_secs_f64(),
    )?;
    Ok((sheet, html))
}
