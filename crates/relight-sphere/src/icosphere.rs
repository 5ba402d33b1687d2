//! Geodesic sphere: an icosahedron whose faces are split into `f^2` triangles (geodesic
//! frequency `f`, class I) and whose vertices are projected onto the unit sphere.
//!
//! Counts: `10 f^2 + 2` vertices, `30 f^2` edges, `20 f^2` triangles; 12 vertices (those of the
//! icosahedron) have 5 neighbours, all others 6. `f = 3` gives the 92 view directions of
//! P. Green 2005, "View-Dependent Precomputed Light Transport Using Non-Linear Gaussian Function
//! Approximations" (MIT thesis; also Green, Kautz, Matusik & Durand, I3D 2006).
//!
//! Construction: the icosahedron has vertices the cyclic permutations of `(0, ±1, ±phi)`
//! (golden ratio), normalised. On each face `(A, B, C)` the grid point `(i, j)`, `i + j <= f`,
//! is `normalize((f - i - j) A + i B + j C)`: this is the *gnomonic* (central) projection of the
//! planar grid, so the cone of directions through a sub-triangle is exactly the cone through
//! the planar sub-triangle, which makes [`Icosphere::locate`] a direct lookup. Triangles are
//! counter-clockwise seen from outside.

use crate::Vec3;
use std::collections::HashMap;

/// A subdivided icosahedron on the unit sphere.
#[derive(Clone, Debug)]
pub struct Icosphere {
    frequency: usize,
    vertices: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    /// Vertex neighbours, counter-clockwise around the outward normal.
    neighbours: Vec<Vec<u32>>,
    /// Triangle across the edge opposite corner `k` (edge `(v[k+1], v[k+2])`).
    tri_adjacency: Vec<[u32; 3]>,
    base_vertices: Vec<Vec3>,
    base_faces: Vec<[u32; 3]>,
    /// `[face][i][j][down]` -> triangle index (`u32::MAX` where unused).
    face_tri: Vec<u32>,
}

