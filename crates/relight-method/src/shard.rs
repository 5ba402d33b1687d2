//! Sharded bakes: one bake split into `N` parts baked anywhere (a Slurm array task, a
//! Kubernetes indexed job), then merged into the bundle a single process would have written,
//! byte for byte.
//!
//! # Conventions
//! * Part `i` of `N` (0-based, as `SLURM_ARRAY_TASK_ID` and `JOB_COMPLETION_INDEX` count)
//!   holds the units `floor(i U / N) .. floor((i + 1) U / N)` of the bake's `U` units
//!   ([`Shard::range`]): contiguous, in order, every unit in exactly one part. The unit is
//!   the method's ([`Method::bake_shard`]): a vertex for `sh`, a flood-fill region for `sg`.
//! * A part bundle records its [`Shard`] in its [`BakeRecord`](crate::store::BakeRecord)
//!   (and, for `sh`, its vertex range); it holds the whole scene (so a merge can check that
//!   every part saw the same one) and only its rows of the method's per-vertex tensors.
//!   Frames refuse it ([`crate::MethodError::PartialBake`]).
//! * A bake is a pure function of the scene, the settings (seed included) and the back-end:
//!   vertex `v`'s samples are seeded by `(seed, v)`, never by the thread or the part, and the
//!   bundle records no time. So the merged rows are the single-process bake's rows.
//!
//! Which methods split, and how:
//! * `sh` with unshadowed or shadowed transfer, by vertex ranges; the merge concatenates.
//! * `sg`, by flood-fill regions (Green 2005 section 2.2.2; `relight_bake::sg::fit`): the
//!   fill couples neighbouring vertices *within* a region only (eq. 2.6), so regions are
//!   independent; a part fits its regions and stores their rows (f32 whatever the bake's
//!   precision, with the fit errors), and the merge runs what one process runs after the
//!   fill: the regions' alignment, the flip count and the statistics. Relaxation sweeps refit
//!   vertices across region borders after the fill, so a bake with relaxation is refused.
//!   At most one part per region (`--regions` raises their number).
//! * `vmf`, by vertex ranges (each slice is seeded by its vertex and view); the merge
//!   concatenates rows in memory (`Method::streams` says so, and `--memory-limit` refuses).
//! * Interreflected `sh` is refused: each bounce gathers the previous bounce of *every*
//!   vertex, so every part would trace the whole mesh (no part would be cheaper than the
//!   whole bake).

use crate::sg::{SgBaked, SgPartRows};
use crate::{sh::ShBaked, BakeContext, BakeInput, BakeKind, Baked, Method, MethodError};
use relight_bake::sg::{self, SgBake};
use relight_bake::sh::ShTransfer;
use relight_bundle::stream::TensorSpec;
use relight_bundle::{Bundle, BundleError};
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
    let most = M::max_parts(input, settings);
    if shard.count > most {
        let more = match M::KIND {
            crate::BakeKind::Sg => " (--regions raises their number)",
            crate::BakeKind::Sh | crate::BakeKind::Cuts | crate::BakeKind::Vmf => "",
        };
        return Err(MethodError::Settings(format!(
            "--shard {}/{}: this {} bake splits into at most {most} parts, one per {}{more}",
            shard.index,
            shard.count,
            M::KIND.name(),
            M::PART_UNIT
        )));
    }
    let mut baked: Baked = M::bake_shard(input, settings, shard, ctx)?.into();
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
    let mut parts = parts.into_iter();
    let Some(first) = parts.next() else {
        return Err(MethodError::Settings("merge: no parts given".into()));
    };
    let (first_path, first) = first?;
    let mut check = Checker::new(&first_path, &first)?;
    let first_path = check.first_path.clone();
    // slot[i]: part i's path and rows (its scene dropped, but for the first part's).
    let mut slot: Vec<Option<(PathBuf, Baked)>> = (0..check.count).map(|_| None).collect();
    let mut scene = None;
    for (nth, part) in std::iter::once(Ok((first_path.clone(), first)))
        .chain(parts)
        .enumerate()
    {
        let (path, mut b) = part?;
        let index = check.check(nth, &path, &b)?;
        let taken = b.take_scene();
        scene.get_or_insert(taken);
        slot[index] = Some((path, b));
    }
    check.complete()?;
    let err = |path: &Path, message: String| MethodError::Merge {
        path: path.to_path_buf(),
        message,
    };
    let paths: Vec<PathBuf> = slot.iter().flatten().map(|(p, _)| p.clone()).collect();
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
        Some(Baked::Sg(first)) => {
            let mesh = &scene.as_ref().expect("at least one part").mesh;
            let SgBaked {
                scene: s,
                bake,
                settings,
                record,
                part,
            } = first;
            let rest = it.map(|b| match b {
                Baked::Sg(b) => (b.bake, b.part),
                Baked::Sh(_) | Baked::Cuts(_) | Baked::Vmf(_) => {
                    unreachable!("kinds checked above")
                }
            });
            let bake = merge_sg(
                &settings.bake,
                std::iter::once((bake, part)).chain(rest),
                &paths,
                mesh,
            )?;
            Baked::Sg(SgBaked {
                scene: s,
                bake,
                settings,
                record,
                part: None,
            })
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
        Some(Baked::Vmf(mut vmf)) => {
            for b in it {
                let Baked::Vmf(p) = b else {
                    unreachable!("kinds checked above")
                };
                vmf.bake.append(p.bake);
                vmf.record.seconds += p.record.seconds;
            }
            Baked::Vmf(vmf)
        }
        None => unreachable!("no part is missing"),
    };
    whole.put_scene(scene.expect("at least one part"));
    let r = whole.record_mut();
    (r.range, r.shard) = (None, None);
    let valid = match &whole {
        Baked::Sh(sh) => sh.validate(),
        Baked::Sg(sg) => sg.validate(),
        Baked::Cuts(cuts) => cuts.validate(),
        Baked::Vmf(vmf) => vmf.validate(),
    };
    valid.map_err(|e| err(&first_path, format!("merged bake: {e}")))?;
    Ok(whole)
}

