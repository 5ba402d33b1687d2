//! `relight bench`: every measurement against a baseline measured in the same run (never
//! asserted in tests; figures go to docs/RESULTS.md). Benchmark code lives here only: the
//! libraries expose what they compute, not how long it takes.
//!
//! Sections, in the order of the report (one child module each):
//! 1. [`rays`]: ray throughput of every back-end on incoherent occlusion and closest-hit rays
//!    from the surface of a ~100K-triangle mesh, as a ratio to Embree 3.
//! 2. [`sh_bake`]: SH bake time of bunny_watertight.obj (order 4, 1024 samples, shadowed + 1
//!    bounce), and its overhead over casting the same rays with nothing else done.
//!    [`shard`]: the same mesh's shadowed `sh` bake and a small `sg` bake, each in N = 1, 2,
//!    4 parts plus the merge, against the one-process bake (and whether the merged bundle is
//!    byte-identical).
//! 3. [`relight`]: SH relight time per frame for 1M vertices at order 5, against a
//!    STREAM-like copy.
//! 4. [`projection`]: exact SH projection of a latlong map against the point rule.
//! 5. [`hybrid`]: environment decomposition per frame against its budget; hybrid frames
//!    against the PRT-only frame.
//! 6. [`prefilter`]: the Gaussian-prefiltered environment, sequential and on every thread,
//!    against cmft's published time.
//! 7. [`sg_fit`]: time per Levenberg-Marquardt fit of 1, 2 (and 3) lobes to tabulated glossy
//!    BRDF lobes, against the 1-lobe fit.
//! 8. [`sg_bake`]: SG bake cost per vertex (tabulation and fit) on a patch of a procedural
//!    glossy mesh (and of the armadillo), extrapolated to the armadillo's bake.
//! 9. [`sg_frame`]: the SG frame (512 x 512, ~15K vertices) against the SH frame of the same
//!    scene.
//! 10. [`cuts_bake`]: cuts bake of the bunny (light samples, light tree, visibility cuts of a
//!     block of vertices against casting the same rays), extrapolated to the whole mesh; the
//!     illumination cut at the budgets 128, 256, 512; the per-pixel merge kernel; light-tree
//!     variants.
//! 11. [`cuts_frame`]: the cuts frame (512 x 512, light cuts 128/256/512): the corner lists
//!     (once per light cut), then the frame split into G-buffer and shading, against the
//!     per-triangle and the per-fragment merge in the same run; [`cuts_local`]: the cuts
//!     local-light frame (a room lit by a point light, one bounce) against the per-fragment
//!     merge in the same run.
//! 12. [`vmf_fit`]: the vMF material fit, EM (what the bake runs) against Levenberg-Marquardt
//!     on a tabulation, over a level of views (the paper's 2 s against 47 s).
//! 13. [`vmf_bake`]: the vMF teapot (exponent 64) baked with adaptive angular and spatial
//!     refinement against a fixed level-1 bake of the same mesh, then its 512 x 512 CPU frame
//!     against `sg`'s and SH's frames of the same mesh and camera.
//! 14. [`gltf`]: a textured GLB (`--gltf`) against its OBJ twin: loading, and the whole
//!     `relight bake MODEL --method cuts` to a bundle.
//! 15. `gpu` (feature `gpu`): frames of the GPU renderer at 1280 x 720 (cuts: 320 x 180) against the CPU
//!     frames, the CPU-side work per frame against 2 ms, per-frame counts.
//!
//! Timing helpers shared by the sections: [`median`], `median_ms` (median wall time of
//! repeated calls after a warm-up) and [`process_cpu_ms`] (CPU time of all threads, which a
//! machine shared with other jobs does not inflate).

pub mod cuts_bake;
pub mod cuts_frame;
pub mod cuts_local;
pub mod gltf;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod hybrid;
pub mod prefilter;
pub mod projection;
pub mod rays;
pub mod relight;
pub mod sg_bake;
pub mod sg_fit;
pub mod sg_frame;
pub mod sh_bake;
pub mod shard;
pub mod vmf_bake;
pub mod vmf_fit;

