//! Textured glTF test assets made by third-party tools: [`gltf_assets`] and [`validate_gltf`].
//!
//! `tools/gltf-assets/make_assets.mjs` (Node) turns the shared `data/meshes/spot.obj` and
//! `spot_texture.png` into a textured GLB with `obj2gltf`, makes variants of it with the
//! `@gltf-transform` library (metallic-roughness texture, normal texture,
//! `KHR_texture_transform`, external `.bin` and `.png` files, two named objects), and checks
//! every output with the Khronos `gltf-validator` (zero errors, else the build fails with the
//! validator's messages). The script's header lists each asset and what it holds.
//!
//! The tools are the ones `scripts/setup.sh` installs with `npm ci` at the versions pinned by
//! `tools/gltf-assets/package-lock.json`, into `$RELIGHT_NPM` (default
//! `$HOME/.cache/relight/npm`); `node` must be on `PATH`. Without them, or without the shared
//! data, [`gltf_assets`] and [`validate_gltf`] [`skip`] with the reason (a failure under
//! `RELIGHT_REQUIRE_REFERENCE=1`).
//!
//! The assets are built once per test process and cached across processes in
//! `<target>/relight-gltf-assets/<key>/`, where the key is a 64-bit FNV-1a hash of the OBJ,
//! the texture, the script and the lock file: a change to any of them builds a new folder.
//! A build goes to a temporary folder renamed into place when complete, so concurrent test
//! processes never see half an asset set.

use crate::{shared_dir, skip};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The Khronos glTF-Validator's verdict on one file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ValidatorVerdict {
    /// The file's name (no folder).
    pub file: String,
    /// Number of issues of severity error.
    pub errors: u32,
    /// Number of warnings.
    pub warnings: u32,
    /// Number of infos.
    pub infos: u32,
    /// Number of hints.
    pub hints: u32,
    /// The distinct issue codes reported (e.g. `IMAGE_FEATURES_UNSUPPORTED`).
    pub codes: Vec<String>,
}

/// The built assets (see the module docs and `tools/gltf-assets/make_assets.mjs`).
#[derive(Debug, Clone)]
pub struct GltfAssets {
    /// The folder holding everything below (and obj2gltf's inputs `spot.obj`, `spot.mtl`,
    /// `spot_texture.png`).
    pub dir: PathBuf,
    /// `spot.glb`: obj2gltf's output, base-colour texture embedded.
    pub spot: PathBuf,
    /// `spot_mr.glb`: plus a striped metallic-roughness texture.
    pub metallic_roughness: PathBuf,
    /// `spot_normal.glb`: plus a bumpy normal texture.
    pub normal: PathBuf,
    /// `spot_transform.glb`: `KHR_texture_transform` on the base colour.
    pub texture_transform: PathBuf,
    /// `spot_external.gltf`: base colour, metallic-roughness and normal textures in separate
    /// `.png` files and the geometry in a separate `.bin`.
    pub external: PathBuf,
    /// `spot_two.glb`: nodes `spot_plastic` (origin) and `spot_metal` (moved along +x by 1.5
    /// bounding-box widths), each with its own mesh and material.
    pub two_objects: PathBuf,
    /// The validator's verdict on each asset above, in that order.
    pub verdicts: Vec<ValidatorVerdict>,
    /// The builder's steps and their times in milliseconds (of the run that built the folder).
    pub timings: Vec<(String, f64)>,
}

impl GltfAssets {
    /// Every asset's path, in the order of [`GltfAssets::verdicts`].
    pub fn all(&self) -> [&Path; 6] {
        [
            &self.spot,
            &self.metallic_roughness,
            &self.normal,
            &self.texture_transform,
            &self.external,
            &self.two_objects,
        ]
    }
}

const ASSET_FILES: [&str; 6] = [
    "spot.glb",
    "spot_mr.glb",
    "spot_normal.glb",
    "spot_transform.glb",
    "spot_external.gltf",
    "spot_two.glb",
];

fn repo_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn script() -> PathBuf {
    repo_dir().join("tools/gltf-assets/make_assets.mjs")
}

/// The folder the npm tools are installed in: `$RELIGHT_NPM` or `$HOME/.cache/relight/npm`.
pub fn npm_dir() -> PathBuf {
    match std::env::var_os("RELIGHT_NPM") {
        Some(d) => PathBuf::from(d),
        None => {
            PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache/relight/npm")
        }
    }
}