/// What every part of one bake must share with the first (its scene's bytes taken once), and
/// which parts came.
struct Checker {
    first_path: PathBuf,
    first: Shard,
    count: usize,
    kind: BakeKind,
    settings: String,
    backend: (String, bool),
    scene: Vec<u8>,
    vertices: usize,
    seen: Vec<Option<PathBuf>>,
}

impl Checker {
    fn new(first_path: &Path, first: &Baked) -> Result<Checker, MethodError> {
        let Some(s0) = first.record().shard else {
            return Err(MethodError::Merge {
                path: first_path.to_path_buf(),
                message: "is not a part of a sharded bake".into(),
            });
        };
        Ok(Checker {
            first_path: first_path.to_path_buf(),
            first: s0,
            count: s0.count,
            kind: first.kind(),
            settings: first.settings_json(),
            backend: (first.record().backend.clone(), first.record().f16),
            scene: first.scene().fingerprint()?,
            vertices: first.scene().mesh.vertex_count(),
            seen: vec![None; s0.count],
        })
    }

    /// Check the `nth` part given (read from `path`) and return its part number.
    fn check(&mut self, nth: usize, path: &Path, b: &Baked) -> Result<usize, MethodError> {
        let err = |message: String| MethodError::Merge {
            path: path.to_path_buf(),
            message,
        };
        let r = b.record();
        let Some(s) = r.shard else {
            return Err(err("is not a part of a sharded bake".into()));
        };
        let differs = |what: &str| {
            err(format!(
                "its {what} differs from that of {}",
                self.first_path.display()
            ))
        };
        if s.count != self.count {
            return Err(err(format!(
                "is part {}/{} but {} is part {}/{}: they come from bakes split differently",
                s.index,
                s.count,
                self.first_path.display(),
                self.first.index,
                self.first.count
            )));
        }
        if nth > 0 {
            if b.kind() != self.kind {
                return Err(differs("method"));
            }
            if b.settings_json() != self.settings {
                return Err(differs("settings (or seed)"));
            }
            if (&r.backend, r.f16) != (&self.backend.0, self.backend.1) {
                return Err(differs("back-end or storage precision"));
            }
            if b.scene().fingerprint()? != self.scene {
                return Err(differs("scene"));
            }
        }
        let v = self.vertices;
        let want = s.range(v);
        let by_range = matches!(b.kind(), BakeKind::Sh | BakeKind::Vmf);
        if by_range && r.range.unwrap_or((0, v)) != (want.start, want.end) {
            return Err(err(format!(
                "holds vertices {:?} but part {}/{} is {want:?}",
                r.range, s.index, s.count
            )));
        }
        if let Some(other) = &self.seen[s.index] {
            return Err(err(format!(
                "part {}/{} is given twice (also {})",
                s.index,
                s.count,
                other.display()
            )));
        }
        self.seen[s.index] = Some(path.to_path_buf());
        Ok(s.index)
    }

    /// Every part came.
    fn complete(&self) -> Result<(), MethodError> {
        let missing: Vec<String> = (0..self.count)
            .filter(|&i| self.seen[i].is_none())
            .map(|i| i.to_string())
            .collect();
        if missing.is_empty() {
            return Ok(());
        }
        Err(MethodError::Merge {
            path: self.first_path.clone(),
            message: format!("parts {} of {} are missing", missing.join(", "), self.count),
        })
    }
}