use crate::{EvalError, Result};
use relight_scene::mesh::TriMesh;
use serde::Serialize;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The benchmarks' options.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Rays per throughput measurement (at least 1).
    pub rays: usize,
    /// Mesh for the ray benchmark (`None`: `<data>/data/meshes/dragon.obj`, 100K triangles, if
    /// a data folder is given, else a procedural 100K-triangle sphere).
    pub ray_mesh: Option<PathBuf>,
    /// Mesh for the bake benchmark (`None`: `<data>/data/meshes/bunny_watertight.obj`, else a
    /// procedural sphere on a plane).
    pub bake_mesh: Option<PathBuf>,
    /// The shared data folder, if any (the SG bake section then also times a patch of
    /// `<data>/data/meshes/armadillo.obj`).
    pub data: Option<PathBuf>,
    /// Vertices of the relight benchmark (at least 1).
    pub relight_vertices: usize,
    /// Fewer rays, samples, vertices and repetitions (a quick smoke run).
    pub quick: bool,
    /// Run only these sections ([`SECTIONS`]); empty: all.
    pub only: Vec<String>,
    /// The GLB of the "gltf" section (its OBJ twin beside it); `None`: the section is
    /// skipped when every section runs, refused when asked for by name.
    pub gltf: Option<PathBuf>,
}

/// One table of the report.
#[derive(Clone, Debug, Serialize)]
pub struct Section {
    /// What was measured.
    pub title: String,
    /// Column names.
    pub columns: Vec<String>,
    /// Rows (numbers where the cell is a number).
    pub rows: Vec<Vec<Value>>,
    /// Peak resident memory of the process while the section ran, MiB (Linux; `None`
    /// elsewhere).
    pub peak_rss_mib: Option<f64>,
}

impl Section {
    fn new(title: impl Into<String>, columns: &[&str]) -> Section {
        Section {
            title: title.into(),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            rows: vec![],
            peak_rss_mib: None,
        }
    }

    fn row(&mut self, cells: Vec<Value>) {
        debug_assert_eq!(cells.len(), self.columns.len(), "{}", self.title);
        self.rows.push(cells);
    }

    /// The section as markdown: non-integer numbers with two decimals, four below 0.1 and in
    /// scientific notation below 0.001 (small errors keep their digits).
    pub fn markdown(&self) -> String {
        let cell = |v: &Value| match v {
            Value::String(s) => s.clone(),
            Value::Number(n) => match n.as_f64() {
                Some(x) if n.is_f64() => match x.abs() {
                    a if a >= 0.1 || a == 0.0 => format!("{x:.2}"),
                    a if a >= 1e-3 => format!("{x:.4}"),
                    _ => format!("{x:.2e}"),
                },
                _ => n.to_string(),
            },
            other => other.to_string(),
        };
        let mut s = format!(
            "## {}\n| {} |\n|{}\n",
            self.title,
            self.columns.join(" | "),
            "---|".repeat(self.columns.len())
        );
        for r in &self.rows {
            s.push_str(&format!(
                "| {} |\n",
                r.iter().map(cell).collect::<Vec<_>>().join(" | ")
            ));
        }
        if let Some(m) = self.peak_rss_mib {
            s.push_str(&format!("\npeak resident memory: {m:.0} MiB\n"));
        }
        s
    }
}

/// Peak resident memory of this process since the last [`reset_peak_rss`] (or its start),
/// MiB: Linux `VmHWM`; `None` elsewhere.
pub fn peak_rss_mib() -> Option<f64> {
    Some(status_kib("VmHWM:")? as f64 / 1024.0)
}

/// A `kB` field of `/proc/self/status` (`key` with its colon).
fn status_kib(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix(key))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()
}

/// The resident memory of this process now, bytes (Linux `VmRSS`), if known.
pub fn resident_bytes() -> Option<u64> {
    Some(status_kib("VmRSS:")? << 10)
}

/// Reset the peak of [`peak_rss_mib`] to the current resident memory (Linux: `5` written to
/// `/proc/self/clear_refs`); does nothing where that is not possible.
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// Worker threads.
    pub threads: usize,
    /// CPU architecture.
    pub arch: String,
    /// The tables, in order.
    pub sections: Vec<Section>,
}

impl BenchReport {
    /// The report as markdown: a title line, then every section's table.
    pub fn markdown(&self) -> String {
        let mut s = format!("# relight bench ({} threads, {})", self.threads, self.arch);
        for t in &self.sections {
            s += &format!("\n\n{}", t.markdown().trim_end());
        }
        s
    }
}

