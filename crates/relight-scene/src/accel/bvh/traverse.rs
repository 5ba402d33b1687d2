//! Traversal of relight's BVH (see `bvh.rs` for the method and citations): per-ray set-up,
//! the 8-wide slab test (AVX2 or portable), the 4-wide watertight triangle test, child
//! sorting networks, and the closest-hit and occlusion loops.

use super::{Bvh, Node8, TriPack, LEAF_BIT, ROBUST_FAR, STACK};
use crate::accel::{Hit, Ray, RayCaster};
use crate::Vec3;
use std::mem::MaybeUninit;

/// Per-ray constants for the slab and triangle tests.
struct RayPre {
    org: [f32; 3],
    /// `1 / dir`, with zero components replaced by `±f32::MAX` (finite, so `0 * inv = 0`).
    inv: [f32; 3],
    /// Per axis: whether `inv < 0` (the near plane is the box's `hi`).
    neg: [bool; 3],
    tmin: f32,
    /// Woop et al.: the axis of largest |dir| is `kz`; `(kx, ky)` keep the winding.
    k: [usize; 3],
    /// Shear `(dx/dz, dy/dz, 1/dz)` in the permuted axes.
    s: [f32; 3],
}

impl RayPre {
    #[inline(always)]
    fn new(r: &Ray) -> RayPre {
        debug_assert!(
            r.dir != Vec3::ZERO && r.dir.is_finite(),
            "bad ray direction {:?}",
            r.dir
        );
        debug_assert!(r.origin.is_finite(), "bad ray origin {:?}", r.origin);
        debug_assert!(r.tmin >= 0.0 && r.tmin <= r.tmax, "bad ray interval {r:?}");
        let d = r.dir.to_array();
        let inv = d.map(|x| {
            let i = 1.0 / x;
            if i.is_finite() {
                i
            } else {
                f32::MAX.copysign(x)
            }
        });
        let ad = r.dir.abs();
        let kz = ad.max_position();
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        RayPre {
            org: r.origin.to_array(),
            inv,
            neg: inv.map(|i| i < 0.0),
            tmin: r.tmin,
            k: [kx, ky, kz],
            s: [d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]],
        }
    }

    /// Slab test of the 8 child boxes for `t` in `[tmin, tmax]`: bit mask of hit children and
    /// their entry distances.
    #[inline(always)]
    fn boxes(&self, n: &Node8, tmax: f32) -> (u32, [f32; 8]) {
        let mut tn = [self.tmin; 8];
        let mut tf = [tmax; 8];
        for a in 0..3 {
            let (near, far) = if self.neg[a] {
                (&n.hi[a], &n.lo[a])
            } else {
                (&n.lo[a], &n.hi[a])
            };
            let (o, inv) = (self.org[a], self.inv[a]);
            for i in 0..8 {
                let t0 = (near[i] - o) * inv;
                let t1 = (far[i] - o) * inv;
                tn[i] = if t0 > tn[i] { t0 } else { tn[i] };
                tf[i] = if t1 < tf[i] { t1 } else { tf[i] };
            }
        }
        let mut mask = 0u32;
        for i in 0..8 {
            mask |= ((tn[i] <= tf[i] * ROBUST_FAR) as u32) << i;
        }
        (mask, tn)
    }

    /// The slab test of [`RayPre::boxes`] in AVX (8 lanes at once).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn boxes_avx(&self, n: &Node8, tmax: f32) -> (u32, [f32; 8]) {
        use std::arch::x86_64::*;
        let mut tn = _mm256_set1_ps(self.tmin);
        let mut tf = _mm256_set1_ps(tmax);
        for a in 0..3 {
            let (near, far) = if self.neg[a] {
                (&n.hi[a], &n.lo[a])
            } else {
                (&n.lo[a], &n.hi[a])
            };
            let (o, inv) = (_mm256_set1_ps(self.org[a]), _mm256_set1_ps(self.inv[a]));
            // SAFETY: `Node8` is 64-byte aligned and each row is 32 bytes at a 32-byte offset.
            let (pn, pf) = unsafe { (_mm256_load_ps(near.as_ptr()), _mm256_load_ps(far.as_ptr())) };
            let t0 = _mm256_mul_ps(_mm256_sub_ps(pn, o), inv);
            let t1 = _mm256_mul_ps(_mm256_sub_ps(pf, o), inv);
            tn = _mm256_max_ps(t0, tn);
            tf = _mm256_min_ps(t1, tf);
        }
        let hit = _mm256_cmp_ps::<_CMP_LE_OQ>(tn, _mm256_mul_ps(tf, _mm256_set1_ps(ROBUST_FAR)));
        let mut out = [0f32; 8];
        // SAFETY: `out` holds 8 floats.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), tn) };
        (_mm256_movemask_ps(hit) as u32, out)
    }

    /// Slab test through the AVX path when `AVX` (checked by the caller), else the portable one.
    #[inline(always)]
    fn boxes_with<const AVX: bool>(&self, n: &Node8, tmax: f32) -> (u32, [f32; 8]) {
        #[cfg(target_arch = "x86_64")]
        if AVX {
            // SAFETY: `AVX` is only true on paths entered after detecting AVX2 and FMA.
            return unsafe { self.boxes_avx(n, tmax) };
        }
        self.boxes(n, tmax)
    }

    /// Watertight test of the 4 triangles of `p` for `t` in `[tmin, tmax]`: the hit mask and,
    /// per lane, the unnormalised barycentrics `[V, W]`, the scaled distance `T` and the
    /// determinant (`t = T / det`, `u = V / det`, `v = W / det`). No division: the interval
    /// test compares `T` against `t * det` with the sign of `det` folded in (as in the paper).
    /// Written lane-wise over `[f32; 4]` so it compiles to 4-wide SIMD.
    #[inline(always)]
    fn tris(&self, p: &TriPack, tmax: f32) -> (u32, [[f32; 4]; 4]) {
        let [kx, ky, kz] = self.k;
        let (ox, oy, oz) = (self.org[kx], self.org[ky], self.org[kz]);
        // Corners relative to the origin, sheared so the ray is the +z axis.
        #[inline(always)]
        fn shear(
            c: &[[f32; 4]; 3],
            [kx, ky, kz]: [usize; 3],
            o: [f32; 3],
            s: [f32; 3],
        ) -> [[f32; 4]; 3] {
            let (px, py, pz) = (&c[kx], &c[ky], &c[kz]);
            let mut r = [[0f32; 4]; 3];
            for i in 0..4 {
                let d = pz[i] - o[2];
                r[0][i] = (px[i] - o[0]) - s[0] * d;
                r[1][i] = (py[i] - o[1]) - s[1] * d;
                r[2][i] = s[2] * d;
            }
            r
        }
        let o = [ox, oy, oz];
        let [ax, ay, az] = shear(&p.v[0], self.k, o, self.s);
        let [bx, by, bz] = shear(&p.v[1], self.k, o, self.s);
        let [cx, cy, cz] = shear(&p.v[2], self.k, o, self.s);
        let mut out = [[0f32; 4]; 4];
        let mut mask = 0u32;
        for i in 0..4 {
            // 2D edge functions: U opposite a, V opposite b, W opposite c.
            let u = cx[i] * by[i] - cy[i] * bx[i];
            let v = ax[i] * cy[i] - ay[i] * cx[i];
            let w = bx[i] * ay[i] - by[i] * ax[i];
            let det = u + v + w;
            let tt = u * az[i] + v * bz[i] + w * cz[i];
            // T * sign(det) against [tmin, tmax] * |det|.
            let sign = det.to_bits() & 0x8000_0000;
            let t_abs = f32::from_bits(tt.to_bits() ^ sign);
            let det_abs = det.abs();
            let inside =
                ((u >= 0.0) & (v >= 0.0) & (w >= 0.0)) | ((u <= 0.0) & (v <= 0.0) & (w <= 0.0));
            let ok =
                inside & (det != 0.0) & (t_abs >= self.tmin * det_abs) & (t_abs <= tmax * det_abs);
            mask |= (ok as u32) << i;
            out[0][i] = v;
            out[1][i] = w;
            out[2][i] = tt;
            out[3][i] = det;
        }
        (mask, out)
    }
}

