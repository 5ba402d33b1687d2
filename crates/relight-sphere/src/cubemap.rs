//! Cube map geometry: face/texel <-> direction, exact texel solid angles, neighbours across
//! faces.
//!
//! # Layout and orientation (OpenGL, `GL_TEXTURE_CUBE_MAP`, spec table 8.19 of GL 4.6)
//! Faces are stored in the order `+X, -X, +Y, -Y, +Z, -Z` (face index 0..5), each an `N x N`
//! row-major image; texel `(face, row, col)` has flat index `face N^2 + row N + col`.
//! A direction `d` selects the face of its largest-magnitude component `ma` and the in-face
//! coordinates `sc, tc` below; then `s = (sc / |ma| + 1) / 2`, `t = (tc / |ma| + 1) / 2`,
//! `col = floor(s N)`, `row = floor(t N)` (row 0 is the first row in memory, as uploaded by
//! `glTexImage2D`):
//!
//! | face | major axis | `sc` | `tc` | texel centre direction for `(sc, tc)` |
//! |------|-----------|------|------|------------------|
//! | 0 `+X` | `+x` | `-z` | `-y` | `( 1, -tc, -sc)` |
//! | 1 `-X` | `-x` | `+z` | `-y` | `(-1, -tc,  sc)` |
//! | 2 `+Y` | `+y` | `+x` | `+z` | `(sc,   1,  tc)` |
//! | 3 `-Y` | `-y` | `+x` | `-z` | `(sc,  -1, -tc)` |
//! | 4 `+Z` | `+z` | `+x` | `-y` | `(sc, -tc,   1)` |
//! | 5 `-Z` | `-z` | `-x` | `-y` | `(-sc, -tc, -1)` |
//!
//! So on the four side faces image "up" (row 0) is +Y; the +Y face has row 0 towards -Z and the
//! -Y face has row 0 towards +Z; columns increase towards +X on the +Y, -Y and +Z faces.
//! (These are the usual DDS / OpenGL cube map images; seen from inside the cube each face looks
//! mirrored, which is how those files are authored.)
//!
//! The solid angle of the texel `[x0, x1] x [y0, y1]` of the face plane at distance 1 is
//! `A(x0,y0) - A(x0,y1) - A(x1,y0) + A(x1,y1)` with `A(x, y) = atan2(x y, sqrt(x^2 + y^2 + 1))`
//! (the solid angle subtended by the rectangle `[0,x] x [0,y]`); the 6 N^2 texels sum to 4 pi.

use crate::{Vec2, Vec3};

/// A cube face, in storage order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CubeFace {
    /// +X, face 0.
    PosX,
    /// -X, face 1.
    NegX,
    /// +Y, face 2.
    PosY,
    /// -Y, face 3.
    NegY,
    /// +Z, face 4.
    PosZ,
    /// -Z, face 5.
    NegZ,
}

impl CubeFace {
    /// The faces in storage order.
    pub const ALL: [CubeFace; 6] = [
        CubeFace::PosX,
        CubeFace::NegX,
        CubeFace::PosY,
        CubeFace::NegY,
        CubeFace::PosZ,
        CubeFace::NegZ,
    ];

    /// Storage index 0..5.
    #[inline]
    pub fn index(self) -> usize {
        self as usize
    }

    /// Face of storage index `i`.
    ///
    /// # Panics
    /// Panics if `i >= 6`.
    #[inline]
    pub fn from_index(i: usize) -> CubeFace {
        Self::ALL[i]
    }

    /// Direction of the point `(sc, tc)` of the face plane (unnormalised; `sc, tc` in
    /// `[-1, 1]` on the face, values beyond extend the plane), per the table in the module docs.
    #[inline]
    pub fn plane_point(self, sc: f32, tc: f32) -> Vec3 {
        match self {
            CubeFace::PosX => Vec3::new(1.0, -tc, -sc),
            CubeFace::NegX => Vec3::new(-1.0, -tc, sc),
            CubeFace::PosY => Vec3::new(sc, 1.0, tc),
            CubeFace::NegY => Vec3::new(sc, -1.0, -tc),
            CubeFace::PosZ => Vec3::new(sc, -tc, 1.0),
            CubeFace::NegZ => Vec3::new(-sc, -tc, -1.0),
        }
    }
}

