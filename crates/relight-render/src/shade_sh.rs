//! Per-vertex relighting with baked SH transfer: the per-frame cost of the `sh` method.
//!
//! `L_o(v) = rho_v sum_i T_v,i L_i` for single-channel transfer (albedo applied here, so it
//! stays editable) and `L_o(v)_c = sum_i T_v,i,c L_i,c` for RGB transfer (albedo baked in);
//! see `relight_bake::sh` for what `T` includes and its layout. `light` holds the
//! environment's RGB SH coefficients (`relight_sphere::sh::project_env`), already rotated into
//! the world frame (`ShRotation`); only the first `n^2` are used.
//!
//! The kernels stream the transfer array once, front to back (vertex-major, coefficient-major,
//! channel innermost), with the light held in L1 in SIMD-ready form: for single-channel
//! transfer, per-channel planes of 4 coefficients (one 4-wide multiply-add per channel per 4
//! coefficients, two accumulators per channel); for RGB transfer, one `Vec3A` per coefficient
//! (one multiply-add of the RGB triple, four accumulators to hide add latency). That portable
//! single-channel kernel turned out compute-bound (about 40 cycles per order-5 vertex per core,
//! the same in and out of cache), so on CPUs with AVX2 and FMA a run-time-selected kernel
//! (`shade_sh/avx2.rs`: 8-wide fused multiply-adds against zero-padded light planes) does the
//! single-channel case, which makes a frame memory-bandwidth bound: `relight bench` (section
//! "SH relight") measures it against a STREAM-like copy (McCalpin's STREAM "Copy" kernel, bytes
//! counted as read + written) on the same machine in the same run.

use glam::{Vec3, Vec3A, Vec4};
use rayon::prelude::*;
use relight_bake::sh::ShTransfer;
use relight_sphere::sh::sh_count;

/// Vertices per parallel work item.
const CHUNK: usize = 2048;

#[cfg(target_arch = "x86_64")]
mod avx2;

/// `RELIGHT_PORTABLE_KERNELS=1` disables the run-time-selected SIMD kernels (for comparisons
/// and for machines where they misbehave).
fn force_portable() -> bool {
    std::env::var_os("RELIGHT_PORTABLE_KERNELS").is_some_and(|v| v == "1")
}

/// Outgoing radiance of every vertex under SH lighting `light`, written to `out`.
///
/// `albedo_per_vertex` multiplies single-channel transfer (`None` = albedo 1: the result is
/// then the transfer-weighted irradiance over pi); it is ignored for RGB transfer, which
/// includes albedo.
///
/// # Panics
/// If `out` or `albedo_per_vertex` do not have one entry per vertex, or `light` has fewer than
/// `n^2` coefficients.
pub fn vertex_radiance(
    transfer: &ShTransfer,
    albedo_per_vertex: Option<&[Vec3]>,
    light: &[Vec3],
    out: &mut [Vec3],
) {
    let n2 = sh_count(transfer.order);
    let stride = transfer.stride();
    assert_eq!(out.len(), transfer.vertex_count, "one output per vertex");
    assert!(
        light.len() >= n2,
        "light has {} coefficients, transfer needs {n2}",
        light.len()
    );
    debug_assert_eq!(transfer.data.len(), transfer.vertex_count * stride);
    let light_coeffs = light;
    match transfer.channels {
        1 => {
            let light = MonoLight::new(&light[..n2]);
            if let Some(a) = albedo_per_vertex {
                assert_eq!(a.len(), transfer.vertex_count, "one albedo per vertex");
            }
            #[cfg(target_arch = "x86_64")]
            if avx2::available() && !force_portable() {
                let planes = avx2::Planes::new(&light_coeffs[..n2]);
                out.par_chunks_mut(CHUNK)
                    .zip(transfer.data.par_chunks(CHUNK * stride))
                    .enumerate()
                    .for_each(|(ci, (out, data))| {
                        let albedo =
                            albedo_per_vertex.map(|a| &a[ci * CHUNK..ci * CHUNK + out.len()]);
                        // SAFETY: AVX2 and FMA were detected above; transfer data is finite
                        // (`ShTransfer::validate`, checked for every baked or loaded bundle).
                        unsafe {
                            avx2::shade_slice(data, stride, &planes, albedo, out, |t| light.dot(t))
                        }
                    });
                return;
            }
            out.par_chunks_mut(CHUNK)
                .zip(transfer.data.par_chunks(CHUNK * stride))
                .enumerate()
                .for_each(|(ci, (out, data))| {
                    for (k, (o, t)) in out.iter_mut().zip(data.chunks_exact(stride)).enumerate() {
                        let rho = albedo_per_vertex.map_or(Vec3::ONE, |a| a[ci * CHUNK + k]);
                        *o = rho * Vec3::from(light.dot(t));
                    }
                });
        }
        _ => {
            // 16-byte SIMD copies of the light, exactly n^2 of them (the kernel relies on it).
            let light: Vec<Vec3A> = light[..n2].iter().map(|&l| l.into()).collect();
            out.par_chunks_mut(CHUNK)
                .zip(transfer.data.par_chunks(CHUNK * stride))
                .for_each(|(out, data)| {
                    for (o, t) in out.iter_mut().zip(data.chunks_exact(stride)) {
                        *o = Vec3::from(dot_rgb(t, &light));
                    }
                });
        }
    }
}

