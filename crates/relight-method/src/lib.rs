//! # relight-method: one seam for every precomputed-transport method
//!
//! A method is what a user picks with `--method`: [`MethodKind`]. Each one has the same verbs,
//! in one folder of this crate:
//!
//! | verb | where | what |
//! |---|---|---|
//! | settings | `Method::Settings` | serde (recorded in the bundle once), validated, and with the `cli` feature the clap options of `relight bake` |
//! | bake | [`Method::bake`] | scene + settings + vertex range -> the method's baked data |
//! | store / load | [`Method::store`], [`Method::load`] | the baked data <-> bundle tensors (schema in [`store`]) |
//! | frame | [`Frame`] | prepare an environment once, then render any camera |
//!
//! Methods that share a bake share its [`BakeKind`]: `hybrid` (thesis ch. 4) is a frame over
//! the `sh` bake, so `hybrid/` has settings and a frame only.
//!
//! [`read_any`] reads any bundle into the closed enum [`Baked`]; [`Baked::frame`] makes the
//! frame of a method, or says which bake the method needs.
//!
//! # Adding a method (what `cuts` and `vmf` do)
//! 1. The maths and the bake loop go in `relight-bake/src/<name>.rs` (settings struct with
//!    `#[derive(Serialize, Deserialize)]` and `#[cfg_attr(feature = "cli", derive(clap::Args))]`,
//!    `validate()`), the per-pixel or per-vertex shading in `relight-render/src/shade_<name>.rs`.
//! 2. Here: `src/<name>.rs` with the baked type and `impl Method`, `<name>/store.rs` with its
//!    tensors (prefixed `<name>_`), `<name>/frame.rs` with its frame settings and `impl Frame`.
//! 3. One arm in each closed set: [`MethodKind`], [`BakeKind`], [`Baked`], [`FrameSettings`].
//!    The compiler then lists every `match` to extend (the CLI's bake dispatch among them).
//! 4. Its evaluation against Mitsuba in `relight-eval`, its benchmark in `relight-eval::bench`.
//!
//! ```no_run
//! use relight_method::{read_any, FrameOptions, FrameSettings, MethodKind};
//! # fn demo(env: &relight_scene::scene::Environment) -> Result<(), relight_method::MethodError> {
//! let baked = read_any(std::path::Path::new("bake.relight"))?;
//! let mut frame = baked.frame(&FrameSettings::default_for(MethodKind::Sh))?;
//! frame.set_environment(env)?;
//! let out = frame.render(&baked.scene().desc.camera, &FrameOptions::default());
//! assert_eq!(out.image.width, baked.scene().desc.camera.width as usize);
//! # Ok(()) }
//! ```

pub mod checkpoint;
pub mod choose;
pub mod cuts;
mod error;
pub mod hybrid;
pub mod job;
pub mod memory;
pub mod objects;
mod prefiltered;
pub mod sg;
pub mod sh;
pub mod shard;
pub mod store;
#[cfg(test)]
mod test_scene;
pub mod vmf;

pub use error::MethodError;
pub use store::{objects_of_materials, BakeRecord, BakedScene};

use relight_bundle::Bundle;
use relight_render::Image;
use relight_scene::accel::Backend;
use relight_scene::camera::Camera;
use relight_scene::scene::{Environment, Scene};
use relight_scene::scene_file::SceneDesc;
use serde::{de::DeserializeOwned, Deserialize, Serialize};
use std::ops::Range;
use std::path::Path;

/// The methods a user can pick (`--method`). A closed set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum MethodKind {
    /// Diffuse SH PRT: shadowed or interreflected transfer (Sloan et al. 2002; thesis 4.2).
    Sh,
    /// The `sh` bake lit by the environment's low-order SH part plus extracted cap lights
    /// with shadow maps (hybrid thesis 4.3-4.4).
    Hybrid,
    /// View-dependent glossy PRT with spherical Gaussians (Green 2005).
    Sg,
    /// Precomputed visibility cuts merged per pixel with the illumination cut, materials
    /// evaluated at render time, with texture and normal maps, and point or spot lights with
    /// one bounce in surface-sample bakes (Cheslack-Postava et al. 2008).
    Cuts,
    /// View-dependent glossy PRT with one von Mises-Fisher lobe per light-path class,
    /// estimated in closed form from traced paths (Laurijssen & Dutré 2009).
    Vmf,
}

