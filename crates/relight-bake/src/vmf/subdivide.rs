//! Midpoint 1-to-4 subdivision with at most one level between neighbours and T-vertices
//! resolved at the end (paper section 4.3, Fig. 4): the mesh side of the adaptive spatial
//! refinement.
//!
//! # Rules
//! * Splitting a leaf triangle `(v0, v1, v2)` of level `l` adds (or reuses) the midpoints
//!   `m01, m12, m20` of its edges and replaces it by four level-`l + 1` triangles
//!   `(v0, m01, m20)`, `(m01, v1, m12)`, `(m20, m12, v2)`, `(m01, m12, m20)` (counter-clockwise
//!   as the parent).
//! * "No two neighboring triangles can differ more than one subdivision level": before a leaf
//!   of level `l` is split, every neighbour of level `l - 1` (one whose edge holds an edge of
//!   the leaf as a half) is split first, recursively. So each edge of a leaf holds at most one
//!   T-vertex (a neighbour's midpoint).
//! * [`AdaptiveMesh::finish`] resolves T-vertices: a leaf with `k` edges holding a midpoint
//!   becomes `k + 1` triangles (fan from the vertex opposite the split edge for `k = 1`, the
//!   4-split for `k = 3`), all counter-clockwise as the leaf, so the output is conforming.
//!
//! # Bad input
//! Neighbours are found by shared vertex indices, through a multimap of directed edges, so a
//! non-manifold edge (three or more triangles) simply has several neighbours, all kept within
//! one level, and a boundary edge (a hole) has none. Triangles that share positions but not
//! vertex indices (a crease with split normals) are not neighbours: splitting one side adds a
//! vertex on the shared edge that the other side does not have, which leaves no crack (the
//! vertex lies on the other side's edge) but a shading seam.

use glam::{Vec2, Vec3};
use relight_scene::mesh::TriMesh;
use std::collections::HashMap;

/// A triangle of the subdivision.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leaf {
    /// Corners, counter-clockwise.
    pub v: [u32; 3],
    /// Subdivision level (0: a triangle of the input mesh).
    pub level: u8,
    /// Material id (of the input triangle it came from).
    pub material: u32,
    /// Still a leaf (not split).
    pub alive: bool,
}

/// A mesh under adaptive midpoint subdivision (module docs).
#[derive(Clone, Debug)]
pub struct AdaptiveMesh {
    /// Positions, shading normals (unit) and uvs of every vertex; the input's first.
    pub positions: Vec<Vec3>,
    /// Unit shading normals.
    pub normals: Vec<Vec3>,
    /// Texture coordinates, if the input had them.
    pub uvs: Option<Vec<Vec2>>,
    /// Every triangle ever made; the live ones are the current mesh.
    pub leaves: Vec<Leaf>,
    /// For each vertex added by a split, its parent vertices (the input's have none).
    pub parents: Vec<Option<[u32; 2]>>,
    /// Midpoint of each split undirected edge `(min, max)`.
    mid: HashMap<(u32, u32), u32>,
    /// Live leaves owning each directed edge.
    owners: HashMap<(u32, u32), Vec<u32>>,
}

fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

impl AdaptiveMesh {
    /// The level-0 subdivision of `mesh` (its triangles, its vertices).
    pub fn new(mesh: &TriMesh) -> AdaptiveMesh {
        let mut m = AdaptiveMesh {
            positions: mesh.positions.clone(),
            normals: mesh
                .normals
                .iter()
                .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
                .collect(),
            uvs: mesh.uvs.clone(),
            leaves: vec![],
            parents: vec![None; mesh.vertex_count()],
            mid: HashMap::new(),
            owners: HashMap::new(),
        };
        for (t, v) in mesh.indices.iter().enumerate() {
            m.add_leaf(Leaf {
                v: *v,
                level: 0,
                material: mesh.material_ids.get(t).copied().unwrap_or(0),
                alive: true,
            });
        }
        m
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The live leaves' indices.
    pub fn live(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.leaves.len()).filter(|&t| self.leaves[t].alive)
    }

    /// Area of leaf `t`.
    pub fn area(&self, t: usize) -> f32 {
        let [a, b, c] = self.leaves[t].v.map(|i| self.positions[i as usize]);
        0.5 * (b - a).cross(c - a).length()
    }

    fn add_leaf(&mut self, l: Leaf) -> u32 {
        let id = self.leaves.len() as u32;
        for k in 0..3 {
            let e = (l.v[k], l.v[(k + 1) % 3]);
            self.owners.entry(e).or_default().push(id);
        }
        self.leaves.push(l);
        id
    }

    fn kill(&mut self, t: usize) {
        let l = self.leaves[t];
        for k in 0..3 {
            let e = (l.v[k], l.v[(k + 1) % 3]);
            if let Some(o) = self.owners.get_mut(&e) {
                o.retain(|&x| x as usize != t);
            }
        }
        self.leaves[t].alive = false;
    }

