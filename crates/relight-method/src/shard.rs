//! Sharded bakes: one bake split into `N` parts baked anywhere (a Slurm array task, a
//! Kubernetes indexed job), then merged into the bundle a single process would have written,
//! byte for byte.
//!
//! # Conventions
//! * Part `i` of `N` (0-based, as `SLURM_ARRAY_TASK_ID` and `JOB_COMPLETION_INDEX` count)
//!   bakes the vertices `floor(i V / N) .. floor((i + 1) V / N)`: contiguous, in order, every
//!   vertex in exactly one part ([`Shard::range`]).
//! * A part bundle records its [`Shard`] and vertex range in its [`BakeRecord`]; it holds the
//!   whole scene (so a merge can check that every part saw the same one) and only its rows of
//!   the method's per-vertex tensors. Frames refuse it ([`crate::MethodError::PartialBake`]).
//! * A bake is a pure function of the scene, the settings (seed included) and the back-end:
//!   vertex `v`'s samples are seeded by `(seed, v)`, never by the thread or the part, and the
//!   bundle records no time. So the concatenated rows are the single-process bake's rows.
//!
//! Which methods split: `sh` with unshadowed or shadowed transfer, by vertex ranges.
//! Interreflected `sh` is refused: each bounce gathers the previous bounce of *every*
//! vertex, so every part would trace the whole mesh (no part would be cheaper than the whole
//! bake). `sg` is refused: its flood fill couples neighbouring vertices (Green 2005 eq. 2.6).

use crate::{sh::ShBaked, BakeContext, BakeInput, Baked, Method, MethodError};
use relight_bake::sh::ShTransfer;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Most parts of one bake (a Slurm array is 1001 tasks by default; this is far above it).
pub const MAX_SHARDS: usize = 1 << 16;

/// Part `index` of `count` of a sharded bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 0-based part number, `< count`.
    pub index: usize,
    /// Number of parts.
    pub count: usize,
}

impl Shard {
    /// Parse `I/N` (0-based `I`), as `relight bake --shard` takes it.
    ///
    /// # Errors
    /// [`MethodError::Settings`] saying what is wrong with the text.
    pub fn parse(s: &str) -> Result<Shard, MethodError> {
        let bad = |why: &str| {
            MethodError::Settings(format!(
                "--shard {s:?}: {why} (expected I/N: part I of N, I from 0 to N - 1, N from 1 to {MAX_SHARDS})"
            ))
        };
        let (i, n) = s.split_once('/').ok_or_else(|| bad("no '/'"))?;
        let index: usize = i.trim().parse().map_err(|_| bad("I is not a number"))?;
        let count: usize = n.trim().parse().map_err(|_| bad("N is not a number"))?;
        if !(1..=MAX_SHARDS).contains(&count) {
            return Err(bad("N is out of range"));
        }
        if index >= count {
            return Err(bad("I is not below N"));
        }
        Ok(Shard { index, count })
    }

    /// The vertices of this part of a mesh of `vertices` vertices.
    pub fn range(self, vertices: usize) -> Range<usize> {
        debug_assert!(self.index < self.count);
        let at = |i: usize| (i as u128 * vertices as u128 / self.count as u128) as usize;
        at(self.index)..at(self.index + 1)
    }
}

impl std::str::FromStr for Shard {
    type Err = MethodError;

    fn from_str(s: &str) -> Result<Shard, MethodError> {
        Shard::parse(s)
    }
}

/// Bake part `shard` of `input` with method `M`: its vertex range, recorded as that part.
///
/// # Errors
/// More parts than vertices, a method or transfer that cannot be split (the message says
/// why), or any error of [`Method::bake`].
pub fn bake_part<M: Method>(
    input: BakeInput,
    settings: &M::Settings,
    shard: Shard,
    ctx: &BakeContext,
) -> Result<Baked, MethodError>
where
    M::Baked: Into<Baked>,
{
    let v = input.scene.mesh.vertex_count();
    if shard.count > v {
        return Err(MethodError::Settings(format!(
            "--shard {}/{}: more parts than the mesh's {v} vertices",
            shard.index, shard.count
        )));
    }
    let mut baked: Baked = M::bake(input, settings, shard.range(v), ctx)?.into();
    baked.record_mut().shard = Some(shard);
    Ok(baked)
}