impl MethodKind {
    /// Every method.
    pub const ALL: [MethodKind; 5] = [
        MethodKind::Sh,
        MethodKind::Hybrid,
        MethodKind::Sg,
        MethodKind::Cuts,
        MethodKind::Vmf,
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            MethodKind::Sh => "sh",
            MethodKind::Hybrid => "hybrid",
            MethodKind::Sg => "sg",
            MethodKind::Cuts => "cuts",
            MethodKind::Vmf => "vmf",
        }
    }

    /// The bake the method renders.
    pub fn bake_kind(self) -> BakeKind {
        match self {
            MethodKind::Sh | MethodKind::Hybrid => BakeKind::Sh,
            MethodKind::Sg => BakeKind::Sg,
            MethodKind::Cuts => BakeKind::Cuts,
            MethodKind::Vmf => BakeKind::Vmf,
        }
    }
}

/// The kinds of baked data a bundle can hold (its `method` metadata). A closed set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BakeKind {
    /// Per-vertex SH transfer ([`sh::ShBaked`]), rendered by `sh` and `hybrid`.
    Sh,
    /// Per-vertex, per-view spherical Gaussians ([`sg::SgBaked`]), rendered by `sg`.
    Sg,
    /// Light samples, light tree and per-vertex visibility cuts ([`cuts::CutsBaked`]),
    /// rendered by `cuts`.
    Cuts,
    /// Per-vertex, per-view vMF transfer slices ([`vmf::VmfBaked`]), rendered by `vmf`.
    Vmf,
}

impl BakeKind {
    /// The name in bundles and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BakeKind::Sh => "sh",
            BakeKind::Sg => "sg",
            BakeKind::Cuts => "cuts",
            BakeKind::Vmf => "vmf",
        }
    }

    /// The methods that render this bake.
    pub fn methods(self) -> Vec<MethodKind> {
        MethodKind::ALL
            .into_iter()
            .filter(|m| m.bake_kind() == self)
            .collect()
    }
}

/// What a bake reads: the scene description, the scene built from it and where it came from
/// (named in errors).
#[derive(Clone, Copy)]
pub struct BakeInput<'a> {
    /// The description (recorded in the bundle).
    pub desc: &'a SceneDesc,
    /// The scene built from it.
    pub scene: &'a Scene,
    /// The scene file, or a name in `<>` for built-in scenes.
    pub origin: &'a Path,
}

/// How a bake runs (none of it changes the result, except `f16`, a storage choice).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeContext {
    /// Ray-casting back-end.
    pub backend: Backend,
    /// Store the method's float tensors as f16.
    pub f16: bool,
    /// Show progress bars on stderr.
    pub progress: bool,
}

impl Default for BakeContext {
    /// The fastest back-end available, f32, no progress bars.
    fn default() -> Self {
        BakeContext {
            backend: Backend::available()[0],
            f16: false,
            progress: false,
        }
    }
}

/// The verbs of a method's bake: settings, bake, store, load.
pub trait Method {
    /// The bake kind this method produces.
    const KIND: BakeKind;
    /// Its settings: serde (recorded in the bundle once) and validated.
    type Settings: Serialize + DeserializeOwned + Clone + std::fmt::Debug + PartialEq;
    /// What the bake produces and the bundle stores.
    type Baked;

    /// Check every setting's range; the message names the setting.
    ///
    /// # Errors
    /// [`MethodError::Settings`].
    fn validate(settings: &Self::Settings) -> Result<(), MethodError>;

