//! Tests of the BVH (`bvh.rs`): against a brute-force loop, watertightness, validation.

use super::traverse::{sort4, sort8};
use super::*;
use crate::accel::test_rng::SplitMix64;
use crate::accel::{build, AccelError, Backend, Ray, RayCaster};

fn mesh(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> TriMesh {
    TriMesh {
        normals: vec![Vec3::Y; positions.len()],
        uvs: None,
        material_ids: vec![0; indices.len()],
        positions,
        indices,
    }
}

/// Closed UV sphere of radius 1 (shared vertices, single-vertex poles, CCW outward).
pub(crate) fn sphere(stacks: u32, slices: u32) -> TriMesh {
    let mut p = vec![Vec3::Y];
    for i in 1..stacks {
        let th = std::f32::consts::PI * i as f32 / stacks as f32;
        for j in 0..slices {
            let ph = std::f32::consts::TAU * j as f32 / slices as f32;
            p.push(Vec3::new(
                th.sin() * ph.cos(),
                th.cos(),
                -th.sin() * ph.sin(),
            ));
        }
    }
    p.push(-Vec3::Y);
    let ring = |i: u32, j: u32| 1 + (i - 1) * slices + j % slices;
    let south = p.len() as u32 - 1;
    let mut t = Vec::new();
    for j in 0..slices {
        t.push([0, ring(1, j), ring(1, j + 1)]);
        t.push([south, ring(stacks - 1, j + 1), ring(stacks - 1, j)]);
    }
    for i in 1..stacks - 1 {
        for j in 0..slices {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            t.push([a, c, d]);
            t.push([a, d, b]);
        }
    }
    mesh(p, t)
}

/// `n x n` quads on a bumpy height field over `[-1, 1]^2` (shared vertices and edges).
fn grid(n: u32, rng: &mut SplitMix64) -> TriMesh {
    let mut p = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (
                2.0 * i as f32 / n as f32 - 1.0,
                2.0 * j as f32 / n as f32 - 1.0,
            );
            p.push(Vec3::new(x, 0.1 * rng.next_f32(), z));
        }
    }
    let id = |i: u32, j: u32| i * (n + 1) + j;
    let mut t = Vec::new();
    for i in 0..n {
        for j in 0..n {
            t.push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
        }
    }
    mesh(p, t)
}

/// `n` random triangles of varied sizes in `[-1, 1]^3`.
fn soup(n: usize, rng: &mut SplitMix64) -> TriMesh {
    let mut p = Vec::new();
    let mut u = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
    let mut t = Vec::new();
    for i in 0..n as u32 {
        let (c, s) = (u(), 0.02 + 0.3 * (i % 7) as f32 / 7.0);
        p.extend([c, c + u() * s, c + u() * s]);
        t.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    mesh(p, t)
}

fn unit(rng: &mut SplitMix64) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

type D3 = [f64; 3];
fn d3(v: Vec3) -> D3 {
    [v.x as f64, v.y as f64, v.z as f64]
}
fn sub(a: D3, b: D3) -> D3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: D3, b: D3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: D3, b: D3) -> D3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Reference: Möller & Trumbore 1997 in f64 over every triangle.
fn brute(m: &TriMesh, r: &Ray) -> Option<(f64, u32)> {
    let (o, d) = (d3(r.origin), d3(r.dir));
    let mut best: Option<(f64, u32)> = None;
    for tri in 0..m.triangle_count() {
        let [a, b, c] = m.triangle(tri).map(d3);
        let (e1, e2) = (sub(b, a), sub(c, a));
        let pv = cross(d, e2);
        let det = dot(e1, pv);
        if det == 0.0 || !det.is_finite() {
            continue;
        }
        let tv = sub(o, a);
        let u = dot(tv, pv) / det;
        let qv = cross(tv, e1);
        let v = dot(d, qv) / det;
        let t = dot(e2, qv) / det;
        if u >= 0.0
            && v >= 0.0
            && u + v <= 1.0
            && t >= r.tmin as f64
            && t <= r.tmax as f64
            && best.is_none_or(|(bt, _)| t < bt)
        {
            best = Some((t, tri as u32));
        }
    }
    best
}