/// The mesh at `explicit`, else `<data>/<rel>` if that file exists, with its name; `None`
/// when neither is given.
fn shared_mesh(
    explicit: &Option<PathBuf>,
    data: &Option<PathBuf>,
    rel: &str,
) -> Result<Option<(String, TriMesh)>> {
    let path = match explicit {
        Some(p) => Some(p.clone()),
        None => data.as_ref().map(|d| d.join(rel)).filter(|p| p.is_file()),
    };
    match path {
        Some(p) => Ok(Some((p.display().to_string(), load_mesh(&p)?))),
        None => Ok(None),
    }
}

/// The mesh of `path` (through the importer, which computes missing normals).
fn load_mesh(path: &Path) -> Result<TriMesh> {
    Ok(relight_scene::io::load_mesh(path)?.mesh)
}

/// The sections' names, in the order of the report (`relight bench --only NAME`).
pub const SECTIONS: [&str; 17] = [
    "rays",
    "sh-bake",
    "shard",
    "relight",
    "projection",
    "hybrid",
    "prefilter",
    "sg-fit",
    "sg-bake",
    "sg-frame",
    "cuts-bake",
    "cuts-frame",
    "cuts-local",
    "vmf-fit",
    "vmf-bake",
    "gltf",
    "gpu",
];

/// Run the benchmarks; each section is also printed as markdown on stderr as it completes.
///
/// # Errors
/// [`EvalError::Options`] for zero rays or relight vertices; a mesh that cannot be read, or a
/// bake that fails.
pub fn run(a: &BenchOptions) -> Result<BenchReport> {
    if a.rays == 0 {
        return Err(EvalError::Options(
            "bench: --rays must be at least 1".into(),
        ));
    }
    if let Some(bad) = a.only.iter().find(|o| !SECTIONS.contains(&o.as_str())) {
        return Err(EvalError::Options(format!(
            "bench: unknown section '{bad}' (sections: {})",
            SECTIONS.join(", ")
        )));
    }
    if a.relight_vertices == 0 {
        return Err(EvalError::Options(
            "bench: --relight-vertices must be at least 1".into(),
        ));
    }
    let threads = rayon::current_num_threads();
    let mut report = BenchReport {
        threads,
        arch: std::env::consts::ARCH.into(),
        sections: vec![],
    };
    // Each section's peak memory: reset before it, read after it.
    reset_peak_rss();
    let mut push = |mut s: Section| {
        s.peak_rss_mib = peak_rss_mib();
        reset_peak_rss();
        eprintln!("{}", s.markdown());
        report.sections.push(s);
    };

    let on = |name: &str| a.only.is_empty() || a.only.iter().any(|o| o == name);
    let rays = if a.quick { a.rays.min(200_000) } else { a.rays };
    if on("rays") {
        push(rays::section(&a.ray_mesh, &a.data, rays, threads)?);
    }
    if on("sh-bake") {
        push(sh_bake::section(&a.bake_mesh, &a.data, a.quick)?);
    }
    if on("shard") {
        shard::section(&a.bake_mesh, &a.data, a.quick, &mut push)?;
    }
    let verts = if a.quick {
        a.relight_vertices.min(200_000)
    } else {
        a.relight_vertices
    };
    if on("relight") {
        push(relight::section(verts, 5));
    }
    if on("projection") {
        push(projection::section(a.quick));
    }
    if on("hybrid") {
        hybrid::sections(a.quick).into_iter().for_each(&mut push);
    }
    if on("prefilter") {
        push(prefilter::section());
    }
    if on("sg-fit") {
        push(sg_fit::section(a.quick));
    }
    if on("sg-bake") {
        push(sg_bake::section(&a.data, a.quick)?);
    }
    if on("sg-frame") {
        push(sg_frame::section(a.quick));
    }
    if on("cuts-bake") {
        cuts_bake::sections(&a.bake_mesh, &a.data, a.quick)?
            .into_iter()
            .for_each(&mut push);
    }
    if on("cuts-frame") {
        push(cuts_frame::section(&a.bake_mesh, &a.data, a.quick)?);
    }
    if on("cuts-local") {
        push(cuts_local::section(a.quick)?);
    }
    if on("vmf-fit") {
        push(vmf_fit::section(a.quick));
    }
    if on("vmf-bake") {
        vmf_bake::sections(&a.data, a.quick)?
            .into_iter()
            .for_each(&mut push);
    }
    if on("gltf") {
        if a.gltf.is_some() || !a.only.is_empty() {
            push(gltf::section(&a.gltf, a.quick)?);
        } else {
            eprintln!("bench: section gltf skipped (no --gltf FILE.glb)");
        }
    }
    if on("gpu") {
        #[cfg(feature = "gpu")]
        gpu::sections(a.quick)?.into_iter().for_each(&mut push);
        #[cfg(not(feature = "gpu"))]
        if !a.only.is_empty() {
            return Err(EvalError::Options(
                "bench: section 'gpu' needs a relight built with `--features gpu`".into(),
            ));
        }
    }
    Ok(report)
}

