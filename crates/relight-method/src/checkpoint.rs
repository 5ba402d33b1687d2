//! Resumable bakes: a bake split into chunks (the parts of [`crate::shard`]), each written
//! atomically to a checkpoint folder as soon as it is done; a bake killed at any moment and
//! rerun with `resume` bakes only the missing chunks, then merges, and writes the bundle an
//! uninterrupted bake writes, byte for byte.
//!
//! # Conventions
//! * The folder is `<out>.checkpoint/` beside the output; chunk `i` of `n` is
//!   `chunk-<i>-of-<n>.relight`, a part bundle with its own checksums. A chunk killed while
//!   being written leaves only a temporary (cleaned by the next write), never a partial chunk.
//! * A rerun without `resume` that finds the folder refuses, saying what it holds; with
//!   `resume`, chunks of another split or scene are refused by name (settings are checked by
//!   the final merge). The folder is removed once the bundle is written. A kill between the
//!   bundle's rename and the folder's removal leaves both: the bundle is complete, and a
//!   rerun with `resume` finds every chunk, writes the same bundle again and removes the
//!   folder (no order of the two steps closes that window: removing the folder first would
//!   lose the chunks to a kill before the rename).
//! * What can be split can be checkpointed: `sh` with unshadowed or shadowed transfer (chunks
//!   of vertices) and `sg` (chunks of flood-fill regions, so at most one chunk per region).

use crate::shard::{bake_part, merge_files, Shard};
use crate::{
    read_any, BakeContext, BakeInput, BakeSummary, Baked, BakedScene, Method, MethodError,
};
use std::path::{Path, PathBuf};

/// The checkpoint folder of the output `out`.
pub fn folder(out: &Path) -> PathBuf {
    let mut name = out.file_name().unwrap_or_default().to_os_string();
    name.push(".checkpoint");
    out.with_file_name(name)
}

/// The chunks found in `dir`: `(index, count, path)`, sorted.
fn chunks(dir: &Path) -> Result<Vec<(usize, usize, PathBuf)>, MethodError> {
    let io = |e: std::io::Error| MethodError::Settings(format!("{}: {e}", dir.display()));
    let mut found = vec![];
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        let parsed = name
            .strip_prefix("chunk-")
            .and_then(|s| s.strip_suffix(".relight"))
            .and_then(|s| s.split_once("-of-"))
            .and_then(|(i, n)| Some((i.parse().ok()?, n.parse().ok()?)));
        if let Some((i, n)) = parsed {
            found.push((i, n, path));
        }
    }
    found.sort();
    Ok(found)
}

/// Bake `input` with `M` in chunks of about `chunk_vertices` vertices, checkpointed in
/// [`folder`]`(out)`, resuming from the chunks there when `resume`; writes `out` and removes
/// the folder. `done(i, n)` is called after each chunk (progress). The final merge streams
/// the chunks into `out` ([`merge_files`]), so an `sh` bake never holds more than a chunk of
/// rows: what `relight bake --memory-limit` relies on.
///
/// # Errors
/// A checkpoint found without `resume` (the message says what it holds and what to do), one
/// of another bake, a method that cannot be split, or any bake, read or write error.
pub fn bake_resumable<M: Method>(
    input: BakeInput,
    settings: &M::Settings,
    ctx: &BakeContext,
    out: &Path,
    chunk_vertices: usize,
    resume: bool,
    mut done: impl FnMut(usize, usize),
) -> Result<BakeSummary, MethodError>
where
    M::Baked: Into<Baked>,
{
    let v = input.scene.mesh.vertex_count();
    let most = M::max_parts(input, settings);
    let n = v
        .div_ceil(chunk_vertices.max(1))
        .clamp(1, crate::shard::MAX_SHARDS.min(most.max(1)));
    let dir = folder(out);
    let mut have = vec![None; n];
    if dir.exists() {
        let found = chunks(&dir)?;
        if !resume {
            return Err(MethodError::Settings(format!(
                "{}: holds a checkpoint of an interrupted bake ({} chunk files): rerun with --resume to finish it, or delete the folder to start again",
                dir.display(),
                found.len()
            )));
        }
        // Chunks of another scene are refused before any baking; the final merge checks
        // every chunk (settings, seed, scene), so one is read here, not each twice.
        if let Some((_, _, path)) = found.first() {
            let b = read_any(path)?;
            if b.scene().fingerprint()? != BakedScene::of(&input).fingerprint()? {
                return Err(MethodError::Merge {
                    path: path.clone(),
                    message: format!(
                        "was baked from another scene: delete {} to start again",
                        dir.display()
                    ),
                });
            }
        }
        for (i, count, path) in found {
            if count != n || i >= n {
                return Err(MethodError::Merge {
                    path,
                    message: format!(
                        "is chunk {i} of {count}, but this bake makes {n} chunks (another --checkpoint-vertices?): delete {} to start again",
                        dir.display()
                    ),
                });
            }
            have[i] = Some(path);
        }
    } else {
        std::fs::create_dir_all(&dir)
            .map_err(|e| MethodError::Settings(format!("{}: {e}", dir.display())))?;
    }
    let mut seconds = 0.0;
    for (index, slot) in have.iter_mut().enumerate() {
        if slot.is_none() {
            let part = bake_part::<M>(input, settings, Shard { index, count: n }, ctx)?;
            seconds += part.record().seconds;
            let path = dir.join(format!("chunk-{index}-of-{n}.relight"));
            part.write(&path)?;
            *slot = Some(path);
        }
        done(index, n);
    }
    let paths: Vec<PathBuf> = have.into_iter().flatten().collect();
    let mut whole = merge_files(&paths, out)?;
    // The time of the chunks baked by this run (a resumed run does not redo the others).
    whole.record.seconds = seconds;
    std::fs::remove_dir_all(&dir)
        .map_err(|e| MethodError::Settings(format!("{}: {e}", dir.display())))?;
    Ok(whole)
}

#[cfg(test)]
mod tests;