    /// Bake the vertices `range` of `input` (all of them: `0..vertex_count`).
    ///
    /// # Errors
    /// Invalid settings or scene, a back-end that cannot be built, or a method that cannot
    /// bake a part (the message says why).
    fn bake(
        input: BakeInput,
        settings: &Self::Settings,
        range: Range<usize>,
        ctx: &BakeContext,
    ) -> Result<Self::Baked, MethodError>;

    /// Bytes of one vertex's rows of the bake in memory ([`crate::memory`]).
    fn row_bytes(input: BakeInput, settings: &Self::Settings) -> u64;

    /// One line naming the settings that matter, for the bake's progress report.
    fn settings_line(settings: &Self::Settings) -> String;

    /// `None` if the bake can be baked in chunks and merged by streaming; else why not
    /// ([`crate::memory`]).
    fn streams(settings: &Self::Settings) -> Option<&'static str>;

    /// What one unit of a sharded bake is ([`Method::max_parts`]), for messages.
    const PART_UNIT: &'static str = "vertex";

    /// Most parts a bake of `input` splits into (no part is empty): by default one per
    /// vertex.
    fn max_parts(input: BakeInput, settings: &Self::Settings) -> usize {
        let _ = settings;
        input.scene.mesh.vertex_count()
    }

    /// Bake part `shard` of `input` ([`crate::shard`]): by default the vertices
    /// `shard.range(V)` through [`Method::bake`]. A method whose parts are not vertex ranges
    /// overrides it.
    ///
    /// # Errors
    /// As [`Method::bake`], and a part that cannot be made (the message says why).
    fn bake_shard(
        input: BakeInput,
        settings: &Self::Settings,
        shard: shard::Shard,
        ctx: &BakeContext,
    ) -> Result<Self::Baked, MethodError> {
        let v = input.scene.mesh.vertex_count();
        Self::bake(input, settings, shard.range(v), ctx)
    }

    /// Write the baked data into a bundle (scene part, settings, record and tensors).
    ///
    /// # Errors
    /// [`MethodError::Settings`] if the settings cannot be recorded.
    fn store(baked: &Self::Baked) -> Result<Bundle, MethodError>;

    /// Read and check the baked data of a bundle read from `path` (named in errors); old
    /// bundles (before schema 2) are migrated.
    ///
    /// # Errors
    /// [`MethodError::Invalid`] or [`MethodError::Bundle`] naming the file and the problem.
    fn load(bundle: &Bundle, path: &Path) -> Result<Self::Baked, MethodError>;
}

/// A material from inline JSON (starting with `{`) or the path of a `.json` file holding
/// one (a regular file of at most 64 MiB), validated.
///
/// # Errors
/// A message naming the file or the JSON and the problem.
pub fn parse_material(text: &str) -> Result<relight_scene::material::Material, String> {
    let (json, origin) = if text.trim_start().starts_with('{') {
        (text.to_string(), "the material".to_string())
    } else {
        let bytes = relight_scene::io::files::read_file(
            std::path::Path::new(text),
            relight_scene::io::files::MAX_TEXT_BYTES,
            "material file",
        )
        .map_err(|e| format!("not inline JSON, and {e}"))?;
        (
            String::from_utf8_lossy(&bytes).into_owned(),
            text.to_string(),
        )
    };
    let m: relight_scene::material::Material =
        serde_json::from_str(&json).map_err(|e| format!("{origin}: not a valid material: {e}"))?;
    m.validate().map_err(|e| format!("{origin}: {e}"))?;
    Ok(m)
}

