//! Writing an experiment's results: images with their error maps, markdown and JSON tables,
//! HTML reports. Every file is written atomically.

use crate::{EvalError, Result};
use relight_render::compare;
use relight_render::tonemap::ToneMap;
use relight_render::{write_image, Image};
use std::fmt::Write as _;
use std::path::Path;

/// Write an image, naming the file in the error.
///
/// # Errors
/// [`EvalError::Options`] for an unknown extension, else the write error.
pub fn image(path: &Path, img: &Image, tm: &ToneMap) -> Result<()> {
    write_image(path, img, tm).map_err(|e| EvalError::Options(e.to_string()))
}

/// Write `name.png`, `name.exr` and, against a reference, `name_error.png` (heat map whose
/// full scale is `scale`, e.g. a quarter of the reference's mean luminance, so that the maps
/// of one experiment compare).
///
/// # Errors
/// A write error naming the file.
pub fn image_set(
    dir: &Path,
    name: &str,
    img: &Image,
    reference: Option<&Image>,
    tm: &ToneMap,
    scale: f32,
) -> Result<()> {
    image(&dir.join(format!("{name}.png")), img, tm)?;
    image(&dir.join(format!("{name}.exr")), img, tm)?;
    if let Some(r) = reference {
        relight_scene::io::image::write_png_srgb8(
            &dir.join(format!("{name}_error.png")),
            img.width,
            img.height,
            &compare::heatmap_with_scale(img, r, scale),
        )?;
    }
    Ok(())
}

/// Create the output folder.
///
/// # Errors
/// [`EvalError::Io`] naming it.
pub fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(EvalError::io(dir))
}

/// Write the markdown table as `out/results.md` and the rows as `out/results.json` (the CLI
/// prints them).
///
/// # Errors
/// A write error naming the file.
pub fn results(out: &Path, md: &str, rows: &impl serde::Serialize) -> Result<()> {
    relight_bundle::write_atomic(&out.join("results.md"), md.as_bytes())?;
    let json = serde_json::to_string_pretty(rows)
        .map_err(|e| EvalError::Options(format!("cannot write results.json: {e}")))?;
    relight_bundle::write_atomic(&out.join("results.json"), json.as_bytes())?;
    eprintln!("wrote {}", out.join("results.md").display());
    Ok(())
}

/// A percentage with one decimal, or `-`.
pub fn pct(x: Option<f64>) -> String {
    x.map_or_else(|| "-".into(), |v| format!("{:.1} %", 100.0 * v))
}

/// Markdown tables (and the lines of text between them) as HTML.
pub fn md_to_html(md: &str) -> String {
    let mut h = String::new();
    let mut in_table = false;
    let mut header = false;
    for line in md.lines() {
        if !line.starts_with('|') {
            if in_table {
                h.push_str("</table>");
                in_table = false;
            }
            if !line.trim().is_empty() {
                let _ = write!(h, "<p>{}</p>", line.trim());
            }
            continue;
        }
        if !in_table {
            h.push_str("<table border=\"1\" style=\"border-collapse:collapse\">");
            in_table = true;
            header = true;
        }
        if line.starts_with("|---") {
            continue;
        }
        let tag = if header { "th" } else { "td" };
        header = false;
        h.push_str("<tr>");
        for cell in line.trim_matches('|').split('|') {
            let _ = write!(h, "<{tag}>{}</{tag}>", cell.trim());
        }
        h.push_str("</tr>");
    }
    if in_table {
        h.push_str("</table>");
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_tables_become_html_tables() {
        let h = md_to_html("title\n| a | b |\n|---|---|\n| 1 | 2 |\nafter");
        assert_eq!(
            h,
            "<p>title</p><table border=\"1\" style=\"border-collapse:collapse\"><tr><th>a</th><th>b</th></tr><tr><td>1</td><td>2</td></tr></table><p>after</p>"
        );
    }
}
