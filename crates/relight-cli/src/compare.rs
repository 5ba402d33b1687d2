//! `relight compare A B`: image error metrics and an error heat map.

use crate::args::Out;
use anyhow::{ensure, Result};
use relight_render::{compare, read_image};
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `relight compare`.
#[derive(clap::Args)]
pub struct Args {
    /// Test image (.exr / .hdr).
    pub a: PathBuf,
    /// Reference image (.exr / .hdr); relative errors are relative to it.
    pub b: PathBuf,
    /// Where to write the error heat map (PNG). Default: `<A>-vs-<B>.err.png` beside A.
    #[arg(short, long, alias = "heatmap")]
    pub out: Option<PathBuf>,
}

/// Print the metrics and write the heat map.
pub fn run(a: Args, out: &Out) -> Result<()> {
    let heat_path = a.out.clone().unwrap_or_else(|| {
        let stem = |p: &PathBuf| {
            p.file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .to_string()
        };
        a.a.with_file_name(format!("{}-vs-{}.err.png", stem(&a.a), stem(&a.b)))
    });
    relight_bundle::output::check_outputs(&[&heat_path], &["png"], &[&a.a, &a.b])?;
    let ia = read_image(&a.a)?;
    let ib = read_image(&a.b)?;
    ensure!(
        ia.width == ib.width && ia.height == ib.height,
        "{} is {}x{} but {} is {}x{}: images must have the same size",
        a.a.display(),
        ia.width,
        ia.height,
        a.b.display(),
        ib.width,
        ib.height
    );
    for (img, p) in [(&ia, &a.a), (&ib, &a.b)] {
        if let Some(i) = img.pixels.iter().position(|c| !c.is_finite()) {
            anyhow::bail!(
                "{}: pixel ({}, {}) is not finite: metrics would be meaningless",
                p.display(),
                i % img.width,
                i / img.width
            );
        }
    }
    let m = compare::metrics(&ia, &ib, None);
    out.line(format!(
        "{} vs {} ({}x{})",
        a.a.display(),
        a.b.display(),
        ia.width,
        ia.height
    ));
    out.line(format!("  RMSE                         {:.6}", m.rmse));
    out.line(format!(
        "  relative RMSE                {:.4} %",
        100.0 * m.rel_rmse
    ));
    out.line(format!("  PSNR                         {:.2} dB", m.psnr));
    out.line(format!(
        "  abs. luminance error, mean   {:.6}  (thesis Table 5.1 metric)",
        m.mean_abs_lum_err
    ));
    out.line(format!(
        "  abs. luminance error, stddev {:.6}",
        m.std_abs_lum_err
    ));
    let heat = compare::heatmap(&ia, &ib);
    relight_scene::io::image::write_png_srgb8(&heat_path, ia.width, ia.height, &heat)?;
    out.line(format!("heat map: {}", heat_path.display()));
    out.summary(json!({
        "command": "compare", "a": a.a, "b": a.b, "width": ia.width, "height": ia.height,
        "rmse": m.rmse, "rel_rmse": m.rel_rmse, "psnr": m.psnr,
        "mean_abs_lum_err": m.mean_abs_lum_err, "std_abs_lum_err": m.std_abs_lum_err,
        "heatmap": heat_path,
    }));
    Ok(())
}