/// Parse `--material` of the cuts frame: inline JSON or a `.json` file holding a material,
/// which may name texture and normal maps (loaded and checked when the frame is built,
/// relative to the file's folder: [`cuts::MaterialOverride`]). The constant material is
/// checked here.
pub fn parse_material_override(text: &str) -> Result<cuts::MaterialOverride, String> {
    let inline = text.trim_start().starts_with('{');
    let (json, origin) = if inline {
        (
            text.to_string(),
            std::path::PathBuf::from("./<inline material>"),
        )
    } else {
        let path = std::path::PathBuf::from(text);
        let bytes = relight_scene::io::files::read_file(
            &path,
            relight_scene::io::files::MAX_TEXT_BYTES,
            "material file",
        )
        .map_err(|e| format!("not inline JSON, and {e}"))?;
        (String::from_utf8_lossy(&bytes).into_owned(), path)
    };
    let desc: relight_scene::material::maps::MaterialDesc = serde_json::from_str(&json)
        .map_err(|e| format!("{}: not a valid material: {e}", origin.display()))?;
    desc.material
        .validate()
        .map_err(|e| format!("{}: {e}", origin.display()))?;
    Ok(cuts::MaterialOverride { desc, origin })
}

/// Any bake, as read from a bundle. A closed set (one arm per [`BakeKind`]).
// One `Baked` exists per loaded bundle (never in arrays), and its arms hold large heap data
// either way: boxing the larger arm would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Baked {
    /// An `sh` bake.
    Sh(sh::ShBaked),
    /// An `sg` bake.
    Sg(sg::SgBaked),
    /// A `cuts` bake.
    Cuts(cuts::CutsBaked),
    /// A `vmf` bake.
    Vmf(vmf::VmfBaked),
}

impl Baked {
    /// Its kind.
    pub fn kind(&self) -> BakeKind {
        match self {
            Baked::Sh(_) => BakeKind::Sh,
            Baked::Sg(_) => BakeKind::Sg,
            Baked::Cuts(_) => BakeKind::Cuts,
            Baked::Vmf(_) => BakeKind::Vmf,
        }
    }

    /// The scene it was baked from.
    pub fn scene(&self) -> &BakedScene {
        match self {
            Baked::Sh(b) => &b.scene,
            Baked::Sg(b) => &b.scene,
            Baked::Cuts(b) => &b.scene,
            Baked::Vmf(b) => &b.scene,
        }
    }

    /// How it was baked.
    pub fn record(&self) -> &BakeRecord {
        match self {
            Baked::Sh(b) => &b.record,
            Baked::Sg(b) => &b.record,
            Baked::Cuts(b) => &b.record,
            Baked::Vmf(b) => &b.record,
        }
    }

    /// How it was baked, to amend (a part's number).
    pub(crate) fn record_mut(&mut self) -> &mut BakeRecord {
        match self {
            Baked::Sh(b) => &mut b.record,
            Baked::Sg(b) => &mut b.record,
            Baked::Cuts(b) => &mut b.record,
            Baked::Vmf(b) => &mut b.record,
        }
    }

    /// Take its scene out (leaving an empty one), to keep one copy when merging parts.
    pub(crate) fn take_scene(&mut self) -> BakedScene {
        let s = match self {
            Baked::Sh(b) => &mut b.scene,
            Baked::Sg(b) => &mut b.scene,
            Baked::Cuts(b) => &mut b.scene,
            Baked::Vmf(b) => &mut b.scene,
        };
        BakedScene {
            desc: s.desc.clone(),
            mesh: std::mem::take(&mut s.mesh),
            materials: std::mem::take(&mut s.materials),
            maps: std::mem::take(&mut s.maps),
            objects: std::mem::take(&mut s.objects),
        }
    }

    /// Put a scene back (see [`Baked::take_scene`]).
    pub(crate) fn put_scene(&mut self, scene: BakedScene) {
        match self {
            Baked::Sh(b) => b.scene = scene,
            Baked::Sg(b) => b.scene = scene,
            Baked::Cuts(b) => b.scene = scene,
            Baked::Vmf(b) => b.scene = scene,
        }
    }

    /// The method's description of the bake (lines for people, the same figures as JSON),
    /// for the methods that have one.
    pub fn describe(&self) -> Option<(Vec<String>, serde_json::Value)> {
        match self {
            Baked::Sg(sg) => Some(sg.describe()),
            Baked::Cuts(cuts) => Some(cuts.describe()),
            Baked::Vmf(vmf) => Some(vmf.describe()),
            Baked::Sh(_) => None,
        }
    }

