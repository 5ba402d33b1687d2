//! The parts of a fit ([`super`] module docs, "The flood fill"): the mesh's flood-fill
//! regions ([`RegionPlan`]) and the fits of some regions' vertices before the regions are
//! aligned ([`PartFit`]), which a sharded bake stores per part and joins in its merge.

use super::graph::{self, Adjacency, Regions};
use super::{auto_regions, SgFitSettings};
use relight_sphere::sg::SgLobe;
use std::ops::Range;

/// The flood-fill regions of a mesh (module docs): the unit of parallel work, and the unit a
/// sharded bake splits (`relight_method::shard`). A pure function of the vertex count, the
/// triangles and [`SgFitSettings::regions`].
pub struct RegionPlan {
    pub(super) adj: Adjacency,
    pub(super) regions: Regions,
}

impl RegionPlan {
    /// The regions of a mesh of `vertex_count` vertices and `triangles` (indices in range).
    pub fn new(vertex_count: usize, triangles: &[[u32; 3]], fit: &SgFitSettings) -> RegionPlan {
        let adj = Adjacency::new(vertex_count, triangles);
        let requested = match fit.regions {
            0 => auto_regions(vertex_count),
            r => r,
        };
        let regions = graph::regions(&adj, requested);
        RegionPlan { adj, regions }
    }

    /// Number of regions (at least one per connected component; 0 for no vertices).
    pub fn region_count(&self) -> usize {
        self.regions.orders.len()
    }

    /// The vertices of the regions `range`, ascending.
    pub fn vertices(&self, range: Range<usize>) -> Vec<u32> {
        let mut v: Vec<u32> = self.regions.orders[range].concat();
        v.sort_unstable();
        v
    }
}

/// The fits of the vertices of some regions, before the regions are aligned (rows in
/// ascending vertex order): what a part of a sharded bake holds, and what `finish` takes
/// once the parts are put together.
#[derive(Clone, Debug, PartialEq)]
pub struct PartFit {
    /// The vertices, ascending.
    pub vertices: Vec<u32>,
    /// Per component (direct, then indirect if fitted): `views * lobes` lobes per vertex.
    pub lobes: Vec<Vec<SgLobe>>,
    /// Per component: the relative L2 error of each view per vertex (negative: no data).
    pub errors: Vec<Vec<f32>>,
    /// Diffuse SH per vertex (`diffuse_stride` floats each).
    pub diffuse_sh: Vec<f32>,
    /// Floats of diffuse SH per vertex.
    pub diffuse_stride: usize,
    /// Levenberg-Marquardt iterations spent.
    pub iterations: u64,
}

impl PartFit {
    /// Put parts together: rows of every part, by vertex, ascending.
    ///
    /// # Errors
    /// A message if two parts hold the same vertex or their layouts differ.
    pub fn join(parts: Vec<PartFit>) -> Result<PartFit, String> {
        // The layout is read from a part with vertices (any part, if none has).
        let Some(first) = parts
            .iter()
            .find(|p| !p.vertices.is_empty())
            .or(parts.first())
        else {
            return Err("no parts".into());
        };
        let comps = first.lobes.len();
        let stride = first.diffuse_stride;
        let row = |p: &PartFit, c: usize| p.lobes[c].len() / p.vertices.len().max(1);
        let rows: Vec<usize> = (0..comps).map(|c| row(first, c)).collect();
        let views = first
            .errors
            .first()
            .map_or(0, |e| e.len() / first.vertices.len().max(1));
        let mut owner: Vec<(u32, usize, usize)> = vec![]; // (vertex, part, row)
        for (pi, p) in parts.iter().enumerate() {
            let n = p.vertices.len();
            let sized = |c: usize| {
                p.lobes[c].len() == n * rows[c]
                    && p.errors.get(c).is_some_and(|e| e.len() == n * views)
            };
            if p.lobes.len() != comps
                || p.diffuse_stride != stride
                || p.diffuse_sh.len() != n * stride
                || !(0..comps).all(sized)
            {
                return Err(format!("part {pi} has another layout than the others"));
            }
            owner.extend(p.vertices.iter().enumerate().map(|(i, &x)| (x, pi, i)));
        }
        owner.sort_unstable();
        if let Some(w) = owner.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(format!("vertex {} is in two parts", w[0].0));
        }
        let views = first
            .errors
            .first()
            .map_or(0, |e| e.len() / first.vertices.len().max(1));
        let mut out = PartFit {
            vertices: owner.iter().map(|o| o.0).collect(),
            lobes: vec![vec![]; comps],
            errors: vec![vec![]; comps],
            diffuse_sh: Vec::with_capacity(owner.len() * stride),
            diffuse_stride: stride,
            iterations: parts.iter().map(|p| p.iterations).sum(),
        };
        for &(_, pi, i) in &owner {
            let p = &parts[pi];
            for (c, &n) in rows.iter().enumerate() {
                out.lobes[c].extend_from_slice(&p.lobes[c][i * n..(i + 1) * n]);
                out.errors[c].extend_from_slice(&p.errors[c][i * views..(i + 1) * views]);
            }
            out.diffuse_sh
                .extend_from_slice(&p.diffuse_sh[i * stride..(i + 1) * stride]);
        }
        Ok(out)
    }
}