/// Random rays: from inside and outside the meshes, some with axis-aligned directions
/// (zero components, infinite inverse), some with a limited `[tmin, tmax]`.
fn rays(n: usize, rng: &mut SplitMix64) -> Vec<Ray> {
    (0..n)
        .map(|i| {
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0) * 1.6;
            let mut d = unit(rng);
            match i % 4 {
                0 => d = Vec3::AXES[i / 4 % 3] * if rng.next_f32() < 0.5 { -1.0 } else { 1.0 },
                1 => d.y = 0.0,
                _ => {}
            }
            let d = if d == Vec3::ZERO { Vec3::X } else { d };
            let (tmin, tmax) = if i % 3 == 0 {
                (rng.next_f32() * 0.5, 0.5 + rng.next_f32() * 1.5)
            } else {
                (0.0, f32::INFINITY)
            };
            Ray::new(o, d, tmin, tmax)
        })
        .collect()
}

/// Compare `c` against the brute-force loop on `rs`; ignores rays whose reference hit is
/// within 1e-4 (relative) of `tmin`/`tmax`, where f32 and f64 may legitimately disagree.
fn check_against_brute(m: &TriMesh, c: &dyn RayCaster, rs: &[Ray]) {
    let mut hits = 0;
    for r in rs {
        let want = brute(m, r);
        let near_limit = |t: f64| {
            (t - r.tmin as f64).abs() <= 1e-4 * t.abs().max(1e-3)
                || (r.tmax.is_finite() && (t - r.tmax as f64).abs() <= 1e-4 * t.abs())
        };
        if want.is_some_and(|(t, _)| near_limit(t)) {
            continue;
        }
        let got = c.intersect(r);
        assert_eq!(
            c.occluded(r),
            want.is_some(),
            "{}: occluded {r:?} want {want:?}",
            c.name()
        );
        match (got, want) {
            (None, None) => {}
            (Some(h), Some((t, tri))) => {
                hits += 1;
                assert!(
                    ((h.t as f64 - t) / t.max(1e-3)).abs() < 1e-4,
                    "{}: t {} vs {t} for {r:?}",
                    c.name(),
                    h.t
                );
                if h.tri != tri {
                    // A tie: the reported triangle must be hit at the same t.
                    let [a, b, cc] = m.triangle(h.tri as usize);
                    let p = a * (1.0 - h.u - h.v) + b * h.u + cc * h.v;
                    assert!(
                        (p - r.at(h.t)).length() < 1e-4,
                        "{}: tri {} vs {tri}",
                        c.name(),
                        h.tri
                    );
                }
                // Barycentrics reproduce the hit point.
                let p = m.point(h.tri as usize, h.u, h.v);
                assert!(
                    (p - r.at(h.t)).length() < 1e-4 * (1.0 + h.t),
                    "{}: bary {h:?}",
                    c.name()
                );
            }
            _ => panic!("{}: {r:?} got {got:?} want {want:?}", c.name()),
        }
    }
    assert!(
        hits > rs.len() / 20,
        "{}: too few hits ({hits}) to test anything",
        c.name()
    );
}

fn test_meshes() -> Vec<(&'static str, TriMesh)> {
    let mut rng = SplitMix64(11);
    vec![
        ("soup", soup(600, &mut rng)),
        ("sphere", sphere(12, 24)),
        ("grid", grid(20, &mut rng)),
    ]
}