    /// Its settings as recorded (JSON).
    pub fn settings_json(&self) -> String {
        match self {
            Baked::Sh(b) => serde_json::to_string(&b.settings),
            Baked::Sg(b) => serde_json::to_string(&b.settings),
            Baked::Cuts(b) => serde_json::to_string(&b.settings),
            Baked::Vmf(b) => serde_json::to_string(&b.settings),
        }
        .unwrap_or_default()
    }

    /// The bundle of this bake.
    ///
    /// # Errors
    /// As [`Method::store`].
    pub fn to_bundle(&self) -> Result<Bundle, MethodError> {
        match self {
            Baked::Sh(b) => sh::Sh::store(b),
            Baked::Sg(b) => sg::Sg::store(b),
            Baked::Cuts(b) => cuts::Cuts::store(b),
            Baked::Vmf(b) => vmf::Vmf::store(b),
        }
    }

    /// Write the bundle atomically to `path`.
    ///
    /// # Errors
    /// As [`Method::store`], or an IO error naming `path`.
    pub fn write(&self, path: &Path) -> Result<(), MethodError> {
        Ok(self.to_bundle()?.write(path)?)
    }

    /// A frame of `settings`' method over this bake; `path` (the bundle, for messages).
    ///
    /// # Errors
    /// [`MethodError::WrongBake`] when the method renders another bake kind,
    /// [`MethodError::PartialBake`] for a part of a sharded bake, invalid frame settings.
    pub fn frame_of(
        &self,
        settings: &FrameSettings,
        path: &Path,
    ) -> Result<Box<dyn Frame + Sync + '_>, MethodError> {
        let method = settings.method();
        let vertices = self.scene().mesh.vertex_count();
        self.record().require_whole(path, vertices)?;
        match (self, settings) {
            (Baked::Sh(b), FrameSettings::Sh(s)) => Ok(Box::new(sh::ShFrame::new(b, s)?)),
            (Baked::Sh(b), FrameSettings::Hybrid(s)) => {
                Ok(Box::new(hybrid::HybridFrame::new(b, s)?))
            }
            (Baked::Sg(b), FrameSettings::Sg(s)) => Ok(Box::new(sg::SgFrame::new(b, s)?)),
            (Baked::Cuts(b), FrameSettings::Cuts(s)) => Ok(Box::new(cuts::CutsFrame::new(b, s)?)),
            (Baked::Vmf(b), FrameSettings::Vmf(s)) => Ok(Box::new(vmf::VmfFrame::new(b, s)?)),
            _ => Err(MethodError::WrongBake {
                path: path.to_path_buf(),
                found: self.kind(),
                needed: method.bake_kind(),
                method,
            }),
        }
    }

    /// [`Baked::frame_of`] with no bundle path in messages.
    ///
    /// # Errors
    /// As [`Baked::frame_of`].
    pub fn frame(
        &self,
        settings: &FrameSettings,
    ) -> Result<Box<dyn Frame + Sync + '_>, MethodError> {
        self.frame_of(settings, Path::new("<bake>"))
    }
}

/// What a report of a written bake needs, without its rows (a streamed merge never holds them
/// all): kind, record, sizes, settings and the method's description.
#[derive(Clone, Debug)]
pub struct BakeSummary {
    /// Its kind.
    pub kind: BakeKind,
    /// How it was baked (seconds: of this run's baking).
    pub record: store::BakeRecord,
    /// Vertices of the mesh.
    pub vertices: usize,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// The settings as recorded (JSON).
    pub settings_json: String,
    /// The method's own lines and JSON (`sg`'s fit statistics), if it has any.
    pub describe: Option<(Vec<String>, serde_json::Value)>,
}

impl BakeSummary {
    /// The summary of a bake in memory.
    pub fn of(b: &Baked) -> BakeSummary {
        BakeSummary {
            kind: b.kind(),
            record: b.record().clone(),
            vertices: b.scene().mesh.vertex_count(),
            triangles: b.scene().mesh.triangle_count(),
            settings_json: b.settings_json(),
            describe: b.describe(),
        }
    }
}