impl Icosphere {
    /// Geodesic sphere of frequency `frequency >= 1` (1 is the icosahedron itself).
    ///
    /// # Panics
    /// Panics if `frequency == 0`.
    pub fn new(frequency: usize) -> Icosphere {
        assert!(frequency >= 1, "geodesic frequency must be >= 1");
        let f = frequency;
        let (base_vertices, base_faces) = icosahedron();
        let mut vertices: Vec<Vec3> = base_vertices.clone();
        let mut edge_vertex: HashMap<(u32, u32, usize), u32> = HashMap::new();
        let mut triangles = Vec::with_capacity(20 * f * f);
        let mut face_tri = vec![u32::MAX; 20 * f * f * 2];
        for (fi, face) in base_faces.iter().enumerate() {
            let [a, b, c] = *face;
            let (pa, pb, pc) = (
                base_vertices[a as usize],
                base_vertices[b as usize],
                base_vertices[c as usize],
            );
            // Vertex index of grid point (i, j) of this face.
            let mut grid = vec![u32::MAX; (f + 1) * (f + 1)];
            for i in 0..=f {
                for j in 0..=(f - i) {
                    let k = f - i - j;
                    let on_edge = |p: u32, q: u32, steps_from_p: usize| -> (u32, u32, usize) {
                        if p < q {
                            (p, q, steps_from_p)
                        } else {
                            (q, p, f - steps_from_p)
                        }
                    };
                    let key = if i == 0 && j == 0 {
                        Some(Err(a))
                    } else if i == f {
                        Some(Err(b))
                    } else if j == f {
                        Some(Err(c))
                    } else if j == 0 {
                        Some(Ok(on_edge(a, b, i)))
                    } else if i == 0 {
                        Some(Ok(on_edge(a, c, j)))
                    } else if k == 0 {
                        Some(Ok(on_edge(b, c, j)))
                    } else {
                        None
                    };
                    let pos = || (pa * k as f32 + pb * i as f32 + pc * j as f32).normalize();
                    let v = match key {
                        Some(Err(corner)) => corner,
                        Some(Ok(edge)) => *edge_vertex.entry(edge).or_insert_with(|| {
                            vertices.push(pos());
                            (vertices.len() - 1) as u32
                        }),
                        None => {
                            vertices.push(pos());
                            (vertices.len() - 1) as u32
                        }
                    };
                    grid[i * (f + 1) + j] = v;
                }
            }
            let g = |i: usize, j: usize| grid[i * (f + 1) + j];
            for i in 0..f {
                for j in 0..(f - i) {
                    face_tri[((fi * f + i) * f + j) * 2] = triangles.len() as u32;
                    triangles.push([g(i, j), g(i + 1, j), g(i, j + 1)]);
                    if i + j + 2 <= f {
                        face_tri[((fi * f + i) * f + j) * 2 + 1] = triangles.len() as u32;
                        triangles.push([g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)]);
                    }
                }
            }
        }
        let tri_adjacency = triangle_adjacency(&triangles);
        let neighbours = vertex_rings(vertices.len(), &triangles);
        Icosphere {
            frequency,
            vertices,
            triangles,
            neighbours,
            tri_adjacency,
            base_vertices,
            base_faces,
            face_tri,
        }
    }

    /// The geodesic frequency `f`.
    #[inline]
    pub fn frequency(&self) -> usize {
        self.frequency
    }

    /// Unit vertex directions (`10 f^2 + 2`); the first 12 are the icosahedron's.
    #[inline]
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices
    }

    /// Triangles (vertex indices, counter-clockwise from outside), `20 f^2`.
    #[inline]
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Neighbours of vertex `v` (5 or 6), counter-clockwise around its outward normal.
    #[inline]
    pub fn neighbours(&self, v: usize) -> &[u32] {
        &self.neighbours[v]
    }

    /// Triangles across the three edges of triangle `t` (entry `k` is across the edge opposite
    /// corner `k`).
    #[inline]
    pub fn triangle_neighbours(&self, t: usize) -> [u32; 3] {
        self.tri_adjacency[t]
    }

    /// Spherical-cone barycentrics of `dir` in triangle `t`: `b` with `sum b = 1` and
    /// `dir ∝ b0 V0 + b1 V1 + b2 V2` (all `>= 0` iff `dir` is inside the cone of `t`).
    #[inline]
    pub fn barycentrics(&self, t: usize, dir: Vec3) -> [f32; 3] {
        let [a, b, c] = self.triangles[t].map(|i| self.vertices[i as usize]);
        cone_barycentrics(a, b, c, dir)
    }

    /// The triangle whose cone contains `dir` (unit or not, non-zero) and the barycentrics of
    /// `dir` in it: `normalize(b0 V0 + b1 V1 + b2 V2) = normalize(dir)`, `b >= 0` up to rounding.
    pub fn locate(&self, dir: Vec3) -> (usize, [f32; 3]) {
        let f = self.frequency;
        // Base face whose cone contains dir: the one with the largest minimum barycentric.
        let (mut best_face, mut best_bary, mut best_min) = (0, [0f32; 3], f32::NEG_INFINITY);
        for (fi, face) in self.base_faces.iter().enumerate() {
            let [a, b, c] = face.map(|i| self.base_vertices[i as usize]);
            if dir.dot(a + b + c) <= 0.0 {
                continue;
            }
            let bary = cone_barycentrics(a, b, c, dir);
            let m = bary[0].min(bary[1]).min(bary[2]);
            if m > best_min {
                (best_face, best_bary, best_min) = (fi, bary, m);
            }
        }
        // Planar grid cell in that face (exact by the gnomonic construction).
        let x = best_bary[1].max(0.0) * f as f32;
        let y = best_bary[2].max(0.0) * f as f32;
        let i = (x as usize).min(f - 1);
        let j = (y as usize).min(f - 1 - i);
        let down = (x - i as f32) + (y - j as f32) > 1.0 && i + j + 2 <= f;
        let mut t = self.face_tri[((best_face * f + i) * f + j) * 2 + down as usize] as usize;
        // Guard against rounding at cell borders: walk towards the most negative barycentric.
        let mut bary = self.barycentrics(t, dir);
        for _ in 0..8 {
            let (k, m) = bary
                .iter()
                .enumerate()
                .fold(
                    (0, f32::INFINITY),
                    |acc, (k, &v)| if v < acc.1 { (k, v) } else { acc },
                );
            if m >= -1e-6 {
                break;
            }
            let next = self.tri_adjacency[t][k] as usize;
            let nb = self.barycentrics(next, dir);
            if nb.iter().copied().fold(f32::INFINITY, f32::min) <= m {
                break;
            }
            t = next;
            bary = nb;
        }
        (t, bary)
    }

    /// The vertex nearest to `dir` (largest dot product), searching the located triangle's
    /// corners and their neighbours.
    pub fn nearest_vertex(&self, dir: Vec3) -> usize {
        let (t, _) = self.locate(dir);
        let mut best = (f32::NEG_INFINITY, 0usize);
        for &v in &self.triangles[t] {
            for &u in std::iter::once(&v).chain(self.neighbours[v as usize].iter()) {
                let d = self.vertices[u as usize].dot(dir);
                if d > best.0 {
                    best = (d, u as usize);
                }
            }
        }
        best.1
    }

    /// Checks every invariant: counts, unit vertices, outward counter-clockwise triangles, a
    /// closed consistently oriented 2-manifold (each directed edge once, its reverse once),
    /// Euler characteristic 2, 5 or 6 neighbours in a closed counter-clockwise ring, symmetric
    /// vertex and triangle adjacency.
    pub fn validate(&self) -> Result<(), IcosphereError> {
        let f = self.frequency;
        let (nv, nt) = (self.vertices.len(), self.triangles.len());
        if nv != 10 * f * f + 2 || nt != 20 * f * f {
            return Err(IcosphereError::Counts {
                vertices: nv,
                triangles: nt,
                frequency: f,
            });
        }
        for (i, v) in self.vertices.iter().enumerate() {
            if (v.length() - 1.0).abs() > 1e-5 {
                return Err(IcosphereError::NotUnit { vertex: i });
            }
        }
        let mut directed = HashMap::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|i| self.vertices[i as usize]);
            if (b - a).cross(c - a).dot(a + b + c) <= 0.0 {
                return Err(IcosphereError::Clockwise { triangle: t });
            }
            for k in 0..3 {
                if directed.insert((tri[k], tri[(k + 1) % 3]), t).is_some() {
                    return Err(IcosphereError::EdgeUsedTwice { triangle: t });
                }
            }
        }
        for &(a, b) in directed.keys() {
            if !directed.contains_key(&(b, a)) {
                return Err(IcosphereError::OpenEdge { from: a, to: b });
            }
        }
        let ne = directed.len() / 2;
        if ne != 30 * f * f || nv + nt != ne + 2 {
            return Err(IcosphereError::Euler {
                edges: ne,
                characteristic: nv as i64 - ne as i64 + nt as i64,
            });
        }
        let mut fives = 0;
        for (v, ring) in self.neighbours.iter().enumerate() {
            match ring.len() {
                5 => fives += 1,
                6 => {}
                n => {
                    return Err(IcosphereError::Valence {
                        vertex: v,
                        neighbours: n,
                    })
                }
            }
            for (k, &u) in ring.iter().enumerate() {
                if !self.neighbours[u as usize].contains(&(v as u32)) {
                    return Err(IcosphereError::AsymmetricNeighbours { a: v, b: u });
                }
                let w = ring[(k + 1) % ring.len()];
                if !directed.contains_key(&(v as u32, u))
                    || directed.get(&(u, w)) != directed.get(&(v as u32, u))
                {
                    return Err(IcosphereError::RingOrder { vertex: v });
                }
            }
        }
        if fives != 12 {
            return Err(IcosphereError::Valence5Count { count: fives });
        }
        for (t, adj) in self.tri_adjacency.iter().enumerate() {
            for &u in adj {
                if !self.tri_adjacency[u as usize].contains(&(t as u32)) {
                    return Err(IcosphereError::AsymmetricAdjacency { a: t, b: u });
                }
            }
        }
        Ok(())
    }
}