/// Why the tools cannot run here, if they cannot: no `node`, or the pinned tools not
/// installed in [`npm_dir`].
fn tools_missing() -> Option<String> {
    let npm = npm_dir();
    let node_ok = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !node_ok {
        return Some("`node` is not on PATH (scripts/setup.sh installs nodejs and npm)".into());
    }
    let committed = std::fs::read(repo_dir().join("tools/gltf-assets/package-lock.json")).ok();
    let installed = std::fs::read(npm.join("installed-lock.json")).ok();
    if committed.is_none() || installed != committed {
        return Some(format!(
            "the glTF asset tools (obj2gltf, @gltf-transform, gltf-validator) are not installed \
             at the pinned versions in {} (run scripts/setup.sh)",
            npm.display()
        ));
    }
    None
}

/// 64-bit FNV-1a over the parts, each preceded by its length (so boundaries count).
fn fnv1a(parts: &[&[u8]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for p in parts {
        eat(&(p.len() as u64).to_le_bytes());
        eat(p);
    }
    h
}

/// Cargo's target folder of this test binary (the ancestor holding `CACHEDIR.TAG`), else the
/// workspace's `target`.
fn target_dir() -> PathBuf {
    std::env::current_exe()
        .ok()
        .and_then(|exe| {
            exe.ancestors()
                .find(|d| d.join("CACHEDIR.TAG").is_file())
                .map(Path::to_path_buf)
        })
        .unwrap_or_else(|| repo_dir().join("target"))
}

/// Parse the builder's `validation.tsv` lines (`file errors warnings infos hints codes`).
fn parse_verdicts(text: &str) -> Result<Vec<ValidatorVerdict>, String> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|line| {
            let f: Vec<&str> = line.split('\t').collect();
            let num = |i: usize| -> Result<u32, String> {
                f.get(i)
                    .and_then(|s| s.parse().ok())
                    .ok_or_else(|| format!("bad validator line '{line}'"))
            };
            Ok(ValidatorVerdict {
                file: f[0].to_string(),
                errors: num(1)?,
                warnings: num(2)?,
                infos: num(3)?,
                hints: num(4)?,
                codes: f
                    .get(5)
                    .map(|c| {
                        c.split(',')
                            .filter(|c| !c.is_empty())
                            .map(String::from)
                            .collect()
                    })
                    .unwrap_or_default(),
            })
        })
        .collect()
}

fn parse_timings(text: &str) -> Vec<(String, f64)> {
    text.lines()
        .filter_map(|l| {
            let (name, ms) = l.split_once('\t')?;
            Some((name.to_string(), ms.trim().parse().ok()?))
        })
        .collect()
}

/// Read a complete asset folder (its `timings.tsv` is written last).
fn read_folder(dir: &Path) -> Result<GltfAssets, String> {
    let read = |f: &str| {
        std::fs::read_to_string(dir.join(f)).map_err(|e| format!("{}: {e}", dir.join(f).display()))
    };
    let verdicts = parse_verdicts(&read("validation.tsv")?)?;
    let names: Vec<&str> = verdicts.iter().map(|v| v.file.as_str()).collect();
    if names != ASSET_FILES {
        return Err(format!("{}: validation.tsv lists {names:?}", dir.display()));
    }
    let p = |i: usize| dir.join(ASSET_FILES[i]);
    Ok(GltfAssets {
        dir: dir.to_path_buf(),
        spot: p(0),
        metallic_roughness: p(1),
        normal: p(2),
        texture_transform: p(3),
        external: p(4),
        two_objects: p(5),
        verdicts,
        timings: parse_timings(&read("timings.tsv")?),
    })
}