impl From<sh::ShBaked> for Baked {
    fn from(b: sh::ShBaked) -> Self {
        Baked::Sh(b)
    }
}

impl From<sg::SgBaked> for Baked {
    fn from(b: sg::SgBaked) -> Self {
        Baked::Sg(b)
    }
}

impl From<cuts::CutsBaked> for Baked {
    fn from(b: cuts::CutsBaked) -> Self {
        Baked::Cuts(b)
    }
}

impl From<vmf::VmfBaked> for Baked {
    fn from(b: vmf::VmfBaked) -> Self {
        Baked::Vmf(b)
    }
}

/// Read any bundle and check it: the right [`Baked`] arm for its `method` metadata.
///
/// # Errors
/// IO, checksum, layout or content errors naming `path`; an unknown method.
pub fn read_any(path: &Path) -> Result<Baked, MethodError> {
    from_bundle(&Bundle::read(path)?, path)
}

/// [`read_any`] of a bundle already in memory, read from `path`.
///
/// # Errors
/// As [`read_any`].
pub fn from_bundle(b: &Bundle, path: &Path) -> Result<Baked, MethodError> {
    let method = b.meta(path, "method")?;
    match method {
        "sh" => Ok(Baked::Sh(sh::Sh::load(b, path)?)),
        "sg" => Ok(Baked::Sg(sg::Sg::load(b, path)?)),
        "cuts" => Ok(Baked::Cuts(cuts::Cuts::load(b, path)?)),
        "vmf" => Ok(Baked::Vmf(vmf::Vmf::load(b, path)?)),
        m => Err(MethodError::invalid(
            path,
            format!("unknown bake method '{m}' (this relight reads sh, sg, cuts, vmf)"),
        )),
    }
}

/// Frame settings of every method. A closed set (one arm per [`MethodKind`]).
// One `FrameSettings` exists per frame (never in arrays): boxing the cuts arm (its material
// edits) would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum FrameSettings {
    /// `sh`.
    Sh(sh::ShFrameSettings),
    /// `hybrid`.
    Hybrid(hybrid::HybridSettings),
    /// `sg`.
    Sg(sg::SgFrameSettings),
    /// `cuts`.
    Cuts(cuts::CutsFrameSettings),
    /// `vmf`.
    Vmf(vmf::VmfFrameSettings),
}

impl FrameSettings {
    /// The method of these settings.
    pub fn method(&self) -> MethodKind {
        match self {
            FrameSettings::Sh(_) => MethodKind::Sh,
            FrameSettings::Hybrid(_) => MethodKind::Hybrid,
            FrameSettings::Sg(_) => MethodKind::Sg,
            FrameSettings::Cuts(_) => MethodKind::Cuts,
            FrameSettings::Vmf(_) => MethodKind::Vmf,
        }
    }

    /// The default settings of `method`.
    pub fn default_for(method: MethodKind) -> FrameSettings {
        match method {
            MethodKind::Sh => FrameSettings::Sh(Default::default()),
            MethodKind::Hybrid => FrameSettings::Hybrid(Default::default()),
            MethodKind::Sg => FrameSettings::Sg(Default::default()),
            MethodKind::Cuts => FrameSettings::Cuts(Default::default()),
            MethodKind::Vmf => FrameSettings::Vmf(Default::default()),
        }
    }
}

/// Per-frame options common to every method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameOptions {
    /// Samples per pixel along each axis (`n x n`, a box filter like Mitsuba's), `1..=16`.
    pub supersample: u32,
    /// Draw the environment behind the objects.
    pub background: bool,
}

impl Default for FrameOptions {
    /// 2 x 2 samples per pixel, no background.
    fn default() -> Self {
        FrameOptions {
            supersample: 2,
            background: false,
        }
    }
}