/// Compare-exchange pairs of local variables: `cas!(a b, c d)` puts the smaller first.
macro_rules! cas {
    ($($a:ident $b:ident),*) => {$(
        let (x, y) = ($a, $b);
        $a = x.min(y);
        $b = x.max(y);
    )*};
}

/// Sort the first 4 of 8 keys ascending (5-comparator network).
#[inline(always)]
pub(super) fn sort4(k: &mut [u64; 8]) {
    let [mut k0, mut k1, mut k2, mut k3, ..] = *k;
    cas!(k0 k1, k2 k3);
    cas!(k0 k2, k1 k3);
    cas!(k1 k2);
    k[..4].copy_from_slice(&[k0, k1, k2, k3]);
}

/// Sort 8 keys ascending with Knuth's 19-comparator network (branch-free min/max, so no
/// mispredictions on random ray data).
#[inline(always)]
pub(super) fn sort8(k: &mut [u64; 8]) {
    let [mut k0, mut k1, mut k2, mut k3, mut k4, mut k5, mut k6, mut k7] = *k;
    cas!(k0 k2, k1 k3, k4 k6, k5 k7);
    cas!(k0 k4, k1 k5, k2 k6, k3 k7);
    cas!(k0 k1, k2 k3, k4 k5, k6 k7);
    cas!(k2 k4, k3 k5);
    cas!(k1 k4, k3 k6);
    cas!(k1 k2, k3 k4, k5 k6);
    *k = [k0, k1, k2, k3, k4, k5, k6, k7];
}