/// Merge the parts of one sharded bake (each with the path it was read from, named in
/// errors) into the whole bake, which is byte-identical in its bundle to a single-process bake
/// with the same seed. Parts are taken one at a time (e.g. read lazily) and only the first
/// keeps its scene, so memory is one scene plus the whole bake's rows.
///
/// Checks that every part belongs to the same bake: same method, settings (seed included),
/// back-end, storage precision, scene (description, materials, mesh) and part count; that no
/// part is missing or repeated; that each holds the rows its number says.
///
/// # Errors
/// [`MethodError::Merge`] naming the part and what does not match, or the error of reading
/// a part.
pub fn merge<I>(parts: I) -> Result<Baked, MethodError>
where
    I: IntoIterator<Item = Result<(PathBuf, Baked), MethodError>>,
{
    let err = |path: &Path, message: String| MethodError::Merge {
        path: path.to_path_buf(),
        message,
    };
    let mut parts = parts.into_iter();
    let Some(first) = parts.next() else {
        return Err(MethodError::Settings("merge: no parts given".into()));
    };
    let (first_path, first) = first?;
    let Some(s0) = first.record().shard else {
        return Err(err(&first_path, "is not a part of a sharded bake".into()));
    };
    // What every other part must share with the first (its scene's bytes, taken once).
    let kind0 = first.kind();
    let settings0 = first.settings_json();
    let (backend0, f16_0) = (first.record().backend.clone(), first.record().f16);
    let scene0 = first.scene().fingerprint()?;
    let v = first.scene().mesh.vertex_count();
    // slot[i]: part i's path and rows (its scene dropped, but for the first part's).
    let mut slot: Vec<Option<(PathBuf, Baked)>> = (0..s0.count).map(|_| None).collect();
    let mut scene = None;
    for (nth, part) in std::iter::once(Ok((first_path.clone(), first)))
        .chain(parts)
        .enumerate()
    {
        let (path, mut b) = part?;
        let r = b.record();
        let Some(s) = r.shard else {
            return Err(err(&path, "is not a part of a sharded bake".into()));
        };
        let differs = |what: &str| {
            err(
                &path,
                format!("its {what} differs from that of {}", first_path.display()),
            )
        };
        if s.count != s0.count {
            return Err(err(
                &path,
                format!(
                    "is part {}/{} but {} is part {}/{}: they come from bakes split differently",
                    s.index,
                    s.count,
                    first_path.display(),
                    s0.index,
                    s0.count
                ),
            ));
        }
        if nth > 0 {
            if b.kind() != kind0 {
                return Err(differs("method"));
            }
            if b.settings_json() != settings0 {
                return Err(differs("settings (or seed)"));
            }
            if (&r.backend, r.f16) != (&backend0, f16_0) {
                return Err(differs("back-end or storage precision"));
            }
            if b.scene().fingerprint()? != scene0 {
                return Err(differs("scene"));
            }
        }
        let want = s.range(v);
        if r.range.unwrap_or((0, v)) != (want.start, want.end) {
            return Err(err(
                &path,
                format!(
                    "holds vertices {:?} but part {}/{} is {want:?}",
                    r.range, s.index, s.count
                ),
            ));
        }
        if let Some((other, _)) = &slot[s.index] {
            return Err(err(
                &path,
                format!(
                    "part {}/{} is given twice (also {})",
                    s.index,
                    s.count,
                    other.display()
                ),
            ));
        }
        let taken = b.take_scene();
        scene.get_or_insert(taken);
        slot[s.index] = Some((path, b));
    }
    let missing: Vec<String> = (0..s0.count)
        .filter(|&i| slot[i].is_none())
        .map(|i| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(err(
            &first_path,
            format!("parts {} of {} are missing", missing.join(", "), s0.count),
        ));
    }
    let mut it = slot.into_iter().flatten().map(|(_, b)| b);
    let mut whole = match it.next() {
        Some(Baked::Sh(mut sh)) => {
            for b in it {
                let Baked::Sh(p) = b else {
                    unreachable!("kinds checked above")
                };
                append_sh(&mut sh, p);
            }
            Baked::Sh(sh)
        }
        Some(Baked::Sg(_)) => {
            return Err(err(&first_path, "sg bakes cannot be sharded".into()));
        }
        Some(Baked::Cuts(mut cuts)) => {
            for b in it {
                let Baked::Cuts(p) = b else {
                    unreachable!("kinds checked above")
                };
                append_cuts(&mut cuts, p).map_err(|m| err(&first_path, m))?;
            }
            Baked::Cuts(cuts)
        }
        None => unreachable!("no part is missing"),
    };
    whole.put_scene(scene.expect("at least one part"));
    let r = whole.record_mut();
    (r.range, r.shard) = (None, None);
    match &whole {
        Baked::Sh(sh) => sh.validate(),
        Baked::Cuts(cuts) => cuts.validate(),
        Baked::Sg(_) => Ok(()),
    }
    .map_err(|e| err(&first_path, format!("merged bake: {e}")))?;
    Ok(whole)
}

/// Append the rows of part `p` to `sh`.
fn append_sh(sh: &mut ShBaked, p: ShBaked) {
    let t: &mut ShTransfer = &mut sh.transfer;
    t.vertex_count += p.transfer.vertex_count;
    t.data.extend_from_slice(&p.transfer.data);
    sh.albedo.extend_from_slice(&p.albedo);
    sh.record.seconds += p.record.seconds;
}

/// Append the cuts of part `p` to `c`: the parts must share their light samples and tree
/// (the same settings and scene make the same ones).
fn append_cuts(c: &mut crate::cuts::CutsBaked, p: crate::cuts::CutsBaked) -> Result<(), String> {
    if p.bake.samples != c.bake.samples || p.bake.tree != c.bake.tree {
        return Err("parts with different light samples or light trees".into());
    }
    let (dst, src) = (&mut c.bake.cuts, p.bake.cuts);
    let (base_v, base_e) = (dst.vertex_count() as u32, dst.index.len() as u64);
    dst.offsets
        .extend(src.offsets.iter().skip(1).map(|&o| o + base_e));
    dst.index.extend(src.index);
    dst.leftleaf.extend(src.leftleaf);
    dst.value.extend(src.value);
    dst.capped.extend(src.capped.iter().map(|&v| v + base_v));
    c.record.seconds += p.record.seconds;
    Ok(())
}

#[cfg(test)]
mod tests;
