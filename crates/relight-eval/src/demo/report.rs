//! The demo's outputs: images per method and rotation, a labelled contact sheet, an HTML
//! report.

use super::{DemoOptions, Row};
use crate::{output, Result};
use relight_method::Baked;
use relight_render::compare;
use relight_render::text::draw_label;
use relight_render::tonemap::ToneMap;
use std::fmt::Write as _;
use std::path::Path;

fn tag(rotate: f32) -> String {
    format!("rot{rotate:03.0}")
}

/// `<method>_rotNNN.{png,exr}`, `<method>_error_rotNNN.png`, `reference_rotNNN.*` and
/// `glossy_reference_rotNNN.*`.
pub(super) fn images(out: &Path, rows: &[Row], tm: &ToneMap) -> Result<()> {
    for r in rows {
        let t = tag(r.rotate);
        for (name, img) in [
            ("reference", &r.reference),
            ("glossy_reference", &r.glossy_reference),
        ] {
            output::image(&out.join(format!("{name}_{t}.png")), img, tm)?;
            output::image(&out.join(format!("{name}_{t}.exr")), img, tm)?;
        }
        for p in &r.panels {
            let reference = if p.name == "sg" {
                &r.glossy_reference
            } else {
                &r.reference
            };
            output::image(&out.join(format!("{}_{t}.png", p.name)), &p.image, tm)?;
            output::image(&out.join(format!("{}_{t}.exr", p.name)), &p.image, tm)?;
            relight_scene::io::image::write_png_srgb8(
                &out.join(format!("{}_error_{t}.png", p.name)),
                p.image.width,
                p.image.height,
                &compare::heatmap(&p.image, reference),
            )?;
        }
    }
    Ok(())
}

/// Two lines per rotation, 5 panels wide, labelled: SH | hybrid | path traced | SH error |
/// hybrid error, then SG | path traced (glossy) | SG error.
pub(super) fn contact_sheet(
    path: &Path,
    rows: &[Row],
    tm: &ToneMap,
    o: &DemoOptions,
) -> Result<()> {
    let (w, h) = (rows[0].reference.width, rows[0].reference.height);
    let gap = 4;
    let lines = 2 * rows.len();
    let (sw, sh) = (5 * w + 6 * gap, lines * h + (lines + 1) * gap);
    let mut px = vec![[40u8, 40, 40]; sw * sh];
    let scale = if w >= 480 { 2 } else { 1 };
    for (r, row) in rows.iter().enumerate() {
        let [s, hy, sg] = [&row.panels[0], &row.panels[1], &row.panels[2]];
        let err = |p: &super::Panel| {
            format!(
                "{} ERROR, REL. RMSE {:.1}%",
                p.name.to_uppercase(),
                100.0 * p.metrics.rel_rmse
            )
        };
        let line0: Vec<(Vec<[u8; 3]>, String)> = vec![
            (
                tm.to_srgb8(&s.image),
                format!(
                    "SH PRT ORDER {}, SKY {:.0}°, {}",
                    o.sh_order, row.rotate, s.note
                ),
            ),
            (tm.to_srgb8(&hy.image), format!("HYBRID, {}", hy.note)),
            (
                tm.to_srgb8(&row.reference),
                format!("PATH TRACED {} SPP", o.spp),
            ),
            (compare::heatmap(&s.image, &row.reference), err(s)),
            (compare::heatmap(&hy.image, &row.reference), err(hy)),
        ];
        let line1 = vec![
            (
                tm.to_srgb8(&sg.image),
                format!("SG (GLOSSY), 1 LOBE, {}", sg.note),
            ),
            (
                tm.to_srgb8(&row.glossy_reference),
                format!("PATH TRACED {} SPP, DIRECT", o.spp),
            ),
            (compare::heatmap(&sg.image, &row.glossy_reference), err(sg)),
        ];
        for (l, line) in [line0, line1].into_iter().enumerate() {
            for (c, (mut panel, label)) in line.into_iter().enumerate() {
                let (x0, y0) = (gap + c * (w + gap), gap + (2 * r + l) * (h + gap));
                draw_label(&mut panel, w, 3, 3, scale, &label);
                for y in 0..h {
                    px[(y0 + y) * sw + x0..(y0 + y) * sw + x0 + w]
                        .copy_from_slice(&panel[y * w..(y + 1) * w]);
                }
            }
        }
    }
    relight_scene::io::image::write_png_srgb8(path, sw, sh, &px)?;
    Ok(())
}