/// Where the time of a frame went, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrameTimes {
    /// Per-vertex work that depends on the camera (SG view blend; 0 for view-independent
    /// methods, whose per-vertex work is in [`Frame::set_environment`]).
    pub vertex_ms: f64,
    /// Rasterisation and per-pixel shading.
    pub pixel_ms: f64,
}

/// A rendered frame.
#[derive(Clone, Debug)]
pub struct FrameOutput {
    /// The linear-radiance image.
    pub image: Image,
    /// Where the time went.
    pub times: FrameTimes,
}

impl FrameOutput {
    /// The output of a frame with no per-vertex work, rasterised since `t0`.
    pub fn rasterised_since(image: Image, t0: std::time::Instant) -> FrameOutput {
        FrameOutput {
            image,
            times: FrameTimes {
                vertex_ms: 0.0,
                pixel_ms: ms_since(t0),
            },
        }
    }
}

/// Where the time of preparing an environment went, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PrepareTimes {
    /// Projection, decomposition or prefiltering of the environment (once per map).
    pub environment_ms: f64,
    /// Per-vertex shading and other view-independent work (once per map or rotation).
    pub shade_ms: f64,
}

/// A method's renderer over one bake: prepare an environment once, render any camera.
pub trait Frame {
    /// The method.
    fn method(&self) -> MethodKind;

    /// Prepare `env` (its map, rotation and scale): everything that does not depend on the
    /// camera. Must be called before [`Frame::render`].
    ///
    /// # Errors
    /// A method-specific failure to prepare (e.g. an environment the decomposition refuses).
    fn set_environment(&mut self, env: &Environment) -> Result<PrepareTimes, MethodError>;

    /// Render `camera` under the prepared environment.
    ///
    /// # Panics
    /// If no environment was set, or `opts.supersample` is 0 (checked by callers that take
    /// user input).
    fn render(&self, camera: &Camera, opts: &FrameOptions) -> FrameOutput;

    /// One line saying what was rendered (lights extracted, lobes, orders), for reports.
    fn summary(&self) -> String;
}

/// Most pixels of a rendered image: 2^26 (8192 x 8192; 768 MiB of linear RGB).
pub const MAX_IMAGE_PIXELS: u64 = 1 << 26;

/// Most rasteriser samples of a frame, pixels x supersample^2: 2^28 (about 8 GiB of
/// G-buffer at its ~32 bytes per sample).
pub const MAX_FRAME_SAMPLES: u64 = 1 << 28;

/// Check [`FrameOptions`] and the image size of `camera` from user input, before any
/// allocation.
///
/// # Errors
/// [`MethodError::Settings`] naming the option and the limit.
pub fn check_frame_options(o: &FrameOptions, camera: &Camera) -> Result<(), MethodError> {
    let err = |m: String| Err(MethodError::Settings(m));
    if !(1..=16).contains(&o.supersample) {
        return err(format!("supersample {} is not in 1..=16", o.supersample));
    }
    let pixels = camera.width as u64 * camera.height as u64;
    if pixels > MAX_IMAGE_PIXELS {
        return err(format!(
            "{} x {} pixels is more than the {MAX_IMAGE_PIXELS} (8192 x 8192) a frame may have",
            camera.width, camera.height
        ));
    }
    let samples = pixels * (o.supersample as u64).pow(2);
    if samples > MAX_FRAME_SAMPLES {
        return err(format!(
            "{} x {} pixels x {}^2 samples per pixel is more than the {MAX_FRAME_SAMPLES} samples a frame may have: lower the size or --supersample",
            camera.width, camera.height, o.supersample
        ));
    }
    Ok(())
}

/// Milliseconds since `t`.
pub(crate) fn ms_since(t: std::time::Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Build the ray caster of `input` with `ctx`'s back-end.
pub(crate) fn build_caster(
    input: &BakeInput,
    ctx: &BakeContext,
) -> Result<Box<dyn relight_scene::accel::RayCaster>, MethodError> {
    relight_scene::accel::build(&input.scene.mesh, ctx.backend).map_err(|e| MethodError::Caster {
        path: input.origin.to_path_buf(),
        message: e.to_string(),
    })
}
