//! Bakes under a memory budget (`relight bake --memory-limit`): a bake whose rows would not fit
//! is baked in chunks written to disk ([`crate::checkpoint`]) and merged by streaming
//! ([`crate::shard::merge_files`]), instead of failing.
//!
//! # The model
//! A whole bake in memory peaks at `resident + accel + 3 V r` bytes: what the process holds
//! before baking (scene, mesh), the ray-casting structure (`ACCEL_BYTES_PER_TRIANGLE` per
//! triangle, above what Embree and our BVH use), and three copies of the `V` rows of `r`
//! bytes each ([`Method::row_bytes`]): the bake's arrays, the bundle's tensors and the
//! bundle's bytes. A chunk of `c` vertices peaks at `3 c r`, and the streamed merge at three
//! copies of one chunk (its file, its tensors, the checked bake); chunks are sized so that
//! `4 c r` fits in what the limit leaves after a reserve of an eighth of it
//! ([`RESERVE_DIVISOR`]).
//!
//! Methods whose merge needs every row at once cannot stream: interreflected `sh` (each bounce
//! gathers every vertex) and `sg` (the merge aligns regions over the whole mesh). Over the
//! limit they are refused with the estimate, before any baking.

use crate::{BakeInput, Method, MethodError};

/// Bytes of ray-casting structure per triangle assumed by the model (module docs).
pub const ACCEL_BYTES_PER_TRIANGLE: u64 = 128;

/// Share of the limit kept for what the model does not see (allocator slack, thread stacks,
/// the ray caster's build temporaries): chunks are sized to `(1 - 1/RESERVE_DIVISOR)` of it.
/// A 1.36M-vertex bake sized to the whole limit peaked 2.2 % over it.
pub const RESERVE_DIVISOR: u64 = 8;

/// How a bake fits in its budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryPlan {
    /// Whole, in memory: the estimate fits.
    Whole {
        /// Estimated peak, bytes.
        estimate: u64,
    },
    /// In chunks of `chunk_vertices` streamed through the disk.
    Chunks {
        /// Vertices per chunk.
        chunk_vertices: usize,
        /// Estimated peak of the whole bake in memory, bytes (over the limit).
        whole: u64,
        /// Estimated peak in chunks, bytes.
        estimate: u64,
    },
}

/// Parse a size: bytes, or a number with `K`, `M`, `G`, `T` (powers of 1024; `KiB`, `MB`...
/// read the same), e.g. `2G`, `512M`, `1.5GiB`.
///
/// # Errors
/// [`MethodError::Settings`] naming the text.
pub fn parse_size(s: &str) -> Result<u64, MethodError> {
    let bad = || {
        MethodError::Settings(format!(
            "--memory-limit {s:?}: not a size (bytes, or a number with K, M, G or T, e.g. 2G)"
        ))
    };
    let t = s.trim();
    let cut = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(cut);
    let x: f64 = num.parse().map_err(|_| bad())?;
    let shift = match unit
        .trim()
        .to_ascii_uppercase()
        .trim_end_matches("IB")
        .trim_end_matches('B')
    {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(bad()),
    };
    let bytes = x * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(bad());
    }
    Ok(bytes as u64)
}