#[test]
fn bvh_matches_brute_force_for_every_preset() {
    let mut rng = SplitMix64(5);
    for (name, m) in test_meshes() {
        let rs = rays(1500, &mut rng);
        for preset in BuildPreset::ALL {
            let b = Bvh::build(&m, preset).unwrap();
            b.validate()
                .unwrap_or_else(|e| panic!("{name} {preset:?}: {e}"));
            check_against_brute(&m, &b, &rs);
            // The scalar (non-AVX2) path too.
            #[cfg(target_arch = "x86_64")]
            check_against_brute(&m, &Bvh { avx2: false, ..b }, &rs);
        }
    }
    #[cfg(target_arch = "x86_64")]
    if !(std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")) {
        relight_testdata::skip_platform("avx2", "the AVX2 traversal not checked: no AVX2/FMA");
    }
}

#[test]
fn every_backend_matches_brute_force() {
    let mut rng = SplitMix64(6);
    for (_, m) in test_meshes() {
        let rs = rays(1500, &mut rng);
        for &backend in Backend::available() {
            check_against_brute(&m, &*build(&m, backend).unwrap(), &rs);
        }
    }
}

#[test]
fn many_queries_match_single_ones() {
    let m = sphere(10, 20);
    let rs = rays(700, &mut SplitMix64(8));
    for &backend in Backend::available() {
        let c = build(&m, backend).unwrap();
        let mut occ = vec![false; rs.len()];
        let mut hit = vec![None; rs.len()];
        c.occluded_many(&rs, &mut occ);
        c.intersect_many(&rs, &mut hit);
        for (i, r) in rs.iter().enumerate() {
            assert_eq!(occ[i], c.occluded(r));
            assert_eq!(hit[i], c.intersect(r));
        }
    }
}

#[test]
fn large_random_mesh_validates_and_matches() {
    // Enough triangles for parallel subtrees (PAR_MIN) and several wide levels.
    let m = soup(20_000, &mut SplitMix64(9));
    for preset in BuildPreset::ALL {
        let b = Bvh::build(&m, preset).unwrap();
        b.validate().unwrap();
        assert!(b.size().0 > 100, "{:?}", b.size());
        check_against_brute(&m, &b, &rays(150, &mut SplitMix64(10)));
    }
}

/// Rays from inside a closed mesh aimed exactly at its vertices and at points on its
/// edges: a watertight caster hits every one.
fn check_watertight(m: &TriMesh, c: &dyn RayCaster) -> usize {
    let mut rng = SplitMix64(12);
    let mut misses = 0;
    let mut n = 0;
    for origin in [
        Vec3::ZERO,
        Vec3::new(0.31, -0.2, 0.17),
        Vec3::new(-0.5, 0.4, 0.1),
    ] {
        for (k, t) in m.indices.iter().enumerate() {
            let [a, b, cc] = t.map(|i| m.positions[i as usize]);
            let s = rng.next_f32();
            // A vertex, and points on two edges (computed in f32, so on or a rounding off).
            for target in [a, a + (b - a) * s, b + (cc - b) * 0.5] {
                let r = Ray::new(origin, target - origin, 0.0, f32::INFINITY);
                n += 1;
                if c.intersect(&r).is_none() || !c.occluded(&r) {
                    misses += 1;
                    eprintln!("{}: ray {r:?} (triangle {k}) slipped through", c.name());
                }
            }
        }
    }
    assert!(n > 1000);
    misses
}

#[test]
fn bvh_is_watertight() {
    // A sphere with jittered vertices, so edges are not aligned with anything.
    let mut m = sphere(16, 32);
    let mut rng = SplitMix64(13);
    for p in &mut m.positions {
        *p *= 1.0 + 0.05 * rng.next_f32();
    }
    for preset in BuildPreset::ALL {
        let b = Bvh::build(&m, preset).unwrap();
        b.validate().unwrap();
        assert_eq!(check_watertight(&m, &b), 0);
    }
}

#[cfg(feature = "embree")]
#[test]
fn embree_robust_is_watertight() {
    let m = sphere(16, 32);
    let e = crate::accel::embree::EmbreeScene::build_robust(&m).unwrap();
    assert_eq!(check_watertight(&m, &e), 0);
}

