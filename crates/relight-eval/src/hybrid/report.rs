//! The hybrid experiment's tables (markdown, JSON) and HTML report.

use super::{HybridEval, HybridRow, METHODS};
use crate::output::{self, md_to_html};
use crate::Result;
use std::fmt::Write as _;

/// The image-name suffix of order `o`: empty when only one order is evaluated.
pub(super) fn suffix(orders: &[usize], o: usize) -> String {
    if orders.len() > 1 {
        format!("_order{o}")
    } else {
        String::new()
    }
}

/// One line on stderr per row.
pub(super) fn progress(r: &HybridRow) {
    let (m, e) = (&r.mean_abs_lum_err, &r.rel_rmse);
    eprintln!(
        "eval hybrid: {} order {}: {} lights; mean |dY| sh {:.4}, thesis {:.4}, hybrid {:.4} (reference noise {:.4}); relRMSE {:.1} / {:.1} / {:.1} %",
        r.env, r.order, r.lights, m[0], m[1], m[2], r.lum_noise,
        100.0 * e[0], 100.0 * e[1], 100.0 * e[2]
    );
    if let Some(b) = &r.better {
        eprintln!(
            "eval hybrid: {} order {}: against {} spp x 2: mean |dY| sh {:.4}, thesis {:.4}, hybrid {:.4} (its noise {:.4}; first reference's error {:.4})",
            r.env, r.order, b.spp, b.mean_abs_lum_err[0], b.mean_abs_lum_err[1], b.mean_abs_lum_err[2], b.lum_noise, b.reference_err
        );
    }
}

fn markdown(rows: &[HybridRow]) -> String {
    let mut md = String::from(
        "| environment | SH order | lights | mean abs. lum. error: SH / thesis hybrid / relight hybrid | std: SH / thesis / relight | relative RMSE: SH / thesis / relight | hybrid vs SH (mean error) | reference noise (rel. RMSE) | reference noise floor (mean abs. lum.) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let (m, s, e) = (&r.mean_abs_lum_err, &r.std_abs_lum_err, &r.rel_rmse);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.4} / {:.4} / {:.4} | {:.4} / {:.4} / {:.4} | {:.1} / {:.1} / {:.1} % | {:.2}x better | {:.1} % | {:.4} |",
            r.env, r.order, r.lights, m[0], m[1], m[2], s[0], s[1], s[2],
            100.0 * e[0], 100.0 * e[1], 100.0 * e[2],
            m[0] / m[2], 100.0 * r.reference_noise, r.lum_noise
        );
    }
    if rows.iter().any(|r| r.better.is_some()) {
        md.push_str(
            "\nAgainst the better reference:\n\n| environment | SH order | reference spp x 2 | mean abs. lum. error: SH / thesis hybrid / relight hybrid | relative RMSE: SH / thesis / relight | hybrid vs SH (mean error) | its noise floor (mean abs. lum.) | first reference's error against it |\n|---|---|---|---|---|---|---|---|\n",
        );
        for r in rows {
            let Some(b) = &r.better else { continue };
            let (m, e) = (&b.mean_abs_lum_err, &b.rel_rmse);
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.4} / {:.4} / {:.4} | {:.1} / {:.1} / {:.1} % | {:.2}x better | {:.4} | {:.4} |",
                r.env, r.order, b.spp, m[0], m[1], m[2],
                100.0 * e[0], 100.0 * e[1], 100.0 * e[2],
                m[0] / m[2], b.lum_noise, b.reference_err
            );
        }
    }
    md
}

/// Write results.md, results.json and report.html.
pub(super) fn write(e: &HybridEval, rows: &[HybridRow]) -> Result<()> {
    let md = markdown(rows);
    output::results(&e.out, &md, &rows)?;
    let mut h = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>relight eval: hybrid</title>\
<style>body{{font-family:sans-serif;margin:2em}}td,th{{padding:3px 8px}}img{{margin:2px}}</style></head><body>\
<h1>Hybrid (thesis 4.3-4.4) vs SH PRT vs Mitsuba 3</h1><p>Scene {}, SH order {:?}, shadowed transfer with {} \
directions per vertex, direct lighting (Mitsuba max_depth 2, {} spp x 2 seeds). Metrics over pixels fully covered by \
geometry; error maps share one scale per environment (25 % of the reference's mean luminance = full scale).</p>{}",
        e.scene.display(),
        e.orders,
        e.samples,
        e.spp,
        md_to_html(&md)
    );
    let figure = |h: &mut String, src: String, caption: &str| {
        let _ = write!(h, "<figure style=\"display:inline-block\"><img src=\"{src}\"><figcaption>{caption}</figcaption></figure>");
    };
    for r in rows {
        let sfx = suffix(&e.orders, r.order);
        let _ = write!(h, "<h2>{}, SH order {}</h2><p>", r.env, r.order);
        figure(&mut h, format!("{}/mitsuba.png", r.env), "mitsuba");
        for name in METHODS {
            figure(&mut h, format!("{}/{name}{sfx}.png", r.env), name);
        }
        h.push_str("<br>");
        for name in METHODS {
            figure(
                &mut h,
                format!("{}/{name}{sfx}_error.png", r.env),
                &format!("{name} error"),
            );
        }
        h.push_str("</p>");
    }
    h.push_str("</body></html>");
    relight_bundle::write_atomic(&e.out.join("report.html"), h.as_bytes())?;
    eprintln!("wrote {}", e.out.join("report.html").display());
    Ok(())
}
