//! `relight view MODEL`: a model file or scene description is baked first (as `relight bake`
//! with its defaults, progress bar and printed choices), into a cache the next `view` of the
//! same input reuses.

use crate::{bake, Cli, Cmd};
use anyhow::{bail, Context, Result};
use clap::{CommandFactory, FromArgMatches};
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};

/// The bundle `relight view` opens for `input`: `input` itself when it is a bundle
/// (`.relight`), else the cached bake of `input` under `env` (the model's default light
/// when `None`), baked now if the cache has none.
pub fn bundle_for(input: &Path, env: Option<&Path>, out: &crate::args::Out) -> Result<PathBuf> {
    let ext = input
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let scene_json = ext.as_deref() == Some("json");
    if ext.as_deref() == Some("relight")
        || !(scene_json || relight_scene::scene_file::model::is_model(input))
    {
        return Ok(input.to_path_buf());
    }
    let cached = cache_path(input, env)?;
    if cached.is_file() {
        eprintln!(
            "view: using the bake of {} cached at {} (delete it to bake again)",
            input.display(),
            cached.display()
        );
        return Ok(cached);
    }
    if let Some(dir) = cached.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    }
    eprintln!("view: baking {} first", input.display());
    let mut argv: Vec<std::ffi::OsString> = vec![
        "relight".into(),
        "bake".into(),
        input.into(),
        "-o".into(),
        cached.clone().into(),
    ];
    if let Some(e) = env {
        argv.extend(["--env".into(), e.into()]);
    }
    let m = Cli::command().try_get_matches_from(argv)?;
    let cli = Cli::from_arg_matches(&m)?;
    let Cmd::Bake(a) = cli.cmd else {
        bail!("internal: the view's bake did not parse as a bake")
    };
    let sub = m.subcommand().map(|(_, s)| s).expect("a subcommand");
    bake::run(a, sub, out)?;
    Ok(cached)
}

/// `$XDG_CACHE_HOME/relight/view/STEM-HASH.relight` (else `~/.cache/...`), the hash over
/// the input's absolute path, size and modification time, the environment and relight's
/// version: another file, an edited one or another light bakes anew.
fn cache_path(input: &Path, env: Option<&Path>) -> Result<PathBuf> {
    let meta = std::fs::metadata(input).with_context(|| format!("{}", input.display()))?;
    let abs = input.canonicalize().unwrap_or_else(|_| input.to_path_buf());
    let mut h = std::collections::hash_map::DefaultHasher::new();
    abs.hash(&mut h);
    meta.len().hash(&mut h);
    meta.modified().ok().hash(&mut h);
    env.map(|e| e.canonicalize().unwrap_or_else(|_| e.to_path_buf()))
        .hash(&mut h);
    env!("CARGO_PKG_VERSION").hash(&mut h);
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .context("view: neither XDG_CACHE_HOME nor HOME is set, so there is no cache folder for the bake (bake it with `relight bake` and view the bundle)")?;
    let stem = input
        .file_stem()
        .map_or("model".into(), |s| s.to_string_lossy());
    Ok(base
        .join("relight")
        .join("view")
        .join(format!("{stem}-{:016x}.relight", h.finish())))
}
