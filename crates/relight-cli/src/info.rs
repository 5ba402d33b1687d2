//! `relight info` (describe and check a bundle) and `relight project` (SH coefficients of an
//! environment).

use crate::args::{self, Out};
use anyhow::{ensure, Result};
use relight_bundle::Bundle;
use relight_method::from_bundle;
use relight_sphere::sh;
use serde_json::json;
use std::path::PathBuf;

/// Arguments of `relight info`.
#[derive(clap::Args)]
pub struct Args {
    /// The bundle (.relight).
    pub bundle: PathBuf,
}

/// Print the bundle's metadata and tensors, after checking its checksums and its contents
/// (the same checks as every reader: `info` never says OK for a bundle `render` refuses).
pub fn run(a: Args, out: &Out) -> Result<()> {
    let b = Bundle::read(&a.bundle)?;
    let baked = from_bundle(&b, &a.bundle)?;
    out.line(format!(
        "{}: relight bundle, format version {}, {:.2} MiB, checksums and contents OK",
        a.bundle.display(),
        relight_bundle::FORMAT_VERSION,
        args::mib(&a.bundle)
    ));
    for (k, v) in &b.metadata {
        let short = match v.char_indices().nth(200) {
            Some((i, _)) => format!("{}... ({} chars)", &v[..i], v.len()),
            None => v.clone(),
        };
        out.line(format!("  {k}: {short}"));
    }
    out.line("  tensors:");
    for (name, t) in &b.tensors {
        out.line(format!(
            "    {name:<18} {:<4} {:?} ({} bytes)",
            t.dtype.name(),
            t.shape,
            t.bytes.len()
        ));
    }
    let objects = baked.scene().object_summaries();
    out.line(format!("  objects ({}):", objects.len()));
    for o in &objects {
        let mats: Vec<String> = o.materials.iter().map(|m| m.short()).collect();
        out.line(format!(
            "    {:<16} {} vertices, {} triangles, {}",
            o.name,
            o.vertices,
            o.triangles,
            mats.join("; ")
        ));
    }
    let methods: Vec<&str> = baked.kind().methods().iter().map(|m| m.name()).collect();
    out.line(format!("  renders with --method {}", methods.join(", ")));
    // The method's own figures under its name (null for the others).
    let mut details = json!({"sg": null, "cuts": null, "vmf": null});
    if let Some((lines, j)) = baked.describe() {
        let tensor_bytes: usize = b.tensors.values().map(|t| t.bytes.len()).sum();
        for l in lines {
            out.line(format!("  {l}"));
        }
        let v = baked.scene().mesh.vertex_count().max(1);
        out.line(format!(
            "  all tensors: {} bytes per vertex",
            tensor_bytes / v
        ));
        details[baked.kind().name()] = j;
    }
    let tensors: serde_json::Map<String, serde_json::Value> = b
        .tensors
        .iter()
        .map(|(n, t)| {
            (
                n.clone(),
                json!({"dtype": t.dtype.name(), "shape": t.shape, "bytes": t.bytes.len()}),
            )
        })
        .collect();
    out.summary(json!({
        "command": "info",
        "bundle": a.bundle,
        "format_version": relight_bundle::FORMAT_VERSION,
        "bytes": std::fs::metadata(&a.bundle).map_or(0, |m| m.len()),
        "valid": true,
        "method": baked.kind().name(),
        "renders_with": methods,
        "vertices": baked.scene().mesh.vertex_count(),
        "triangles": baked.scene().mesh.triangle_count(),
        "record": baked.record(),
        "objects": objects,
        "metadata": b.metadata,
        "tensors": tensors,
        "sg": details["sg"],
        "cuts": details["cuts"],
        "vmf": details["vmf"],
    }));
    Ok(())
}

/// Arguments of `relight project`.
#[derive(clap::Args)]
pub struct ProjectArgs {
    /// Environment map (.hdr / .exr; latlong, vertical cross or angular probe).
    pub env: PathBuf,
    /// SH order n (n^2 coefficients).
    #[arg(long, visible_alias = "order", default_value_t = 3)]
    pub sh_order: usize,
    /// Layout (latlong, cube, probe); detected from the aspect ratio when absent.
    #[arg(long)]
    pub layout: Option<String>,
}

/// Print the SH projection of an environment.
pub fn project(a: ProjectArgs, out: &Out) -> Result<()> {
    ensure!(
        (1..=sh::MAX_ORDER).contains(&a.sh_order),
        "--sh-order {} is not in 1..={}",
        a.sh_order,
        sh::MAX_ORDER
    );
    let map = relight_scene::io::load_env(&a.env, args::layout(a.layout.as_deref())?)?;
    let c = sh::project_env(&map, a.sh_order);
    if let Some(i) = c.iter().position(|v| !v.is_finite()) {
        anyhow::bail!(
            "{}: the projection overflows (coefficient {i} is not finite): the map's radiance is beyond f32",
            a.env.display()
        );
    }
    out.line(format!(
        "# SH projection of {} (order {}, real orthonormal, R&H 2001 basis on world x,y,z)",
        a.env.display(),
        a.sh_order
    ));
    out.line("# l  m        r            g            b");
    let mut rows = vec![];
    for l in 0..a.sh_order as i32 {
        for m in -l..=l {
            let v = c[sh::sh_index(l, m)];
            out.line(format!(
                "{l:3} {m:3} {:12.6} {:12.6} {:12.6}",
                v.x, v.y, v.z
            ));
            rows.push(json!({"l": l, "m": m, "rgb": v.to_array()}));
        }
    }
    out.summary(
        json!({"command": "project", "env": a.env, "sh_order": a.sh_order, "coefficients": rows}),
    );
    Ok(())
}