/// The first invariant of an [`Icosphere`] found violated by [`Icosphere::validate`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum IcosphereError {
    /// Vertex or triangle count is not `10 f^2 + 2` / `20 f^2`.
    #[error("counts: {vertices} vertices, {triangles} triangles for f = {frequency}")]
    Counts {
        /// Vertices held.
        vertices: usize,
        /// Triangles held.
        triangles: usize,
        /// The frequency `f`.
        frequency: usize,
    },
    /// A vertex is not of unit length.
    #[error("vertex {vertex} not unit")]
    NotUnit {
        /// The vertex.
        vertex: usize,
    },
    /// A triangle is clockwise seen from outside.
    #[error("triangle {triangle} not counter-clockwise from outside")]
    Clockwise {
        /// The triangle.
        triangle: usize,
    },
    /// A directed edge appears twice (the surface is not a consistently oriented manifold).
    #[error("directed edge of triangle {triangle} used twice")]
    EdgeUsedTwice {
        /// The triangle of the second use.
        triangle: usize,
    },
    /// The edge `from -> to` has no reverse: the surface is not closed.
    #[error("edge ({from}, {to}) has no opposite: not closed")]
    OpenEdge {
        /// First vertex.
        from: u32,
        /// Second vertex.
        to: u32,
    },
    /// Wrong edge count or Euler characteristic (not 2).
    #[error("{edges} edges, Euler characteristic {characteristic}")]
    Euler {
        /// Undirected edges.
        edges: usize,
        /// `V - E + F`.
        characteristic: i64,
    },
    /// A vertex has neither 5 nor 6 neighbours.
    #[error("vertex {vertex} has {neighbours} neighbours")]
    Valence {
        /// The vertex.
        vertex: usize,
        /// Its neighbour count.
        neighbours: usize,
    },
    /// `b` is a neighbour of `a` but not the other way round.
    #[error("neighbours of {a} and {b} not symmetric")]
    AsymmetricNeighbours {
        /// The vertex whose ring holds `b`.
        a: usize,
        /// The neighbour.
        b: u32,
    },
    /// A vertex's neighbour ring is not in counter-clockwise order around it.
    #[error("ring of vertex {vertex} is not counter-clockwise around it")]
    RingOrder {
        /// The vertex.
        vertex: usize,
    },
    /// Not exactly 12 vertices of valence 5.
    #[error("{count} vertices of valence 5 (expected 12)")]
    Valence5Count {
        /// Vertices of valence 5.
        count: usize,
    },
    /// `b` is adjacent to triangle `a` but not the other way round.
    #[error("triangle adjacency {a} / {b} not symmetric")]
    AsymmetricAdjacency {
        /// The triangle whose adjacency holds `b`.
        a: usize,
        /// The adjacent triangle.
        b: u32,
    },
}

