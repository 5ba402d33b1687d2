//! `relight compare A B`: image error metrics and an error heat map.

use crate::common::read_image;
use anyhow::{ensure, Result};
use relight_render::compare;
use std::path::PathBuf;

/// Arguments of `relight compare`.
#[derive(clap::Args)]
pub struct Args {
    /// Test image (.exr / .hdr).
    pub a: PathBuf,
    /// Reference image (.exr / .hdr); relative errors are relative to it.
    pub b: PathBuf,
    /// Where to write the error heat map (PNG). Default: `<A>-vs-<B>.err.png` beside A.
    #[arg(long)]
    pub heatmap: Option<PathBuf>,
}

/// Print the metrics and write the heat map.
pub fn run(a: Args) -> Result<()> {
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
    let m = compare::metrics(&ia, &ib, None);
    println!(
        "{} vs {} ({}x{})",
        a.a.display(),
        a.b.display(),
        ia.width,
        ia.height
    );
    println!("  RMSE                         {:.6}", m.rmse);
    println!("  relative RMSE                {:.4} %", 100.0 * m.rel_rmse);
    println!("  PSNR                         {:.2} dB", m.psnr);
    println!(
        "  abs. luminance error, mean   {:.6}  (thesis Table 5.1 metric)",
        m.mean_abs_lum_err
    );
    println!("  abs. luminance error, stddev {:.6}", m.std_abs_lum_err);
    let out = a.heatmap.unwrap_or_else(|| {
        let stem_a = a.a.file_stem().unwrap_or_default().to_string_lossy();
        let stem_b = a.b.file_stem().unwrap_or_default().to_string_lossy();
        a.a.with_file_name(format!("{stem_a}-vs-{stem_b}.err.png"))
    });
    let heat = compare::heatmap(&ia, &ib);
    relight_scene::io::image::write_png_srgb8(&out, ia.width, ia.height, &heat)?;
    println!("heat map: {}", out.display());
    Ok(())
}
