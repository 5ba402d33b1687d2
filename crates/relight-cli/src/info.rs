//! `relight info` (describe a bundle) and `relight project` (SH coefficients of an environment).

use anyhow::{Context, Result};
use relight_bundle::Bundle;
use relight_sphere::sh;
use std::path::PathBuf;

/// Arguments of `relight info`.
#[derive(clap::Args)]
pub struct Args {
    /// The bundle (.relight).
    pub bundle: PathBuf,
}

/// Print the bundle's metadata and tensors.
pub fn run(a: Args) -> Result<()> {
    let b = Bundle::read(&a.bundle)?;
    let size = std::fs::metadata(&a.bundle).map(|m| m.len()).unwrap_or(0);
    println!(
        "{}: relight bundle, format version {}, {:.2} MiB, checksums OK",
        a.bundle.display(),
        relight_bundle::FORMAT_VERSION,
        size as f64 / (1 << 20) as f64
    );
    for (k, v) in &b.metadata {
        if v.len() > 200 {
            println!(
                "  {k}: {}... ({} chars)",
                &v[..v.char_indices().nth(200).map_or(v.len(), |c| c.0)],
                v.len()
            );
        } else {
            println!("  {k}: {v}");
        }
    }
    println!("  tensors:");
    for (name, t) in &b.tensors {
        println!(
            "    {name:<16} {:<4} {:?} ({} bytes)",
            t.dtype.name(),
            t.shape,
            t.bytes.len()
        );
    }
    if b.metadata.get("method").map(String::as_str) == Some("sg") {
        describe_sg(&a.bundle, &b)?;
    }
    Ok(())
}

/// The SG part of `relight info`: views, lobes, storage per vertex, fit statistics.
fn describe_sg(path: &std::path::Path, b: &Bundle) -> Result<()> {
    let sg = crate::store::SgBundle::from_bundle(path, b)?;
    let (s, k) = (&sg.settings, &sg.bake);
    let v = sg.mesh.vertex_count().max(1);
    let tensor_bytes: usize = b.tensors.values().map(|t| t.bytes.len()).sum();
    println!("  SG (Green 2005 view-dependent glossy PRT):");
    println!(
        "    {} views (icosahedron frequency {}), {} direct + {} indirect lobes per vertex and view, diffuse SH order {}",
        k.direct.view_count, k.view_frequency, s.direct_lobes, s.indirect_lobes, s.diffuse_order
    );
    println!(
        "    bytes per vertex: {} transfer (lobes + diffuse SH, {}), {} all tensors",
        sg.transfer_bytes_per_vertex(),
        if s.f16 { "f16" } else { "f32" },
        tensor_bytes / v
    );
    let distinct: std::collections::BTreeSet<String> =
        k.materials.iter().map(|m| format!("{m:?}")).collect();
    println!(
        "    {} distinct per-vertex materials{}",
        distinct.len(),
        s.blend
            .as_ref()
            .map_or(String::new(), |b| format!(" (blend to {b})"))
    );
    let st = &k.stats;
    println!(
        "    fit: mean relative L2 error {:.4} direct, {:.4} indirect; {} iterations; flips {} -> {} after relaxation",
        st.mean_relative_error[0], st.mean_relative_error[1], st.iterations, st.flips, st.flips_after_relaxation
    );
    Ok(())
}

/// Arguments of `relight project`.
#[derive(clap::Args)]
pub struct ProjectArgs {
    /// Environment map (.hdr / .exr; latlong, vertical cross or angular probe).
    pub env: PathBuf,
    /// SH order n (n^2 coefficients).
    #[arg(long, default_value_t = 3)]
    pub order: usize,
    /// Layout (latlong, cube, probe); detected from the aspect ratio when absent.
    #[arg(long)]
    pub layout: Option<String>,
}

/// Print the SH projection of an environment.
pub fn project(a: ProjectArgs) -> Result<()> {
    anyhow::ensure!(
        (1..=sh::MAX_ORDER).contains(&a.order),
        "--order {} is not in 1..={}",
        a.order,
        sh::MAX_ORDER
    );
    let layout = match &a.layout {
        Some(l) => Some(
            relight_scene::scene_file::parse_layout(l)
                .with_context(|| format!("unknown layout '{l}' (latlong, cube, probe)"))?,
        ),
        None => None,
    };
    let map = relight_scene::io::load_env(&a.env, layout)?;
    let c = sh::project_env(&map, a.order);
    println!(
        "# SH projection of {} (order {}, real orthonormal, R&H 2001 basis on world x,y,z)",
        a.env.display(),
        a.order
    );
    println!("# l  m        r            g            b");
    for l in 0..a.order as i32 {
        for m in -l..=l {
            let v = c[sh::sh_index(l, m)];
            println!("{l:3} {m:3} {:12.6} {:12.6} {:12.6}", v.x, v.y, v.z);
        }
    }
    Ok(())
}