/// Face and `(s, t)` in `[0, 1]^2` of a direction (ties between axes go to X, then Y).
#[inline]
pub fn dir_to_face_st(dir: Vec3) -> (CubeFace, Vec2) {
    let a = dir.abs();
    let (face, sc, tc, ma) = if a.x >= a.y && a.x >= a.z {
        if dir.x >= 0.0 {
            (CubeFace::PosX, -dir.z, -dir.y, a.x)
        } else {
            (CubeFace::NegX, dir.z, -dir.y, a.x)
        }
    } else if a.y >= a.z {
        if dir.y >= 0.0 {
            (CubeFace::PosY, dir.x, dir.z, a.y)
        } else {
            (CubeFace::NegY, dir.x, -dir.z, a.y)
        }
    } else if dir.z >= 0.0 {
        (CubeFace::PosZ, dir.x, -dir.y, a.z)
    } else {
        (CubeFace::NegZ, -dir.x, -dir.y, a.z)
    };
    let inv = if ma > 0.0 { 1.0 / ma } else { 0.0 };
    (
        face,
        Vec2::new(0.5 * (sc * inv + 1.0), 0.5 * (tc * inv + 1.0)),
    )
}

/// Unit direction of `(s, t)` in `[0, 1]^2` on `face`.
#[inline]
pub fn face_st_to_dir(face: CubeFace, st: Vec2) -> Vec3 {
    face.plane_point(2.0 * st.x - 1.0, 2.0 * st.y - 1.0)
        .normalize()
}

/// Flat index of texel `(face, row, col)` of an `n x n`-per-face cube map.
#[inline]
pub fn texel_index(n: usize, face: CubeFace, row: usize, col: usize) -> usize {
    debug_assert!(row < n && col < n);
    (face.index() * n + row) * n + col
}

/// `(face, row, col)` of flat texel index `i`.
///
/// # Panics
/// Debug builds assert `i < 6 n^2`.
#[inline]
pub fn texel_coords(n: usize, i: usize) -> (CubeFace, usize, usize) {
    debug_assert!(i < 6 * n * n);
    (CubeFace::from_index(i / (n * n)), (i / n) % n, i % n)
}

/// Unit direction through the centre of texel `(face, row, col)`.
#[inline]
pub fn texel_dir(n: usize, face: CubeFace, row: usize, col: usize) -> Vec3 {
    let s = (col as f32 + 0.5) / n as f32;
    let t = (row as f32 + 0.5) / n as f32;
    face_st_to_dir(face, Vec2::new(s, t))
}

/// Flat index of the texel containing `dir`.
#[inline]
pub fn dir_to_texel(n: usize, dir: Vec3) -> usize {
    let (face, st) = dir_to_face_st(dir);
    let col = ((st.x * n as f32) as usize).min(n - 1);
    let row = ((st.y * n as f32) as usize).min(n - 1);
    texel_index(n, face, row, col)
}

fn area_element(x: f64, y: f64) -> f64 {
    (x * y).atan2((x * x + y * y + 1.0).sqrt())
}

/// Exact solid angle of texel `(row, col)` of an `n x n` face (the same on every face).
#[inline]
pub fn texel_solid_angle(n: usize, row: usize, col: usize) -> f64 {
    debug_assert!(row < n && col < n);
    let inv = 2.0 / n as f64;
    let x0 = col as f64 * inv - 1.0;
    let y0 = row as f64 * inv - 1.0;
    let (x1, y1) = (x0 + inv, y0 + inv);
    area_element(x0, y0) - area_element(x0, y1) - area_element(x1, y0) + area_element(x1, y1)
}

/// The four edge neighbours of texel `i`, in the order `col - 1, col + 1, row - 1, row + 1`,
/// crossing onto the adjacent face at a face edge (found by extending the face plane by one
/// texel and re-projecting, which always lands in the adjacent edge texel).
pub fn texel_neighbours(n: usize, i: usize) -> [usize; 4] {
    let (face, row, col) = texel_coords(n, i);
    let step = |dc: i64, dr: i64| -> usize {
        let c = col as i64 + dc;
        let r = row as i64 + dr;
        if (0..n as i64).contains(&c) && (0..n as i64).contains(&r) {
            return texel_index(n, face, r as usize, c as usize);
        }
        let sc = 2.0 * (c as f32 + 0.5) / n as f32 - 1.0;
        let tc = 2.0 * (r as f32 + 0.5) / n as f32 - 1.0;
        dir_to_texel(n, face.plane_point(sc, tc))
    };
    [step(-1, 0), step(1, 0), step(0, -1), step(0, 1)]
}