/// Build the assets (or find them built); `Err` is a skip reason, a failed build panics.
fn build() -> Result<GltfAssets, String> {
    let shared = shared_dir().ok_or(
        "shared data folder (../shared or $RELIGHT_SHARED) not present; the glTF assets are \
         made from data/meshes/spot.obj",
    )?;
    let (obj, texture) = (
        shared.join("data/meshes/spot.obj"),
        shared.join("data/meshes/spot_texture.png"),
    );
    if let Some(why) = tools_missing() {
        return Err(why);
    }
    let read = |p: &Path| std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()));
    let key = fnv1a(&[
        &read(&obj)?,
        &read(&texture)?,
        &read(&script())?,
        &read(&repo_dir().join("tools/gltf-assets/package-lock.json"))?,
    ]);
    let root = target_dir().join("relight-gltf-assets");
    let dir = root.join(format!("{key:016x}"));
    if dir.join("timings.tsv").is_file() {
        return Ok(read_folder(&dir).unwrap_or_else(|e| panic!("cached glTF assets: {e}")));
    }
    std::fs::create_dir_all(&root).unwrap_or_else(|e| panic!("{}: {e}", root.display()));
    let tmp = root.join(format!("{key:016x}.tmp-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let out = Command::new("node")
        .arg(script())
        .arg("build")
        .arg("--npm")
        .arg(npm_dir())
        .arg("--obj")
        .arg(&obj)
        .arg("--texture")
        .arg(&texture)
        .arg("--out")
        .arg(&tmp)
        .output()
        .unwrap_or_else(|e| panic!("cannot run node: {e}"));
    eprint!("{}", String::from_utf8_lossy(&out.stdout));
    if !out.status.success() {
        let _ = std::fs::remove_dir_all(&tmp);
        panic!(
            "building the glTF assets failed ({}):\n{}{}",
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // Another process may have finished the same key first: then use its folder.
    if std::fs::rename(&tmp, &dir).is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    Ok(read_folder(&dir).unwrap_or_else(|e| panic!("built glTF assets: {e}")))
}

/// The textured glTF test assets, built once per test process (cached across runs, see the
/// module docs), or `None` after a [`skip`] naming what is missing (the npm tools, `node`,
/// the shared data): `let Some(assets) = gltf_assets() else { return };`
///
/// # Panics
/// When the tools are there but the build fails (the validator finds an error in an asset,
/// a tool fails): the message carries the script's output. Under
/// `RELIGHT_REQUIRE_REFERENCE=1`, when it would skip.
#[track_caller]
pub fn gltf_assets() -> Option<&'static GltfAssets> {
    static ASSETS: OnceLock<Result<GltfAssets, String>> = OnceLock::new();
    match ASSETS.get_or_init(build) {
        Ok(a) => Some(a),
        Err(why) => {
            skip(why);
            None
        }
    }
}

/// Run the Khronos glTF-Validator on `file` (a `.glb` or `.gltf`; external resources are read
/// from its folder): `Some(Ok(verdict))` when it has no error, `Some(Err(messages))` with the
/// validator's error messages when it has errors or cannot be read as glTF, `None` after a
/// [`skip`] when the tools are missing.
///
/// # Panics
/// When `node` cannot be started although found before; under `RELIGHT_REQUIRE_REFERENCE=1`,
/// when it would skip.
#[track_caller]
pub fn validate_gltf(file: &Path) -> Option<Result<ValidatorVerdict, String>> {
    if let Some(why) = tools_missing() {
        skip(&why);
        return None;
    }
    let out = Command::new("node")
        .arg(script())
        .args(["validate", "--npm"])
        .arg(npm_dir())
        .arg(file)
        .output()
        .unwrap_or_else(|e| panic!("cannot run node: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let verdict = parse_verdicts(&stdout)
        .ok()
        .and_then(|v| v.into_iter().next());
    Some(match (out.status.success(), verdict) {
        (true, Some(v)) => Ok(v),
        (true, None) => Err(format!(
            "the validator printed no verdict: {stdout}{stderr}"
        )),
        (false, _) => Err(format!("{stdout}{stderr}")),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_known_values_and_counts_boundaries() {
        // FNV-1a 64 of the empty input is the offset basis; of "a" the published 0xaf63dc4c8601ec8c.
        let plain = |b: &[u8]| {
            let mut h: u64 = 0xcbf2_9ce4_8422_2325;
            for &x in b {
                h = (h ^ u64::from(x)).wrapping_mul(0x0000_0100_0000_01b3);
            }
            h
        };
        assert_eq!(plain(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(plain(b"a"), 0xaf63_dc4c_8601_ec8c);
        // A part is its length (8 bytes, little-endian) then its bytes.
        assert_eq!(fnv1a(&[]), plain(b""));
        assert_eq!(fnv1a(&[b"a"]), plain(b"\x01\0\0\0\0\0\0\0a"));
        // Moving a byte from one part to the next changes the key.
        assert_ne!(fnv1a(&[b"ab", b"c"]), fnv1a(&[b"a", b"bc"]));
        assert_eq!(fnv1a(&[b"ab", b"c"]), fnv1a(&[b"ab", b"c"]));
    }

    #[test]
    fn verdict_lines_parse_and_bad_ones_are_refused() {
        let v = parse_verdicts("spot.glb\t0\t2\t1\t0\tA_CODE,B_CODE\nx.gltf\t3\t0\t0\t0\t\n")
            .expect("valid lines");
        assert_eq!(v.len(), 2);
        assert_eq!(
            v[0],
            ValidatorVerdict {
                file: "spot.glb".into(),
                errors: 0,
                warnings: 2,
                infos: 1,
                hints: 0,
                codes: vec!["A_CODE".into(), "B_CODE".into()],
            }
        );
        assert_eq!((v[1].errors, v[1].codes.len()), (3, 0));
        for bad in ["spot.glb\t0\t2", "spot.glb\tzero\t0\t0\t0\t", "spot.glb"] {
            assert!(parse_verdicts(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn timings_parse() {
        let t = parse_timings("obj2gltf\t387.5\nmaps\t34\nbroken line\n");
        assert_eq!(
            t,
            vec![("obj2gltf".to_string(), 387.5), ("maps".to_string(), 34.0)]
        );
    }
}
