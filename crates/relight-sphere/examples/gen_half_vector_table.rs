//! Writes the tap table of `relight_sphere::half_vector`, fitted by continuation (module
//! docs), to the file given (write to a temporary file, then rename). From the workspace root:
//!
//! ```text
//! cargo run --release -p relight-sphere --example gen_half_vector_table crates/relight-sphere/src/half_vector_table.rs
//! ```
use relight_sphere::half_vector::{fit_table, grid_s, grid_theta, table_source, THETA_COUNT};

fn main() -> std::io::Result<()> {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: gen_half_vector_table OUT.rs");
        std::process::exit(2);
    };
    let start = std::time::Instant::now();
    let table = fit_table();
    let (entries, errors) = (&table.entries, &table.errors);
    let worst = errors.iter().fold(0.0f64, |a, &b| a.max(b));
    for (k, e) in errors.iter().enumerate() {
        let (i, j) = (k / THETA_COUNT, k % THETA_COUNT);
        eprintln!(
            "s {:9.3} theta {:4.1}: relative L2 error {e:.4} taps {:?}",
            grid_s(i),
            grid_theta(j).to_degrees(),
            entries[k]
        );
    }
    let tmp = format!("{path}.tmp");
    std::fs::write(&tmp, table_source(&table))?;
    std::fs::rename(&tmp, &path)?;
    eprintln!(
        "wrote {path}: {} entries, largest relative L2 error {worst:.4}, {:.1} s",
        entries.len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