/// Plan the bake of `input` with `M` under `limit` bytes, the process holding `resident`
/// bytes now (module docs).
///
/// # Errors
/// [`MethodError::Settings`] with the estimates when the bake cannot fit: the scene alone
/// over the limit, or a method that cannot stream over it.
pub fn plan<M: Method>(
    input: BakeInput,
    settings: &M::Settings,
    limit: u64,
    resident: u64,
) -> Result<MemoryPlan, MethodError> {
    let mesh = &input.scene.mesh;
    let v = mesh.vertex_count() as u64;
    let row = M::row_bytes(input, settings).max(1);
    let base = resident.saturating_add(mesh.triangle_count() as u64 * ACCEL_BYTES_PER_TRIANGLE);
    let whole = base.saturating_add(v.saturating_mul(row).saturating_mul(3));
    if whole <= limit {
        return Ok(MemoryPlan::Whole { estimate: whole });
    }
    let gib = |b: u64| b as f64 / f64::from(1u32 << 30);
    let over = format!(
        "--memory-limit {:.2} GiB: this bake needs about {:.2} GiB in memory ({:.2} GiB of scene and ray-casting structure, {} vertices of {row} bytes, three copies)",
        gib(limit),
        gib(whole),
        gib(base),
        v
    );
    if let Some(why) = M::streams(settings) {
        return Err(MethodError::Settings(format!(
            "{over}; it cannot be baked in chunks: {why}"
        )));
    }
    let usable = limit - limit / RESERVE_DIVISOR;
    if base >= usable {
        return Err(MethodError::Settings(format!(
            "{over}; the scene and its ray-casting structure alone take more than the limit (less its 1/{RESERVE_DIVISOR} reserve)"
        )));
    }
    let chunk = ((usable - base) / (4 * row)).max(1);
    Ok(MemoryPlan::Chunks {
        chunk_vertices: usize::try_from(chunk).unwrap_or(usize::MAX),
        whole,
        estimate: base + 4 * chunk.min(v) * row,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::Sh;
    use crate::test_scene::with_input;
    use relight_bake::sh::{ShBakeSettings, ShTransferKind};

    #[test]
    fn sizes_are_parsed_or_refused_by_name() {
        assert_eq!(parse_size("2G").unwrap(), 2 << 30);
        assert_eq!(parse_size("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_size("1.5 GB").unwrap(), 3 << 29);
        assert_eq!(parse_size("4096").unwrap(), 4096);
        for bad in ["", "G", "2X", "-1G", "0", "1e30T"] {
            let e = parse_size(bad).unwrap_err().to_string();
            assert!(e.contains("--memory-limit"), "{bad}: {e}");
        }
    }

    #[test]
    fn bakes_over_the_limit_are_chunked_or_refused_with_the_estimate() {
        let s = ShBakeSettings {
            order: 8,
            ..Default::default()
        };
        with_input(0.5, |input| {
            let v = input.scene.mesh.vertex_count() as u64;
            let row = Sh::row_bytes(input, &s);
            assert_eq!(row, 64 * 4 + 12);
            let Ok(MemoryPlan::Whole { estimate }) = plan::<Sh>(input, &s, u64::MAX, 1000) else {
                panic!("no limit")
            };
            // A limit leaving room for a tenth of the rows after the reserve: chunks of a
            // fortieth.
            let base = estimate - 3 * v * row;
            let usable = base + v * row / 10;
            let limit = usable * RESERVE_DIVISOR / (RESERVE_DIVISOR - 1) + 1;
            let Ok(MemoryPlan::Chunks {
                chunk_vertices,
                whole,
                estimate: e,
            }) = plan::<Sh>(input, &s, limit, 1000)
            else {
                panic!("chunks")
            };
            assert_eq!(whole, estimate);
            assert!(e <= limit, "{e} > {limit}");
            let left = limit - limit / RESERVE_DIVISOR - base;
            assert_eq!(chunk_vertices as u64, left / (4 * row));
            assert!(
                (chunk_vertices as u64).abs_diff(v / 40) <= 1,
                "{chunk_vertices} of {v}"
            );
            // The scene alone over the limit, and interreflected transfer, are refused.
            let e = plan::<Sh>(input, &s, 1000, 1000).unwrap_err().to_string();
            assert!(e.contains("scene") && e.contains("GiB"), "{e}");
            let ir = ShBakeSettings {
                transfer: ShTransferKind::Interreflected,
                ..s
            };
            let e = plan::<Sh>(input, &ir, limit, 1000).unwrap_err().to_string();
            assert!(
                e.contains("cannot be baked in chunks") && e.contains("bounce"),
                "{e}"
            );
        });
    }
}