/// `b` with `sum b = 1` and `dir ∝ b0 a + b1 b + b2 c` (signed volumes).
#[inline]
fn cone_barycentrics(a: Vec3, b: Vec3, c: Vec3, dir: Vec3) -> [f32; 3] {
    let w = [
        dir.dot(b.cross(c)),
        dir.dot(c.cross(a)),
        dir.dot(a.cross(b)),
    ];
    let s = w[0] + w[1] + w[2];
    [w[0] / s, w[1] / s, w[2] / s]
}

/// Unit icosahedron: vertices (cyclic permutations of `(0, ±1, ±phi)`) and 20 faces,
/// counter-clockwise from outside, found as the triples of mutually adjacent vertices.
fn icosahedron() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let phi = (1.0 + 5f32.sqrt()) * 0.5;
    let mut v = Vec::with_capacity(12);
    for s1 in [-1.0, 1.0] {
        for s2 in [-phi, phi] {
            v.push(Vec3::new(0.0, s1, s2));
            v.push(Vec3::new(s1, s2, 0.0));
            v.push(Vec3::new(s2, 0.0, s1));
        }
    }
    // Edges have length 2 before normalisation.
    let adjacent = |i: usize, j: usize| (v[i].distance_squared(v[j]) - 4.0).abs() < 1e-3;
    let mut faces = Vec::with_capacity(20);
    for a in 0..12 {
        for b in a + 1..12 {
            for c in b + 1..12 {
                if adjacent(a, b) && adjacent(b, c) && adjacent(a, c) {
                    let (pa, pb, pc) = (v[a], v[b], v[c]);
                    if (pb - pa).cross(pc - pa).dot(pa + pb + pc) > 0.0 {
                        faces.push([a as u32, b as u32, c as u32]);
                    } else {
                        faces.push([a as u32, c as u32, b as u32]);
                    }
                }
            }
        }
    }
    debug_assert_eq!(faces.len(), 20);
    (v.iter().map(|p| p.normalize()).collect(), faces)
}