#[test]
fn empty_and_invalid_meshes_are_errors() {
    for &backend in Backend::available() {
        assert_eq!(
            build(&TriMesh::default(), backend).err(),
            Some(AccelError::NoUsableTriangle { triangles: 0 })
        );
        let degenerate = mesh(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]]);
        assert_eq!(
            build(&degenerate, backend).err(),
            Some(AccelError::NoUsableTriangle { triangles: 1 })
        );
        let out_of_range = mesh(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 3]]);
        let e = build(&out_of_range, backend).err().unwrap();
        assert_eq!(
            e.to_string(),
            "triangle 0 has vertex index out of range: [0, 1, 3] (3 vertices)"
        );
    }
}

#[test]
fn degenerate_triangles_are_ignored() {
    // A unit triangle plus a zero-area one, a collinear one and one with a NaN corner,
    // all on the ray's path.
    let p = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, -0.5),
        Vec3::new(-1.0, 0.0, -0.3),
        Vec3::new(1.0, 0.0, -0.3),
        Vec3::new(0.0, f32::NAN, -0.2),
    ];
    let m = mesh(p, vec![[3, 3, 3], [4, 3, 5], [0, 1, 2], [6, 4, 5]]);
    let r = Ray::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
    for preset in BuildPreset::ALL {
        let b = Bvh::build(&m, preset).unwrap();
        b.validate().unwrap();
        assert_eq!(b.intersect(&r).map(|h| h.tri), Some(2));
    }
    for &backend in Backend::available() {
        let c = build(&m, backend).unwrap();
        assert_eq!(c.intersect(&r).map(|h| h.tri), Some(2), "{}", c.name());
        assert!(c.occluded(&r));
    }
}

#[test]
fn sort8_sorts_every_zero_one_input() {
    // Zero-one principle: a comparator network sorting all 2^8 binary inputs sorts all.
    for bits in 0u32..256 {
        let mut k = [0u64; 8];
        for (i, x) in k.iter_mut().enumerate() {
            *x = (bits >> i & 1) as u64;
        }
        sort8(&mut k);
        assert!(k.windows(2).all(|w| w[0] <= w[1]), "{bits:08b} -> {k:?}");
    }
}

#[test]
fn sort4_sorts_every_zero_one_input() {
    for bits in 0u32..16 {
        let mut k = [9u64; 8];
        for (i, x) in k.iter_mut().take(4).enumerate() {
            *x = (bits >> i & 1) as u64;
        }
        sort4(&mut k);
        assert!(k.windows(2).all(|w| w[0] <= w[1]), "{bits:04b} -> {k:?}");
    }
}

#[test]
fn validate_catches_corruption() {
    let m = sphere(12, 24);
    let good = Bvh::build(&m, BuildPreset::Quality).unwrap();
    good.validate().unwrap();
    // Shrink a child box: it no longer holds its triangles.
    let mut b = Bvh::build(&m, BuildPreset::Quality).unwrap();
    b.nodes[0].hi[0][0] = b.nodes[0].lo[0][0];
    assert!(
        matches!(
            b.validate(),
            Err(BvhError::OutsideParent { .. } | BvhError::CornerOutsideLeaf { .. })
        ),
        "{:?}",
        b.validate()
    );
    // Reference a triangle twice.
    let mut b = Bvh::build(&m, BuildPreset::Quality).unwrap();
    b.packs[1].prim[0] = b.packs[0].prim[0];
    assert!(b.validate().is_err());
    // Lose a triangle.
    let mut b = Bvh::build(&m, BuildPreset::Quality).unwrap();
    b.tris.push(Some(m.triangle(0)));
    let t = m.triangle_count();
    assert_eq!(
        b.validate(),
        Err(BvhError::TriangleCount {
            triangle: t,
            count: 0,
            expected: 1
        })
    );
}
