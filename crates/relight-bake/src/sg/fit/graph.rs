//! The mesh as a graph for the flood fill (thesis section 2.2.2): vertex adjacency from the
//! triangles, connected components, independent regions grown from farthest-point seeds, and
//! each region's breadth-first order.

use std::collections::VecDeque;

/// Vertex adjacency in compressed rows: the neighbours of `x` are
/// `list[offsets[x]..offsets[x + 1]]`, sorted, without duplicates or `x` itself.
#[derive(Clone, Debug)]
pub struct Adjacency {
    offsets: Vec<usize>,
    list: Vec<u32>,
}

impl Adjacency {
    /// Adjacency of `vertex_count` vertices from triangle edges (indices must be in range;
    /// degenerate triangles contribute their distinct edges only).
    pub fn new(vertex_count: usize, triangles: &[[u32; 3]]) -> Adjacency {
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(6 * triangles.len());
        for t in triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                debug_assert!((a as usize) < vertex_count && (b as usize) < vertex_count);
                if a != b {
                    edges.push((a, b));
                    edges.push((b, a));
                }
            }
        }
        edges.sort_unstable();
        edges.dedup();
        let mut offsets = vec![0; vertex_count + 1];
        for &(a, _) in &edges {
            offsets[a as usize + 1] += 1;
        }
        for i in 0..vertex_count {
            offsets[i + 1] += offsets[i];
        }
        Adjacency {
            offsets,
            list: edges.into_iter().map(|(_, b)| b).collect(),
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Neighbours of `x`, sorted.
    #[inline]
    pub fn neighbours(&self, x: usize) -> &[u32] {
        &self.list[self.offsets[x]..self.offsets[x + 1]]
    }

    /// Every edge once, as `(x, y)` with `x < y`.
    pub fn edges(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.len()).flat_map(move |x| {
            self.neighbours(x)
                .iter()
                .filter(move |&&y| y as usize > x)
                .map(move |&y| (x, y as usize))
        })
    }
}

/// The flood-fill regions of a mesh.
#[derive(Clone, Debug)]
pub struct Regions {
    /// Region of each vertex.
    pub region_of: Vec<u32>,
    /// Each region's vertices in breadth-first order from its seed (the seed first).
    pub orders: Vec<Vec<u32>>,
    /// Position of each vertex in its region's order.
    pub rank: Vec<u32>,
}

/// Hop distances from `sources` within their component `members` (written to `dist`, whose
/// entries outside `members` are left alone).
fn bfs_distances(adj: &Adjacency, sources: &[u32], members: &[u32], dist: &mut [u32]) {
    for &x in members {
        dist[x as usize] = u32::MAX;
    }
    let mut queue = VecDeque::new();
    for &s in sources {
        dist[s as usize] = 0;
        queue.push_back(s);
    }
    while let Some(x) = queue.pop_front() {
        for &y in adj.neighbours(x as usize) {
            if dist[y as usize] == u32::MAX {
                dist[y as usize] = dist[x as usize] + 1;
                queue.push_back(y);
            }
        }
    }
}

/// The farthest vertex of `members` from the sources (ties: lowest index).
fn farthest(members: &[u32], dist: &[u32]) -> u32 {
    members.iter().copied().fold(members[0], |b, x| {
        if dist[x as usize] > dist[b as usize] {
            x
        } else {
            b
        }
    })
}

/// Splits the mesh into about `requested` regions (at least one per connected component):
/// each component gets seeds in proportion to its size, placed by farthest-point sampling in
/// hop distance (the first one the farthest vertex from the component's lowest index), and
/// its vertices go to the nearest seed by a multi-source breadth-first search (first claim
/// wins, seeds and neighbours in index order). Depends on the mesh and `requested` only.
pub fn regions(adj: &Adjacency, requested: usize) -> Regions {
    let nv = adj.len();
    let mut region_of = vec![u32::MAX; nv];
    let mut orders: Vec<Vec<u32>> = vec![];
    // Connected components, in order of their lowest vertex.
    let mut comp_of = vec![u32::MAX; nv];
    let mut comps: Vec<Vec<u32>> = vec![];
    for s in 0..nv {
        if comp_of[s] != u32::MAX {
            continue;
        }
        let id = comps.len() as u32;
        let mut members = vec![s as u32];
        comp_of[s] = id;
        let mut i = 0;
        while i < members.len() {
            for &y in adj.neighbours(members[i] as usize) {
                if comp_of[y as usize] == u32::MAX {
                    comp_of[y as usize] = id;
                    members.push(y);
                }
            }
            i += 1;
        }
        comps.push(members);
    }
    let requested = requested.max(1);
    let mut dist = vec![u32::MAX; nv];
    let mut in_order = vec![false; nv];
    for members in &comps {
        let k = ((requested * members.len()) as f64 / nv as f64).round() as usize;
        let k = k.clamp(1, members.len());
        // Farthest-point seeds.
        bfs_distances(adj, &members[..1], members, &mut dist);
        let mut seeds = vec![farthest(members, &dist)];
        while seeds.len() < k {
            bfs_distances(adj, &seeds, members, &mut dist);
            let f = farthest(members, &dist);
            if dist[f as usize] == 0 {
                break;
            }
            seeds.push(f);
        }
        // Grow all seeds at once.
        let first = orders.len() as u32;
        let mut queue = VecDeque::new();
        for (i, &s) in seeds.iter().enumerate() {
            region_of[s as usize] = first + i as u32;
            queue.push_back(s);
        }
        while let Some(x) = queue.pop_front() {
            for &y in adj.neighbours(x as usize) {
                if region_of[y as usize] == u32::MAX {
                    region_of[y as usize] = region_of[x as usize];
                    queue.push_back(y);
                }
            }
        }
        // Each region's own breadth-first order from its seed.
        for (i, &s) in seeds.iter().enumerate() {
            let r = first + i as u32;
            let mut order = vec![s];
            in_order[s as usize] = true;
            let mut j = 0;
            while j < order.len() {
                for &y in adj.neighbours(order[j] as usize) {
                    if region_of[y as usize] == r && !in_order[y as usize] {
                        in_order[y as usize] = true;
                        order.push(y);
                    }
                }
                j += 1;
            }
            orders.push(order);
        }
    }
    let mut rank = vec![0u32; nv];
    for order in &orders {
        for (i, &x) in order.iter().enumerate() {
            rank[x as usize] = i as u32;
        }
    }
    debug_assert!(orders.iter().map(Vec::len).sum::<usize>() == nv);
    Regions {
        region_of,
        orders,
        rank,
    }
}