/// The HTML report.
pub(super) fn html(
    path: &Path,
    o: &DemoOptions,
    sh: &Baked,
    sg: &Baked,
    rows: &[Row],
    tm: &ToneMap,
    total_s: f64,
) -> Result<()> {
    let mut h = String::new();
    let (shr, sgr) = (sh.record(), sg.record());
    let _ = write!(
        h,
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>relight demo</title>\
<style>body{{font-family:sans-serif;margin:2em;background:#fafafa}}td,th{{padding:4px 10px;text-align:right}}\
img{{image-rendering:pixelated;margin:2px}}</style></head><body>\
<h1>relight demo</h1>\
<p><b>Diffuse scene</b>: a sphere and a box on a ground plane under the procedural Preetham sun and sky, baked once with \
diffuse SH PRT (order {order}, {samples} directions per vertex, shadowed + 1 interreflection bounce, \
{verts} vertices, {backend}, {secs:.1} s), then relit under the sky rotated about +Y without re-baking, by the \
<code>sh</code> frame and the <code>hybrid</code> frame (the sun extracted as a cap light with a soft shadow map, SH \
PRT for the rest; its lights are direct only, so it is a little dark where the reference has sunlight reflected by the \
ground). Ground truth: relight's reference path tracer at {spp} spp, max_depth 3 (direct + one bounce, as the bake).</p>\
<p><b>Glossy scene</b>: a GGX conductor sphere (alpha 0.25) on a floor, baked once with <code>sg</code> (Green 2005: \
92 views per vertex, one Gaussian per view, diffuse SH order 5; {gverts} vertices, {gsecs:.1} s), relit the same way. \
Ground truth at max_depth 2 (direct lighting, as the bake). The sun is SG's hard case: a 0.5-degree source seen through \
the Gaussian-prefiltered environment.</p>\
<p>Tone map of the PNGs: {tm}. Heat maps: absolute luminance error, colour ramp scaled to the reference's mean \
luminance (see <code>relight_render::compare::heatmap</code>). Metrics over all pixels, background included \
(identical in both, so it dilutes the error a little).</p>",
        order = o.sh_order,
        samples = o.samples,
        verts = sh.scene().mesh.vertex_count(),
        backend = shr.backend,
        secs = shr.seconds,
        gverts = sg.scene().mesh.vertex_count(),
        gsecs = sgr.seconds,
        spp = o.spp,
        tm = describe(tm),
    );
    h.push_str("<table><tr><th>sky rotation</th><th>method</th><th>frame</th><th>references (s)</th><th>relative RMSE</th><th>RMSE</th><th>PSNR (dB)</th><th>mean |ΔY| (Table 5.1)</th><th>std |ΔY|</th></tr>");
    for r in rows {
        for p in &r.panels {
            let m = &p.metrics;
            let _ = write!(
                h,
                "<tr><td>{:.0}°</td><td>{}</td><td>{}</td><td>{:.1}</td><td>{:.2} %</td><td>{:.4}</td><td>{:.1}</td><td>{:.4}</td><td>{:.4}</td></tr>",
                r.rotate, p.name, p.note.to_lowercase(), r.reference_s, 100.0 * m.rel_rmse, m.rmse, m.psnr, m.mean_abs_lum_err, m.std_abs_lum_err
            );
        }
    }
    h.push_str("</table><h2>sh | hybrid | path traced | sh error | hybrid error; sg | path traced | sg error</h2>");
    for r in rows {
        let t = tag(r.rotate);
        let _ = write!(
            h,
            "<p>sky rotated {:.0}°<br><img src=\"sh_{t}.png\"><img src=\"hybrid_{t}.png\"><img src=\"reference_{t}.png\"><img src=\"sh_error_{t}.png\"><img src=\"hybrid_error_{t}.png\"><br>\
<img src=\"sg_{t}.png\"><img src=\"glossy_reference_{t}.png\"><img src=\"sg_error_{t}.png\"></p>",
            r.rotate
        );
    }
    let _ = write!(
        h,
        "<p>Contact sheet: <a href=\"contact_sheet.png\">contact_sheet.png</a>. Bundles: <code>demo.relight</code> (sh, \
renders with --method sh or hybrid) and <code>demo_sg.relight</code> (sg); try <code>relight info demo.relight</code> and \
<code>relight render demo.relight --method hybrid --rotate-env 45 -o x.png</code>. Total demo time {total_s:.1} s.</p></body></html>"
    );
    relight_bundle::write_atomic(path, h.as_bytes())?;
    Ok(())
}

/// A tone map in words.
fn describe(t: &ToneMap) -> String {
    match t {
        ToneMap::Linear { exposure } => format!("linear, clamp({exposure} c), then sRGB"),
        ToneMap::Reinhard { exposure } => format!("Reinhard x/(1+x), x = {exposure} c, then sRGB"),
        ToneMap::Exponential { gamma } => {
            format!("exponential 1 - exp(-{gamma} c) (thesis 4.4), then sRGB")
        }
    }
}