/// The four texels and bilinear weights of the lookup of `dir`: bilinear within the face of
/// `dir`, clamped at the face edges (no filtering across faces). Weights sum to 1.
#[inline]
pub fn bilinear(n: usize, dir: Vec3) -> [(usize, f32); 4] {
    let (face, st) = dir_to_face_st(dir);
    let x = (st.x * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
    let y = (st.y * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
    let c0 = (x as usize).min(n.saturating_sub(2));
    let r0 = (y as usize).min(n.saturating_sub(2));
    let fx = (x - c0 as f32).min(1.0);
    let fy = (y - r0 as f32).min(1.0);
    let c1 = (c0 + 1).min(n - 1);
    let r1 = (r0 + 1).min(n - 1);
    [
        (texel_index(n, face, r0, c0), (1.0 - fx) * (1.0 - fy)),
        (texel_index(n, face, r0, c1), fx * (1.0 - fy)),
        (texel_index(n, face, r1, c0), (1.0 - fx) * fy),
        (texel_index(n, face, r1, c1), fx * fy),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opengl_orientation_table() {
        // Face centres.
        let centres = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        for (f, c) in CubeFace::ALL.iter().zip(centres) {
            assert!((face_st_to_dir(*f, Vec2::splat(0.5)) - c).length() < 1e-6);
            let (f2, st) = dir_to_face_st(c);
            assert_eq!(*f, f2);
            assert!((st - Vec2::splat(0.5)).length() < 1e-6);
        }
        // Row 0 of the side faces looks up (+Y); +Y row 0 looks to -Z; -Y row 0 looks to +Z.
        for f in [
            CubeFace::PosX,
            CubeFace::NegX,
            CubeFace::PosZ,
            CubeFace::NegZ,
        ] {
            assert!(face_st_to_dir(f, Vec2::new(0.5, 0.0)).y > 0.5);
        }
        assert!(face_st_to_dir(CubeFace::PosY, Vec2::new(0.5, 0.0)).z < -0.5);
        assert!(face_st_to_dir(CubeFace::NegY, Vec2::new(0.5, 0.0)).z > 0.5);
        // s grows towards -Z on +X, towards +X on +Z (OpenGL table).
        assert!(face_st_to_dir(CubeFace::PosX, Vec2::new(1.0, 0.5)).z < -0.5);
        assert!(face_st_to_dir(CubeFace::PosZ, Vec2::new(1.0, 0.5)).x > 0.5);
        assert!(face_st_to_dir(CubeFace::NegZ, Vec2::new(1.0, 0.5)).x < -0.5);
    }

    #[test]
    fn roundtrip_texels() {
        let n = 9;
        for i in 0..6 * n * n {
            let (f, r, c) = texel_coords(n, i);
            assert_eq!(texel_index(n, f, r, c), i);
            assert_eq!(dir_to_texel(n, texel_dir(n, f, r, c)), i);
        }
    }

    #[test]
    fn solid_angles_sum_to_4pi() {
        for n in [1, 2, 3, 16, 128] {
            let s: f64 = (0..n)
                .flat_map(|r| (0..n).map(move |c| texel_solid_angle(n, r, c)))
                .sum::<f64>()
                * 6.0;
            assert!((s - 4.0 * std::f64::consts::PI).abs() < 1e-10, "n={n}: {s}");
        }
        // Small texel at the centre: about area / distance^2 = (2/n)^2.
        let n = 1001;
        let w = texel_solid_angle(n, 500, 500);
        assert!((w - (2.0 / n as f64).powi(2)).abs() < 1e-9);
    }

    #[test]
    fn neighbours_are_adjacent_and_symmetric() {
        let n = 6;
        let mut hist = [0usize; 6];
        for i in 0..6 * n * n {
            let nb = texel_neighbours(n, i);
            let (f, r, c) = texel_coords(n, i);
            let d = texel_dir(n, f, r, c);
            for &j in &nb {
                assert_ne!(i, j);
                assert!(texel_neighbours(n, j).contains(&i), "symmetry {i} {j}");
                let (g, rr, cc) = texel_coords(n, j);
                let e = texel_dir(n, g, rr, cc);
                // Adjacent texel centres are at most ~1.3 texel angles apart.
                assert!(d.angle_between(e) < 1.5 * (2.0 / n as f32), "{i} {j}");
                if g != f {
                    hist[f.index()] += 1;
                }
            }
        }
        // Each face has 4 n edge crossings.
        assert!(hist.iter().all(|&h| h == 4 * n));
    }

    #[test]
    fn bilinear_weights() {
        let n = 8;
        for i in 0..6 * n * n {
            let (f, r, c) = texel_coords(n, i);
            let b = bilinear(n, texel_dir(n, f, r, c));
            let w: f32 = b.iter().filter(|x| x.0 == i).map(|x| x.1).sum();
            assert!(w > 0.999, "{i}: {b:?}");
        }
    }
}