/// The median of `v` (the upper one for an even count).
///
/// # Panics
/// If `v` is empty.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median wall time of `runs` calls of `f` (after one warm-up call), milliseconds.
fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    f();
    median(
        (0..runs.max(1))
            .map(|_| {
                let start = Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

/// User + system CPU time of this process so far, all threads, milliseconds (Linux
/// `/proc/self/stat` fields 14 and 15, in clock ticks of 10 ms: the kernel's `USER_HZ` is 100
/// on every Linux architecture relight builds for); `None` elsewhere.
pub fn process_cpu_ms() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) is in parentheses and may hold spaces: split after it.
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks * 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_rays_or_vertices_and_unknown_sections_are_refused_by_name() {
        let o = BenchOptions {
            rays: 0,
            ray_mesh: None,
            bake_mesh: None,
            data: None,
            relight_vertices: 10,
            quick: true,
            only: vec![],
            gltf: None,
        };
        let e = run(&o).unwrap_err().to_string();
        assert!(e.contains("--rays"), "{e}");
        let o = BenchOptions { rays: 10, ..o };
        let e = run(&BenchOptions {
            relight_vertices: 0,
            ..o.clone()
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("--relight-vertices"), "{e}");
        let e = run(&BenchOptions {
            only: vec!["sh-bake".into(), "nope".into()],
            ..o
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("'nope'") && e.contains("sg-frame"), "{e}");
    }

    #[test]
    fn peak_memory_sees_an_allocation_and_resets() {
        let Some(before) = peak_rss_mib() else {
            relight_testdata::skip_platform("proc", "no VmHWM in /proc/self/status");
            return;
        };
        let v = vec![1u8; 96 << 20]; // touched: resident
        std::hint::black_box(&v);
        let with = peak_rss_mib().unwrap();
        assert!(with >= before.max(96.0), "{before} -> {with}");
        drop(v);
        reset_peak_rss();
        let after = peak_rss_mib().unwrap();
        // Resetting is best effort (a kernel may refuse clear_refs): never above the peak.
        assert!(after <= with, "{with} -> {after}");
    }

    #[test]
    fn markdown_has_one_line_per_row() {
        let mut s = Section::new("T", &["a", "b"]);
        s.row(vec![serde_json::json!(1), serde_json::json!(0.5)]);
        s.row(vec![serde_json::json!("x"), serde_json::json!(0.0123)]);
        s.row(vec![serde_json::json!(null), serde_json::json!(-1.5e-5)]);
        assert_eq!(
            s.markdown(),
            "## T\n| a | b |\n|---|---|\n| 1 | 0.50 |\n| x | 0.0123 |\n| null | -1.50e-5 |\n"
        );
    }

    #[test]
    fn process_cpu_time_grows() {
        let Some(a) = process_cpu_ms() else {
            relight_testdata::skip_platform("proc", "no /proc/self/stat");
            return;
        };
        // Spin until 30 ms of CPU time are counted (3 ticks), for at most 20 s of wall time
        // (a loaded machine gives this thread a fraction of a core).
        let t0 = Instant::now();
        let mut x = 0u64;
        let mut b = a;
        while b < a + 30.0 && t0.elapsed().as_secs() < 20 {
            for _ in 0..100_000 {
                x = std::hint::black_box(x.wrapping_add(1));
            }
            b = process_cpu_ms().unwrap();
        }
        assert!(b >= a + 30.0, "{a} -> {b} ms after {:?}", t0.elapsed());
    }
}
