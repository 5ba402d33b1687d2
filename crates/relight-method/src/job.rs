//! A bake run to a bundle file, as `relight bake` and a cluster's shard worker run it: whole,
//! one part of a sharded bake ([`crate::shard`]), checkpointed and resumable
//! ([`crate::checkpoint`]), or in chunks when the memory estimate is over a limit
//! ([`crate::memory`]).

use crate::memory::{self, MemoryPlan};
use crate::shard::{bake_part, Shard};
use crate::{BakeContext, BakeInput, BakeSummary, Baked, Method, MethodError};
use std::path::Path;

/// How to run a bake.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BakeJob {
    /// Bake only this part of a sharded bake.
    pub shard: Option<Shard>,
    /// Checkpoint every this many vertices (a chunk per file in the checkpoint folder).
    pub checkpoint_vertices: Option<u64>,
    /// Bake in chunks if the estimated peak memory is above this many bytes.
    pub memory_limit: Option<u64>,
    /// Finish a checkpointed bake from its checkpoint folder.
    pub resume: bool,
    /// Bytes already resident in the process (counted against `memory_limit`).
    pub resident: u64,
}

/// Bake `input` with `M` as `job` says and write the bundle `out`; `log` receives one line
/// per step worth telling (the memory plan, the part, each checkpointed chunk).
///
/// # Errors
/// Invalid settings, a part that cannot be made, a limit no chunk fits, or a failed write.
pub fn bake_to_file<M: Method>(
    input: BakeInput,
    settings: &M::Settings,
    job: &BakeJob,
    ctx: &BakeContext,
    out: &Path,
    mut log: impl FnMut(String),
) -> Result<BakeSummary, MethodError>
where
    M::Baked: Into<Baked>,
{
    let mut chunk = job
        .checkpoint_vertices
        .map(|n| usize::try_from(n).unwrap_or(usize::MAX));
    if let Some(limit) = job.memory_limit {
        match memory::plan::<M>(input, settings, limit, job.resident)? {
            MemoryPlan::Whole { estimate } => log(format!(
                "memory: about {} MiB expected, within --memory-limit {} MiB",
                estimate >> 20,
                limit >> 20
            )),
            MemoryPlan::Chunks {
                chunk_vertices,
                whole,
                estimate,
            } => {
                let c = chunk.map_or(chunk_vertices, |c| c.min(chunk_vertices));
                log(format!(
                    "memory: a whole bake needs about {} MiB, over --memory-limit {} MiB: baking chunks of {c} vertices through {} (about {} MiB)",
                    whole >> 20,
                    limit >> 20,
                    crate::checkpoint::folder(out).display(),
                    estimate >> 20
                ));
                chunk = Some(c);
            }
        }
    }
    if let Some(n) = chunk {
        return crate::checkpoint::bake_resumable::<M>(
            input,
            settings,
            ctx,
            out,
            n,
            job.resume,
            |i, n| log(format!("checkpoint: chunk {} of {n} done", i + 1)),
        );
    }
    let baked = match job.shard {
        Some(s) => {
            let units = M::max_parts(input, settings);
            let r = s.range(units);
            log(format!(
                "part {}/{}: units {}..{} of {units} (a unit is one {})",
                s.index,
                s.count,
                r.start,
                r.end,
                M::PART_UNIT
            ));
            bake_part::<M>(input, settings, s, ctx)?
        }
        None => M::bake(input, settings, 0..input.scene.mesh.vertex_count(), ctx)?.into(),
    };
    baked.write(out)?;
    Ok(BakeSummary::of(&baked))
}