    /// The midpoint vertex of `(a, b)`, made if new.
    fn midpoint(&mut self, a: u32, b: u32) -> u32 {
        if let Some(&m) = self.mid.get(&key(a, b)) {
            return m;
        }
        let (ia, ib) = (a as usize, b as usize);
        let m = self.positions.len() as u32;
        self.positions
            .push(0.5 * (self.positions[ia] + self.positions[ib]));
        let n = (self.normals[ia] + self.normals[ib])
            .try_normalize()
            .unwrap_or(self.normals[ia]);
        self.normals.push(n);
        if let Some(uv) = &mut self.uvs {
            uv.push(0.5 * (uv[ia] + uv[ib]));
        }
        self.parents.push(Some([a, b]));
        self.mid.insert(key(a, b), m);
        m
    }

    /// Live leaves of a lower level than `t` whose edge holds an edge of `t` as a half.
    fn coarser_neighbours(&self, t: usize) -> Vec<usize> {
        let l = self.leaves[t];
        let mut out = vec![];
        for k in 0..3 {
            let (a, b) = (l.v[k], l.v[(k + 1) % 3]);
            // b is the midpoint of a coarser edge (a, x), or a of (x, b): the neighbour owns
            // its reverse.
            let mut cands = vec![];
            if let Some([p, q]) = self.parents[b as usize] {
                if p == a {
                    cands.push((q, a));
                } else if q == a {
                    cands.push((p, a));
                }
            }
            if let Some([p, q]) = self.parents[a as usize] {
                if p == b {
                    cands.push((b, q));
                } else if q == b {
                    cands.push((b, p));
                }
            }
            for e in cands {
                for &o in self.owners.get(&e).map_or(&[][..], |v| &v[..]) {
                    let o = o as usize;
                    if self.leaves[o].alive && self.leaves[o].level < l.level {
                        out.push(o);
                    }
                }
            }
        }
        out
    }

    /// Split live leaf `t` (after its coarser neighbours, recursively); returns the leaves
    /// split (forced ones included), in order.
    ///
    /// # Panics
    /// If `t` is not a live leaf.
    pub fn split(&mut self, t: usize) -> Vec<usize> {
        assert!(self.leaves[t].alive, "leaf {t} is not live");
        let mut done = vec![];
        // Coarser neighbours first (they are at least one level lower, so this ends).
        loop {
            let c = self.coarser_neighbours(t);
            let Some(&n) = c.first() else { break };
            done.extend(self.split(n));
        }
        let l = self.leaves[t];
        let [v0, v1, v2] = l.v;
        let (m01, m12, m20) = (
            self.midpoint(v0, v1),
            self.midpoint(v1, v2),
            self.midpoint(v2, v0),
        );
        self.kill(t);
        let child = |v| Leaf {
            v,
            level: l.level + 1,
            material: l.material,
            alive: true,
        };
        for v in [
            [v0, m01, m20],
            [m01, v1, m12],
            [m20, m12, v2],
            [m01, m12, m20],
        ] {
            self.add_leaf(child(v));
        }
        done.push(t);
        done
    }

    /// The conforming mesh: live leaves with their T-vertices resolved (module docs).
    pub fn finish(&self) -> TriMesh {
        let mut indices = vec![];
        let mut material_ids = vec![];
        for t in self.live() {
            let l = self.leaves[t];
            let v = l.v;
            let m: [Option<u32>; 3] =
                std::array::from_fn(|k| self.mid.get(&key(v[k], v[(k + 1) % 3])).copied());
            let mut push = |tri: [u32; 3]| {
                indices.push(tri);
                material_ids.push(l.material);
            };
            match m.iter().filter(|x| x.is_some()).count() {
                0 => push(v),
                1 => {
                    let k = (0..3).find(|&k| m[k].is_some()).expect("one split edge");
                    let (a, b, c) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
                    let mk = m[k].expect("split");
                    push([a, mk, c]);
                    push([mk, b, c]);
                }
                2 => {
                    // The edge without a midpoint is k; the other two are split.
                    let k = (0..3).find(|&k| m[k].is_none()).expect("one whole edge");
                    let (a, b, c) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
                    let mbc = m[(k + 1) % 3].expect("split");
                    let mca = m[(k + 2) % 3].expect("split");
                    push([mbc, c, mca]);
                    push([a, b, mbc]);
                    push([a, mbc, mca]);
                }
                _ => {
                    let [m01, m12, m20] = m.map(|x| x.expect("split"));
                    let [v0, v1, v2] = v;
                    push([v0, m01, m20]);
                    push([m01, v1, m12]);
                    push([m20, m12, v2]);
                    push([m01, m12, m20]);
                }
            }
        }
        TriMesh {
            positions: self.positions.clone(),
            normals: self.normals.clone(),
            uvs: self.uvs.clone(),
            indices,
            material_ids,
        }
    }
}

#[cfg(test)]
mod tests;
