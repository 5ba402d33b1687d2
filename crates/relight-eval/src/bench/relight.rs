//! SH relighting per frame against the memory bandwidth (section "SH relight").
//!
//! A frame of the `sh` method streams the transfer array once
//! ([`relight_render::shade_sh::vertex_radiance`]), so its bound is the machine's memory
//! bandwidth: [`bench_relight`] measures it against a STREAM-like copy (McCalpin's STREAM
//! "Copy" kernel, bytes counted as read + written) on the same machine in the same run.

use super::{median_ms, Section};
use glam::Vec3;
use rayon::prelude::*;
use relight_bake::sh::{ShTransfer, ShTransferKind};
use relight_render::shade_sh::vertex_radiance;
use relight_sphere::sh::sh_count;
use serde_json::json;

/// Result of [`bench_relight`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelightBench {
    /// Median wall time of one [`vertex_radiance`] call, milliseconds.
    pub ms_per_frame: f64,
    /// Bytes one frame must move at least: transfer read + albedo read + radiance written.
    pub bytes_per_frame: u64,
    /// Multi-threaded STREAM-like copy bandwidth measured in the same run, GB/s (1e9 B/s,
    /// read + written bytes).
    pub stream_copy_gbps: f64,
    /// Achieved relighting bandwidth over the copy bandwidth: `(bytes_per_frame / ms) /
    /// stream_copy`; 1 means as fast as memory allows, above 1 means the data partly fits in
    /// cache.
    pub ratio_to_bandwidth_bound: f64,
    /// Rayon threads used.
    pub threads: usize,
}

/// Benchmark relighting `vertices` vertices of synthetic single-channel transfer of SH `order`
/// with per-vertex albedo (the default `Shadowed` bake) against a STREAM-like copy between two
/// 128 MiB buffers, both on rayon's current pool. Takes about a second for a million vertices.
///
/// # Panics
/// Debug builds: `vertices == 0` or `order` outside `1..=MAX_ORDER`.
pub fn bench_relight(vertices: usize, order: usize) -> RelightBench {
    debug_assert!(vertices > 0 && (1..=relight_sphere::sh::MAX_ORDER).contains(&order));
    let n2 = sh_count(order);
    // Synthetic but non-trivial data (a cheap hash), so nothing folds away.
    let data: Vec<f32> = (0..vertices * n2)
        .into_par_iter()
        .map(|i| ((i as u32).wrapping_mul(2_654_435_761) >> 8) as f32 * (1.0 / 16_777_216.0) - 0.5)
        .collect();
    let transfer = ShTransfer {
        order,
        kind: ShTransferKind::Shadowed,
        vertex_count: vertices,
        channels: 1,
        data,
    };
    let albedo = vec![Vec3::splat(0.5); vertices];
    let light: Vec<Vec3> = (0..n2)
        .map(|i| Vec3::new(1.0, 0.5, 0.25) / (1 + i) as f32)
        .collect();
    let mut out = vec![Vec3::ZERO; vertices];
    let ms_per_frame = median_ms(7, || {
        vertex_radiance(&transfer, Some(&albedo), &light, &mut out)
    });
    std::hint::black_box(&out);
    let bytes_per_frame = (vertices * (4 * n2 + 12 + 12)) as u64;

    // STREAM-like copy: a[i] = b[i] between two 128 MiB arrays (well beyond any last-level
    // cache), chunked over the same pool.
    let len = 32 << 20; // f32s
    let src: Vec<f32> = (0..len).into_par_iter().map(|i| i as f32).collect();
    let mut dst = vec![0.0f32; len];
    let copy_ms = median_ms(5, || {
        dst.par_chunks_mut(1 << 16)
            .zip(src.par_chunks(1 << 16))
            .for_each(|(d, s)| d.copy_from_slice(s));
    });
    std::hint::black_box(&dst);
    let stream_copy_gbps = (2 * 4 * len) as f64 / (copy_ms * 1e-3) / 1e9;
    let achieved_gbps = bytes_per_frame as f64 / (ms_per_frame * 1e-3) / 1e9;
    RelightBench {
        ms_per_frame,
        bytes_per_frame,
        stream_copy_gbps,
        ratio_to_bandwidth_bound: achieved_gbps / stream_copy_gbps,
        threads: rayon::current_num_threads(),
    }
}

/// The section: [`bench_relight`] of `vertices` vertices at SH `order`.
pub(super) fn section(vertices: usize, order: usize) -> Section {
    let r = bench_relight(vertices, order);
    let mut sec = Section::new(
        format!("SH relight: {vertices} vertices, order {order}, single-channel transfer + albedo"),
        &[
            "ms/frame",
            "MB/frame",
            "achieved GB/s",
            "STREAM copy GB/s",
            "time over bandwidth bound",
        ],
    );
    let achieved = r.bytes_per_frame as f64 / (r.ms_per_frame * 1e-3) / 1e9;
    sec.row(vec![
        json!(r.ms_per_frame),
        json!(r.bytes_per_frame as f64 / 1e6),
        json!(achieved),
        json!(r.stream_copy_gbps),
        json!(1.0 / r.ratio_to_bandwidth_bound),
    ]);
    sec
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_reports_consistent_figures() {
        let b = bench_relight(20_000, 3);
        assert!(
            b.ms_per_frame > 0.0 && b.stream_copy_gbps > 0.0 && b.ratio_to_bandwidth_bound > 0.0
        );
        assert_eq!(b.bytes_per_frame, 20_000 * (4 * 9 + 24));
    }
}