/// Convenience: [`vertex_radiance`] into a new vector.
pub fn shade(
    transfer: &ShTransfer,
    albedo_per_vertex: Option<&[Vec3]>,
    light: &[Vec3],
) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; transfer.vertex_count];
    vertex_radiance(transfer, albedo_per_vertex, light, &mut out);
    out
}

/// Independent accumulators of the RGB kernel: enough to hide the latency of SIMD adds.
const ACC: usize = 4;

/// The light for single-channel transfer: channel planes of 4 coefficients each (`r[k]` holds
/// coefficients `4k..4k+3` of red), and the last `n^2 mod 4` coefficients as RGB.
struct MonoLight {
    r: Vec<Vec4>,
    g: Vec<Vec4>,
    b: Vec<Vec4>,
    tail: Vec<Vec3A>,
}

impl MonoLight {
    fn new(light: &[Vec3]) -> Self {
        let quads = light.len() / 4;
        let plane = |c: usize| -> Vec<Vec4> {
            (0..quads)
                .map(|k| Vec4::from_array(std::array::from_fn(|j| light[4 * k + j][c])))
                .collect()
        };
        let tail = light[4 * quads..].iter().map(|&l| l.into()).collect();
        MonoLight {
            r: plane(0),
            g: plane(1),
            b: plane(2),
            tail,
        }
    }

    /// `sum_i t_i L_i` for one vertex's single-channel transfer `t` (as long as the light):
    /// 4 coefficients per SIMD multiply-add, two accumulators per channel.
    #[inline]
    fn dot(&self, t: &[f32]) -> Vec3A {
        let (mut ar, mut ag, mut ab) = ([Vec4::ZERO; 2], [Vec4::ZERO; 2], [Vec4::ZERO; 2]);
        let mut tc = t.chunks_exact(8);
        let (mut rc, mut gc, mut bc) = (
            self.r.chunks_exact(2),
            self.g.chunks_exact(2),
            self.b.chunks_exact(2),
        );
        for (((tt, r), g), b) in (&mut tc).zip(&mut rc).zip(&mut gc).zip(&mut bc) {
            for j in 0..2 {
                let t4 = Vec4::from_slice(&tt[4 * j..4 * j + 4]);
                ar[j] += t4 * r[j];
                ag[j] += t4 * g[j];
                ab[j] += t4 * b[j];
            }
        }
        // An odd quad left over, then fewer than 4 coefficients.
        let rem = tc.remainder();
        if let ([r], [g], [b]) = (rc.remainder(), gc.remainder(), bc.remainder()) {
            let t4 = Vec4::from_slice(&rem[..4]);
            ar[0] += t4 * *r;
            ag[0] += t4 * *g;
            ab[0] += t4 * *b;
        }
        let (r, g, b) = (ar[0] + ar[1], ag[0] + ag[1], ab[0] + ab[1]);
        let mut acc = Vec3A::new(r.element_sum(), g.element_sum(), b.element_sum());
        for (&ti, &li) in rem[rem.len() / 4 * 4..].iter().zip(&self.tail) {
            acc += li * ti;
        }
        acc
    }
}