/// A fixed-size traversal stack as two locals (entries, length), so the length stays in a
/// register: `stack!(push st, sp, x)` / `stack!(pop st, sp)` (an `Option`). The entries are
/// not zeroed per ray; `validate` guarantees `7 * depth + 1 <= STACK` entries suffice.
macro_rules! stack {
    (new $t:ty) => {
        ([const { MaybeUninit::<$t>::uninit() }; STACK], 0usize)
    };
    (push $st:ident, $sp:ident, $x:expr) => {{
        $st[$sp] = MaybeUninit::new($x);
        $sp += 1;
    }};
    (pop $st:ident, $sp:ident) => {
        if $sp == 0 {
            None
        } else {
            $sp -= 1;
            // SAFETY: every entry below the old length was written by a push.
            Some(unsafe { $st[$sp].assume_init() })
        }
    };
}

impl Bvh {
    /// Start loading the node or triangle pack of child code `code` into the cache (the
    /// traversal is bound by memory latency; this overlaps the loads of stacked subtrees
    /// with work on the current one).
    #[inline(always)]
    fn prefetch(&self, code: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let (ptr, bytes) = if code & LEAF_BIT != 0 {
                let i = ((code & !LEAF_BIT) as usize).min(self.packs.len() - 1);
                (
                    self.packs.as_ptr().wrapping_add(i) as *const i8,
                    size_of::<TriPack>(),
                )
            } else {
                let i = (code as usize).min(self.nodes.len() - 1);
                (
                    self.nodes.as_ptr().wrapping_add(i) as *const i8,
                    size_of::<Node8>(),
                )
            };
            for off in (0..bytes).step_by(64) {
                // SAFETY: prefetching has no architectural effect and cannot fault; the
                // address is inside the node or pack array anyway.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(ptr.wrapping_add(off)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = code;
    }

    #[inline(always)]
    fn occluded_impl<const AVX: bool>(&self, ray: &Ray) -> bool {
        let rp = RayPre::new(ray);
        let (mut st, mut sp) = stack!(new u32);
        let mut cur = 0u32;
        loop {
            if cur & LEAF_BIT == 0 {
                let (mut mask, _) = rp.boxes_with::<AVX>(&self.nodes[cur as usize], ray.tmax);
                if mask != 0 {
                    let child = &self.nodes[cur as usize].child;
                    cur = child[mask.trailing_zeros() as usize];
                    mask &= mask - 1;
                    while mask != 0 {
                        let c = child[mask.trailing_zeros() as usize];
                        self.prefetch(c);
                        stack!(push st, sp, c);
                        mask &= mask - 1;
                    }
                    continue;
                }
            } else {
                let (mask, _) = rp.tris(&self.packs[(cur & !LEAF_BIT) as usize], ray.tmax);
                if mask != 0 {
                    return true;
                }
            }
            match stack!(pop st, sp) {
                Some(c) => cur = c,
                None => return false,
            }
        }
    }

    #[inline(always)]
    fn intersect_impl<const AVX: bool>(&self, ray: &Ray) -> Option<Hit> {
        let rp = RayPre::new(ray);
        let (mut st, mut sp) = stack!(new(u32, f32));
        let mut best_t = ray.tmax;
        let mut best: Option<Hit> = None;
        let mut cur = 0u32;
        loop {
            if cur & LEAF_BIT == 0 {
                let node = &self.nodes[cur as usize];
                let (mask, tn) = rp.boxes_with::<AVX>(node, best_t);
                if mask != 0 {
                    let i0 = mask.trailing_zeros() as usize;
                    let rest = mask & (mask - 1);
                    if rest == 0 {
                        cur = node.child[i0];
                        continue;
                    }
                    if rest & (rest - 1) == 0 {
                        // Two children (the most common case after one): one comparison.
                        let i1 = rest.trailing_zeros() as usize;
                        let (near, far) = if tn[i1] < tn[i0] { (i1, i0) } else { (i0, i1) };
                        self.prefetch(node.child[far]);
                        stack!(push st, sp, (node.child[far], tn[far]));
                        cur = node.child[near];
                        continue;
                    }
                    // Sort the hit children by entry distance (keys `dist bits << 32 | code`;
                    // distances are >= 0, so their bits order like the floats), descend into
                    // the nearest and stack the others nearest-on-top.
                    let key = |i: usize| ((tn[i].to_bits() as u64) << 32) | node.child[i] as u64;
                    let count = mask.count_ones() as usize;
                    let mut keys = [u64::MAX; 8];
                    if count <= 4 {
                        // Three or four children: compact and sort with a 5-comparator network.
                        let mut m = mask;
                        for k in keys.iter_mut().take(count) {
                            *k = key(m.trailing_zeros() as usize);
                            m &= m - 1;
                        }
                        sort4(&mut keys);
                    } else {
                        for (i, k) in keys.iter_mut().enumerate() {
                            *k = if mask & (1 << i) != 0 {
                                key(i)
                            } else {
                                u64::MAX
                            };
                        }
                        sort8(&mut keys);
                    }
                    for &k in keys[1..count].iter().rev() {
                        self.prefetch(k as u32);
                        stack!(push st, sp, (k as u32, f32::from_bits((k >> 32) as u32)));
                    }
                    cur = keys[0] as u32;
                    continue;
                }
            } else {
                let pack = &self.packs[(cur & !LEAF_BIT) as usize];
                let (mut mask, [bv, bw, tt, det]) = rp.tris(pack, best_t);
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let inv_det = 1.0 / det[i];
                    let t = tt[i] * inv_det;
                    if t <= best_t {
                        best_t = t;
                        best = Some(Hit {
                            t,
                            tri: pack.prim[i],
                            u: bv[i] * inv_det,
                            v: bw[i] * inv_det,
                        });
                    }
                }
            }
            // Pop the nearest subtree that can still hold a closer hit.
            loop {
                match stack!(pop st, sp) {
                    Some((c, d)) if d <= best_t => {
                        cur = c;
                        break;
                    }
                    Some(_) => continue,
                    None => return best,
                }
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn occluded_many_avx2(&self, rays: &[Ray], out: &mut [bool]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.occluded_impl::<true>(r);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn intersect_many_avx2(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.intersect_impl::<true>(r);
        }
    }
}

impl RayCaster for Bvh {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut out = [None];
        self.intersect_many(std::slice::from_ref(ray), &mut out);
        out[0]
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let mut out = [false];
        self.occluded_many(std::slice::from_ref(ray), &mut out);
        out[0]
    }

    fn occluded_many(&self, rays: &[Ray], out: &mut [bool]) {
        debug_assert_eq!(rays.len(), out.len());
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU reports AVX2 and FMA.
            return unsafe { self.occluded_many_avx2(rays, out) };
        }
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.occluded_impl::<false>(r);
        }
    }

    fn intersect_many(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        debug_assert_eq!(rays.len(), out.len());
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `occluded_many`.
            return unsafe { self.intersect_many_avx2(rays, out) };
        }
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = self.intersect_impl::<false>(r);
        }
    }

    fn name(&self) -> &'static str {
        "relight-bvh8"
    }
}