/// [`merge`] the part bundles `paths` (any order) into the bundle `out`, written atomically,
/// with memory bounded by one part for methods whose merge concatenates rows (`sh`): the
/// parts are read once to check them, then the output's tensors are streamed in name order,
/// each from the parts in turn ([`relight_bundle::stream`]). An `sg` merge aligns regions
/// over the whole mesh, so it holds the whole bake. The file is the one [`merge`] then
/// [`Baked::write`] would write.
///
/// # Errors
/// As [`merge`], and IO errors naming the file.
pub fn merge_files(paths: &[PathBuf], out: &Path) -> Result<crate::BakeSummary, MethodError> {
    let Some(first_path) = paths.first() else {
        return Err(MethodError::Settings("merge: no parts given".into()));
    };
    let first = crate::read_any(first_path)?;
    if first.kind() != BakeKind::Sh {
        let rest = paths[1..]
            .iter()
            .map(|p| Ok((p.clone(), crate::read_any(p)?)));
        let whole = merge(std::iter::once(Ok((first_path.clone(), first))).chain(rest))?;
        whole.write(out)?;
        return Ok(crate::BakeSummary::of(&whole));
    }
    let mut check = Checker::new(first_path, &first)?;
    let mut order: Vec<PathBuf> = vec![PathBuf::new(); check.count];
    let mut head = None;
    let mut first = Some(first);
    for (nth, path) in paths.iter().enumerate() {
        let b = match first.take() {
            Some(b) => b,
            None => crate::read_any(path)?,
        };
        let index = check.check(nth, path, &b)?;
        order[index] = path.clone();
        if index == 0 {
            head = Some(b);
        }
    }
    check.complete()?;
    let mut head = head.expect("part 0 is there");
    let r = head.record_mut();
    (r.range, r.shard) = (None, None);
    let v = check.vertices;
    let rows = crate::sh::ROW_TENSORS;
    let bundle = head.to_bundle()?;
    let specs: Vec<TensorSpec> = bundle
        .tensors
        .iter()
        .map(|(name, t)| {
            let mut shape = t.shape.clone();
            if rows.contains(&name.as_str()) {
                shape[0] = v;
            }
            TensorSpec {
                name: name.clone(),
                dtype: t.dtype,
                shape,
            }
        })
        .collect();
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |error| BundleError::Io { path, error }
    };
    relight_bundle::stream::write_streamed(out, &bundle.metadata, &specs, |spec, sink| {
        if !rows.contains(&spec.name.as_str()) {
            return sink
                .write(&bundle.tensors[&spec.name].bytes)
                .map_err(io(out));
        }
        for (i, path) in order.iter().enumerate() {
            let part = Bundle::read(path)?;
            let t = part.tensor(path, &spec.name)?;
            let want = Shard {
                index: i,
                count: order.len(),
            }
            .range(v)
            .len();
            if t.dtype != spec.dtype || t.shape[1..] != spec.shape[1..] || t.shape[0] != want {
                return Err(BundleError::Invalid {
                    path: path.clone(),
                    msg: format!(
                        "tensor '{}' is {} {:?}, expected {} [{want}, ...] (changed since it was checked?)",
                        spec.name,
                        t.dtype.name(),
                        t.shape,
                        spec.dtype.name()
                    ),
                });
            }
            sink.write(&t.bytes).map_err(io(out))?;
        }
        Ok(())
    })?;
    let mut summary = crate::BakeSummary::of(&head);
    summary.vertices = v;
    Ok(summary)
}

/// The whole `sg` bake from its parts `all` in part order (`paths` name them):
/// each part must hold the vertices of the regions its number says
/// ([`relight_bake::sg::finish_parts`] then aligns the regions as one process does).
fn merge_sg(
    settings: &relight_bake::sg::SgBakeSettings,
    all: impl Iterator<Item = (SgBake, Option<SgPartRows>)>,
    paths: &[PathBuf],
    mesh: &relight_scene::mesh::TriMesh,
) -> Result<SgBake, MethodError> {
    let plan = sg::region_plan(mesh, settings);
    let count = paths.len();
    let r = plan.region_count();
    let mut parts = Vec::with_capacity(count);
    for (i, ((bake, rows), path)) in all.zip(paths).enumerate() {
        let bad = |message: String| MethodError::Merge {
            path: path.clone(),
            message,
        };
        let Some(rows) = rows else {
            return Err(bad("holds no part rows".into()));
        };
        let want = Shard { index: i, count }.range(r);
        if rows.vertices != plan.vertices(want.clone()) {
            return Err(bad(format!(
                "does not hold the vertices of flood-fill regions {want:?} of {r}, which part {i}/{count} is"
            )));
        }
        parts.push(crate::sg::to_part(bake, rows));
    }
    sg::finish_parts(mesh, settings, parts).map_err(|e| MethodError::Merge {
        path: paths[0].clone(),
        message: e.to_string(),
    })
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
    if p.bake.samples != c.bake.samples
        || p.bake.surface != c.bake.surface
        || p.bake.tree != c.bake.tree
    {
        return Err("parts with different light samples or light trees".into());
    }
    c.bake.cuts.append(p.bake.cuts);
    c.record.seconds += p.record.seconds;
    Ok(())
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_sg;