fn triangle_adjacency(triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut edge_tri = HashMap::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            edge_tri.insert((tri[k], tri[(k + 1) % 3]), t as u32);
        }
    }
    triangles
        .iter()
        .map(|tri| {
            let mut adj = [u32::MAX; 3];
            for (k, a) in adj.iter_mut().enumerate() {
                let (p, q) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                *a = edge_tri.get(&(q, p)).copied().unwrap_or(u32::MAX);
            }
            adj
        })
        .collect()
}

/// Counter-clockwise one-rings: in a CCW triangle `(v, b, c)`, `c` follows `b` around `v`.
fn vertex_rings(nv: usize, triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut next: Vec<Vec<(u32, u32)>> = vec![Vec::new(); nv];
    for tri in triangles {
        for k in 0..3 {
            next[tri[k] as usize].push((tri[(k + 1) % 3], tri[(k + 2) % 3]));
        }
    }
    next.iter()
        .map(|pairs| {
            let mut ring = Vec::with_capacity(pairs.len());
            let mut cur = pairs[0].0;
            for _ in 0..pairs.len() {
                ring.push(cur);
                match pairs.iter().find(|p| p.0 == cur) {
                    Some(p) => cur = p.1,
                    None => break,
                }
            }
            ring
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::warp::{square_to_uniform_sphere, Rng};

    #[test]
    fn counts_and_validate() {
        for f in 1..=8 {
            let s = Icosphere::new(f);
            s.validate().unwrap_or_else(|e| panic!("f={f}: {e}"));
            assert_eq!(s.vertices().len(), 10 * f * f + 2);
        }
        let g = Icosphere::new(3);
        assert_eq!(g.vertices().len(), 92, "Green 2005's 92 view directions");
        for v in 0..92 {
            assert!(matches!(g.neighbours(v).len(), 5 | 6));
        }
    }

    #[test]
    fn validate_catches_breakage() {
        let mut s = Icosphere::new(2);
        s.triangles[3].swap(0, 1);
        assert_eq!(s.validate(), Err(IcosphereError::Clockwise { triangle: 3 }));
        let mut s = Icosphere::new(2);
        s.vertices[5] *= 1.1;
        assert_eq!(s.validate(), Err(IcosphereError::NotUnit { vertex: 5 }));
    }

    #[test]
    fn locate_reproduces_direction() {
        let mut rng = Rng::new(6, 6);
        for f in [1, 3, 7] {
            let s = Icosphere::new(f);
            let mut dirs: Vec<Vec3> = (0..3000)
                .map(|_| square_to_uniform_sphere(rng.next_vec2()))
                .collect();
            dirs.extend(s.vertices().iter().copied());
            dirs.extend(
                s.triangles().iter().map(|t| {
                    (s.vertices()[t[0] as usize] + s.vertices()[t[1] as usize]).normalize()
                }),
            );
            for d in dirs {
                let (t, b) = s.locate(d);
                assert!(b.iter().all(|&x| x >= -1e-5), "f={f} {d}: {b:?}");
                assert!((b.iter().sum::<f32>() - 1.0).abs() < 1e-5);
                let tri = s.triangles()[t];
                let p = (0..3).fold(Vec3::ZERO, |acc, k| {
                    acc + s.vertices()[tri[k] as usize] * b[k]
                });
                assert!((p.normalize() - d).length() < 1e-5, "f={f} {d}");
            }
        }
    }

    #[test]
    fn nearest_vertex_is_nearest() {
        let s = Icosphere::new(4);
        let mut rng = Rng::new(9, 9);
        for _ in 0..500 {
            let d = square_to_uniform_sphere(rng.next_vec2());
            let brute = (0..s.vertices().len())
                .max_by(|&a, &b| s.vertices()[a].dot(d).total_cmp(&s.vertices()[b].dot(d)))
                .unwrap();
            let got = s.nearest_vertex(d);
            assert!((s.vertices()[got].dot(d) - s.vertices()[brute].dot(d)).abs() < 1e-6);
        }
    }
}
