//! `relight demo`: the built-in demo (no downloads).
//!
//! A procedural scene (a sphere and a box on a ground plane) under the procedural sun and sky
//! is baked once with diffuse SH PRT (shadowed + one interreflection bounce), then relit under
//! the sky rotated to several angles without re-baking. Each relit frame is compared with the
//! reference path tracer at the same depth (max_depth 3: direct + one bounce). Writes the
//! images, a contact sheet PNG and an HTML report, and prints where.

use crate::bake::bake_scene;
use crate::common::{describe_tonemap, write_image};
use crate::hybrid::{relight_hybrid, HybridOpts};
use crate::render::relight;
use anyhow::{Context, Result};
use relight_bake::sh::{ShBakeSettings, ShTransferKind};
use relight_render::compare::{self, Metrics};
use relight_render::pathtrace::{self, PtSettings};
use relight_render::tonemap::ToneMap;
use relight_render::Image;
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::scene_file::{EnvDesc, SceneDesc, ShapeDesc};
use relight_sphere::sh::Window;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `relight demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Image width (height is 3/4 of it).
    #[arg(long, default_value_t = 320)]
    pub width: u32,
    /// Path-tracer samples per pixel for the references.
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// SH order of the bake.
    #[arg(long, default_value_t = 6)]
    pub order: usize,
    /// Directions per vertex of the bake.
    #[arg(long, default_value_t = 1024)]
    pub samples: u32,
}

/// The demo scene: a sphere and a box on a ground plane under the procedural sky.
pub fn demo_scene(width: u32) -> SceneDesc {
    let lambert = |r: f32, g: f32, b: f32| {
        Some(Material::Lambert {
            albedo: glam::Vec3::new(r, g, b),
        })
    };
    SceneDesc {
        shapes: vec![
            ShapeDesc::Plane {
                center: [0.0, 0.0, 0.0],
                size: 6.0,
                divisions: Some(64),
                material: lambert(0.6, 0.6, 0.6),
            },
            ShapeDesc::Sphere {
                center: [-0.6, 0.55, 0.0],
                radius: 0.55,
                rings: Some(48),
                material: lambert(0.8, 0.25, 0.2),
            },
            ShapeDesc::Box {
                min: [0.25, 0.0, -0.55],
                max: [1.15, 0.9, 0.35],
                material: lambert(0.25, 0.45, 0.8),
            },
        ],
        environment: EnvDesc::Sky {
            sun_elevation_deg: 35.0,
            sun_azimuth_deg: 60.0,
            turbidity: 3.0,
            ground_albedo: [0.3, 0.3, 0.3],
            rotate_y_deg: None,
        },
        camera: Camera {
            origin: [0.6, 2.2, 4.2],
            target: [0.1, 0.35, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_deg: 45.0,
            width,
            height: width * 3 / 4,
        },
    }
}

struct Row {
    rotate: f32,
    prt: Image,
    hybrid: Image,
    reference: Image,
    metrics: Metrics,
    hybrid_metrics: Metrics,
    lights: usize,
    relight_ms: f64,
    reference_s: f64,
}

/// Run the demo.
pub fn run(a: Args) -> Result<()> {
    let t_start = Instant::now();
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let desc = demo_scene(a.width);
    let origin = Path::new("<built-in demo scene>");
    let scene = desc.build(origin)?;
    eprintln!(
        "demo: scene with {} vertices, {} triangles under the procedural sky",
        scene.mesh.vertex_count(),
        scene.mesh.triangle_count()
    );
    let settings = ShBakeSettings {
        order: a.order,
        samples: a.samples,
        seed: 1,
        kind: ShTransferKind::Interreflected { bounces: 1 },
        threads: None,
        progress: true,
    };
    let backend = crate::bake::parse_backend(None)?;
    let baked = bake_scene(&desc, &scene, &settings, backend, false, origin)?;
    let bundle_path = a.out.join("demo.relight");
    baked.to_bundle()?.write(&bundle_path)?;
    eprintln!(
        "demo: baked in {:.1} s -> {}",
        baked.settings.seconds,
        bundle_path.display()
    );

    let caster = relight_scene::accel::build_default(&scene.mesh);
    // Exposure from the unrotated reference: its mean pixel luminance maps to display 0.5
    // under the thesis' exponential tone map (1 - exp(-gamma Y) = 0.5).
    let mut tm = ToneMap::Exponential { gamma: 1.0 };
    let mut rows = Vec::new();
    for rotate in [0.0f32, 120.0, 240.0] {
        let mut env = scene.env.clone();
        env.rotate_y_deg = rotate;
        let (prt, times) = relight(&baked, &env, &scene.camera, Window::None, 2, true);
        let (hybrid, htimes, dec) =
            relight_hybrid(&baked, &env, &scene.camera, &HybridOpts::default(), 2, true)?;
        let mut s = scene.clone();
        s.env = env;
        let t0 = Instant::now();
        let reference = pathtrace::render(
            &s,
            caster.as_ref(),
            &PtSettings {
                spp: a.spp,
                max_depth: 3,
                seed: 7,
                threads: None,
                show_background: true,
                progress: true,
            },
        );
        let reference_s = t0.elapsed().as_secs_f64();
        let metrics = compare::metrics(&prt, &reference, None);
        let hybrid_metrics = compare::metrics(&hybrid, &reference, None);
        if rows.is_empty() {
            let mean_y = reference
                .pixels
                .iter()
                .map(|&c| compare::luminance(c) as f64)
                .sum::<f64>()
                / reference.pixels.len() as f64;
            if mean_y > 0.0 {
                tm = ToneMap::Exponential {
                    gamma: (std::f64::consts::LN_2 / mean_y) as f32,
                };
            }
        }
        let tag = format!("rot{rotate:03.0}");
        write_image(&a.out.join(format!("prt_{tag}.exr")), &prt, &tm)?;
        write_image(&a.out.join(format!("prt_{tag}.png")), &prt, &tm)?;
        write_image(&a.out.join(format!("hybrid_{tag}.exr")), &hybrid, &tm)?;
        write_image(&a.out.join(format!("hybrid_{tag}.png")), &hybrid, &tm)?;
        relight_scene::io::image::write_png_srgb8(
            &a.out.join(format!("hybrid_error_{tag}.png")),
            hybrid.width,
            hybrid.height,
            &compare::heatmap(&hybrid, &reference),
        )?;
        write_image(&a.out.join(format!("reference_{tag}.exr")), &reference, &tm)?;
        write_image(&a.out.join(format!("reference_{tag}.png")), &reference, &tm)?;
        relight_scene::io::image::write_png_srgb8(
            &a.out.join(format!("error_{tag}.png")),
            prt.width,
            prt.height,
            &compare::heatmap(&prt, &reference),
        )?;
        eprintln!(
            "demo: sky rotated {rotate:>5.1} deg: SH relight {:.2} ms, hybrid {:.0} ms ({} lights), reference {:.1} s; relative RMSE SH {:.1} %, hybrid {:.1} %",
            times.shade_ms,
            htimes.decompose_ms + htimes.shade_ms + htimes.render_ms,
            dec.lights.len(),
            reference_s,
            100.0 * metrics.rel_rmse,
            100.0 * hybrid_metrics.rel_rmse
        );
        rows.push(Row {
            rotate,
            prt,
            hybrid,
            reference,
            metrics,
            hybrid_metrics,
            lights: dec.lights.len(),
            relight_ms: times.shade_ms,
            reference_s,
        });
    }
    let sheet = a.out.join("contact_sheet.png");
    write_contact_sheet(&sheet, &rows, &tm, a.order, a.spp)?;
    let report = a.out.join("report.html");
    write_report(
        &report,
        &a,
        &baked,
        &rows,
        &tm,
        t_start.elapsed().as_secs_f64(),
    )?;
    println!("contact sheet: {}", sheet.display());
    println!("report:        {}", report.display());
    Ok(())
}

/// Rows of (PRT | reference | error heat map), 4-pixel gaps, dark grey background, labelled.
fn write_contact_sheet(
    path: &Path,
    rows: &[Row],
    tm: &ToneMap,
    order: usize,
    spp: u32,
) -> Result<()> {
    let (w, h) = (rows[0].prt.width, rows[0].prt.height);
    let gap = 4;
    let (sw, sh) = (5 * w + 6 * gap, rows.len() * h + (rows.len() + 1) * gap);
    let mut px = vec![[40u8, 40, 40]; sw * sh];
    for (r, row) in rows.iter().enumerate() {
        let panels = [
            tm.to_srgb8(&row.prt),
            tm.to_srgb8(&row.hybrid),
            tm.to_srgb8(&row.reference),
            compare::heatmap(&row.prt, &row.reference),
            compare::heatmap(&row.hybrid, &row.reference),
        ];
        let labels = [
            format!(
                "SH PRT ORDER {order}, SKY {:.0}°, {:.1} MS",
                row.rotate, row.relight_ms
            ),
            format!("HYBRID, {} LIGHTS", row.lights),
            format!("PATH TRACED {spp} SPP, {:.1} S", row.reference_s),
            format!("SH ERROR, REL. RMSE {:.1}%", 100.0 * row.metrics.rel_rmse),
            format!(
                "HYBRID ERROR, REL. RMSE {:.1}%",
                100.0 * row.hybrid_metrics.rel_rmse
            ),
        ];
        for (c, (panel, label)) in panels.iter().zip(&labels).enumerate() {
            let (x0, y0) = (gap + c * (w + gap), gap + r * (h + gap));
            let mut panel = panel.clone();
            let scale = if w >= 480 { 2 } else { 1 };
            relight_render::text::draw_label(&mut panel, w, 3, 3, scale, label);
            for y in 0..h {
                px[(y0 + y) * sw + x0..(y0 + y) * sw + x0 + w]
                    .copy_from_slice(&panel[y * w..(y + 1) * w]);
            }
        }
    }
    relight_scene::io::image::write_png_srgb8(path, sw, sh, &px)?;
    Ok(())
}

fn write_report(
    path: &Path,
    a: &Args,
    baked: &crate::store::ShBake,
    rows: &[Row],
    tm: &ToneMap,
    total_s: f64,
) -> Result<()> {
    let mut h = String::new();
    let s = &baked.settings;
    let _ = write!(
        h,
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>relight demo</title>\
<style>body{{font-family:sans-serif;margin:2em;background:#fafafa}}td,th{{padding:4px 10px;text-align:right}}\
img{{image-rendering:pixelated;margin:2px}}</style></head><body>\
<h1>relight demo</h1>\
<p>A sphere and a box on a ground plane under the procedural Preetham sun and sky, baked once with \
diffuse SH PRT (order {order}, {samples} directions per vertex, shadowed + {bounces} interreflection bounce, \
{verts} vertices, {backend}, {secs:.1} s), then relit under the sky rotated about +Y without re-baking. \
Ground truth: relight's reference path tracer at {spp} spp, max_depth 3 (direct + one bounce, as the bake).</p>\
<p>Tone map of the PNGs: {tm}. Heat maps: absolute luminance error, colour ramp scaled to the reference's \
mean luminance (see <code>relight_render::compare::heatmap</code>). Metrics over all pixels, background included \
(identical in both, so it dilutes the error a little). A 9..36-coefficient SH cannot hold the sun's 0.53 degree disc: \
sharp sun shadows are blurred and ring. The <code>hybrid</code> column (work in progress, issue 3) extracts the sun from the \
environment as a cap light with a soft shadow map and keeps SH PRT for the rest; its sun light is direct only (no bounce), \
so it is a little dark where the reference has sunlight reflected by the ground.</p>",
        order = s.order,
        samples = s.samples,
        bounces = s.bounces,
        verts = baked.mesh.vertex_count(),
        backend = s.backend,
        secs = s.seconds,
        spp = a.spp,
        tm = describe_tonemap(tm),
    );
    h.push_str("<table><tr><th>sky rotation</th><th>method</th><th>relight (ms)</th><th>reference (s)</th><th>relative RMSE</th><th>RMSE</th><th>PSNR (dB)</th><th>mean |ΔY| (Table 5.1)</th><th>std |ΔY|</th></tr>");
    for r in rows {
        for (name, m, ms) in [
            ("SH PRT", &r.metrics, format!("{:.2}", r.relight_ms)),
            ("hybrid", &r.hybrid_metrics, format!("{} lights", r.lights)),
        ] {
            let _ = write!(
                h,
                "<tr><td>{:.0}°</td><td>{name}</td><td>{ms}</td><td>{:.1}</td><td>{:.2} %</td><td>{:.4}</td><td>{:.1}</td><td>{:.4}</td><td>{:.4}</td></tr>",
                r.rotate, r.reference_s, 100.0 * m.rel_rmse, m.rmse, m.psnr, m.mean_abs_lum_err, m.std_abs_lum_err
            );
        }
    }
    h.push_str("</table><h2>SH PRT | hybrid (SH + sun with shadow map) | path-traced reference | SH error | hybrid error</h2>");
    for r in rows {
        let tag = format!("rot{:03.0}", r.rotate);
        let _ = write!(
            h,
            "<p>sky rotated {:.0}°<br><img src=\"prt_{tag}.png\"><img src=\"hybrid_{tag}.png\"><img src=\"reference_{tag}.png\"><img src=\"error_{tag}.png\"><img src=\"hybrid_error_{tag}.png\"></p>",
            r.rotate
        );
    }
    let _ = write!(
        h,
        "<p>Contact sheet: <a href=\"contact_sheet.png\">contact_sheet.png</a>. Bundle: <code>demo.relight</code> \
(try <code>relight info</code> and <code>relight render demo.relight --rotate-env 45 -o x.png</code>). \
Total demo time {total_s:.1} s.</p></body></html>"
    );
    relight_bundle::write_atomic(path, h.as_bytes())?;
    Ok(())
}