/// `sum_i t_i,c L_i,c` for one vertex's interleaved RGB transfer `t`
/// (`t.len() == 3 * light.len()`).
#[inline]
fn dot_rgb(t: &[f32], light: &[Vec3A]) -> Vec3A {
    let mut acc = [Vec3A::ZERO; ACC];
    let (mut tc, mut lc) = (t.chunks_exact(3 * ACC), light.chunks_exact(ACC));
    for (tt, ll) in (&mut tc).zip(&mut lc) {
        for j in 0..ACC {
            acc[j] += ll[j] * Vec3A::new(tt[3 * j], tt[3 * j + 1], tt[3 * j + 2]);
        }
    }
    for (tt, &li) in tc.remainder().chunks_exact(3).zip(lc.remainder()) {
        acc[0] += li * Vec3A::new(tt[0], tt[1], tt[2]);
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_bake::sh::ShTransferKind;

    fn synthetic(order: usize, kind: ShTransferKind, vertices: usize) -> ShTransfer {
        let stride = sh_count(order) * kind.channels();
        let data = (0..vertices * stride)
            .map(|i| ((i * 7919) % 1000) as f32 / 500.0 - 1.0)
            .collect();
        ShTransfer {
            order,
            kind,
            vertex_count: vertices,
            channels: kind.channels(),
            data,
        }
    }

    #[test]
    fn fast_kernel_matches_the_reference_for_every_order_and_kind() {
        let n = 2 * CHUNK + 37; // several chunks and a ragged last one
        for order in 1..=10 {
            let light: Vec<Vec3> = (0..sh_count(order) + 3)
                .map(|i| Vec3::new(1.0 + i as f32, 0.5 - i as f32 * 0.1, (i as f32).sin()))
                .collect();
            let albedo: Vec<Vec3> = (0..n)
                .map(|v| Vec3::new(0.2, 0.5, (v % 10) as f32 / 10.0))
                .collect();
            for kind in [ShTransferKind::Shadowed, ShTransferKind::Interreflected] {
                let t = synthetic(order, kind, n);
                t.validate().unwrap();
                for alb in [None, Some(albedo.as_slice())] {
                    let fast = shade(&t, alb, &light);
                    for v in (0..n).step_by(13) {
                        let rho = alb.map_or(Vec3::ONE, |a| a[v]);
                        let slow = t.eval_vertex(v, rho, &light);
                        // 1e-5 relative to the sum of |terms|: f32 summation in another order.
                        let scale = (0..sh_count(order))
                            .map(|i| light[i].abs().max_element())
                            .sum::<f32>()
                            * 3.0;
                        assert!(
                            (fast[v] - slow).abs().max_element() <= 1e-5 * scale,
                            "order {order} {kind:?} v{v}: {} vs {slow}",
                            fast[v]
                        );
                    }
                }
            }
        }
    }

    /// The run-time-selected AVX2/FMA kernel against the portable one, on every vertex
    /// (including the last vertex of each work slice, which falls back to the portable path).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_kernel_matches_the_portable_one_on_every_vertex() {
        if !avx2::available() {
            relight_testdata::skip_platform("avx2", "no AVX2/FMA on this CPU");
            return;
        }
        let n = CHUNK + 301;
        for order in [1, 2, 3, 4, 5, 6, 9, 10] {
            let t = synthetic(order, ShTransferKind::Shadowed, n);
            let light: Vec<Vec3> = (0..sh_count(order))
                .map(|i| Vec3::new(0.3 + i as f32, 1.0 - 0.07 * i as f32, (i as f32).cos()))
                .collect();
            let albedo: Vec<Vec3> = (0..n).map(|v| Vec3::splat((v % 7) as f32 / 7.0)).collect();
            let fast = shade(&t, Some(&albedo), &light);
            let mono = MonoLight::new(&light);
            let scale = light.iter().map(|l| l.abs().max_element()).sum::<f32>();
            for v in 0..n {
                let slow = albedo[v] * Vec3::from(mono.dot(t.vertex(v)));
                assert!(
                    (fast[v] - slow).abs().max_element() <= 1e-5 * scale,
                    "order {order} v{v}: {} vs {slow}",
                    fast[v]
                );
            }
        }
    }

    #[test]
    fn constant_light_gives_albedo_under_unoccluded_dc_transfer() {
        // T_0 = y_0 (unoccluded cosine transfer), L_0 = 2 sqrt(pi) (radiance 1): L_o = albedo.
        let mut t = synthetic(3, ShTransferKind::Shadowed, 4);
        t.data
            .iter_mut()
            .enumerate()
            .for_each(|(i, x)| *x = if i % 9 == 0 { 0.282_094_8 } else { 0.0 });
        let mut light = vec![Vec3::ZERO; 9];
        light[0] = Vec3::splat(2.0 * std::f32::consts::PI.sqrt());
        let rho = [Vec3::new(0.1, 0.5, 0.9); 4];
        for o in shade(&t, Some(&rho), &light) {
            assert!((o - rho[0]).abs().max_element() < 1e-6);
        }
    }
}
