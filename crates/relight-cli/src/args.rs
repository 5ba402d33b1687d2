//! Parsing shared by the subcommands (camera, window, tone map, back-end, environment
//! overrides), the checks of output paths before any work, and `--json` printing.

use anyhow::{bail, ensure, Context, Result};
use clap::parser::ValueSource;
use clap::ArgMatches;
use relight_render::tonemap::ToneMap;
use relight_scene::accel::Backend;
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use relight_scene::scene_file::{self, model, parse_layout, EnvDesc, SceneDesc};
use relight_sphere::sh::Window;
use std::path::{Path, PathBuf};

/// Parse a tone map (`relight_render::tonemap::ToneMap`'s `FromStr`).
pub fn tonemap(s: &str) -> Result<ToneMap> {
    Ok(s.parse()?)
}

/// The tone map of PNG outputs: `--tonemap` if given, else the automatic exposure of `img`
/// ([`relight_render::tonemap::ToneMap::auto`]), printed when a PNG is written.
pub fn png_tonemap(
    given: Option<&str>,
    img: &relight_render::Image,
    outs: &[PathBuf],
    out: &Out,
) -> Result<ToneMap> {
    if let Some(s) = given {
        return tonemap(s);
    }
    let auto = relight_render::tonemap::AutoExposure::of(img);
    let png =
        |p: &PathBuf| relight_render::ImageFormat::of(p) == Some(relight_render::ImageFormat::Png);
    if outs.iter().any(png) {
        out.line(format!("tone map: {auto}; --tonemap overrides"));
    }
    Ok(auto.tonemap)
}

/// Parse an SH window (`relight_sphere::sh::Window`'s `FromStr`).
pub fn window(s: &str) -> Result<Window> {
    s.parse().context("--window")
}

/// Parse a ray-casting back-end name (`None`: the fastest available).
pub fn backend(s: Option<&str>) -> Result<Backend> {
    let b = match s {
        None => return Ok(Backend::available()[0]),
        Some("embree") => Backend::Embree,
        Some("bvh") => Backend::Bvh,
        Some(o) => bail!("unknown --backend '{o}' (embree, bvh)"),
    };
    ensure!(
        Backend::available().contains(&b),
        "--backend {} is not in this build (built without the `embree` feature)",
        s.unwrap_or_default()
    );
    Ok(b)
}

/// Parse `x,y,z` (finite numbers).
pub fn vec3(s: &str, flag: &str) -> Result<[f32; 3]> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{flag} '{s}' is not three numbers x,y,z"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => bail!("{flag} '{s}' is not three finite numbers x,y,z"),
    }
}

/// Parse `ox,oy,oz/tx,ty,tz[/fov]` over a base camera.
pub fn camera(s: &str, base: &Camera) -> Result<Camera> {
    let parts: Vec<&str> = s.split('/').collect();
    ensure!(
        (2..=3).contains(&parts.len()),
        "--camera '{s}': expected ox,oy,oz/tx,ty,tz[/fov]"
    );
    let mut c = *base;
    c.origin = vec3(parts[0], "--camera origin")?;
    c.target = vec3(parts[1], "--camera target")?;
    c.up = [0.0, 1.0, 0.0];
    if let Some(f) = parts.get(2) {
        c.fov_deg = f
            .trim()
            .parse()
            .with_context(|| format!("--camera '{s}': fov '{f}' is not a number"))?;
    }
    Ok(c)
}

/// Parse a list of SH orders: `5`, `3,4,6`, `2-10`.
pub fn orders(s: &str) -> Result<Vec<usize>> {
    let mut out = Vec::new();
    for part in s.split(',') {
        let num = |x: &str| -> Result<usize> {
            x.trim()
                .parse()
                .with_context(|| format!("--sh-orders '{s}': '{x}' is not an order"))
        };
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (num(a)?, num(b)?);
                ensure!(a <= b, "--sh-orders '{s}': range {a}-{b} is empty");
                out.extend(a..=b);
            }
            None => out.push(num(part)?),
        }
    }
    let max = relight_sphere::sh::MAX_ORDER;
    ensure!(
        out.iter().all(|o| (1..=max).contains(o)),
        "--sh-orders '{s}': orders must be in 1..={max}"
    );
    Ok(out)
}

/// How scene files, model files and the models they name are read.
#[derive(clap::Args, Clone, Debug)]
pub struct SceneArgs {
    /// Let references inside a model (glTF buffer and image URIs, OBJ mtllib) lead outside
    /// the model's folder (absolute paths, `..`, symlinks out of it): refused by default.
    #[arg(long)]
    pub allow_outside_paths: bool,
    /// Most triangles a mesh file, and the whole scene, may have (counted before expanding
    /// glTF instancing or generating shapes).
    #[arg(long, default_value_t = relight_scene::io::files::DEFAULT_MAX_TRIANGLES)]
    pub max_triangles: usize,
    /// The light: an environment map (.hdr / .exr, layout detected from the aspect ratio)
    /// or `sky` (the procedural sun and sky). Default for a model file: the sky; for a scene
    /// description: its own environment, which this replaces.
    #[arg(long, value_name = "ENV.hdr|ENV.exr|sky")]
    pub env: Option<PathBuf>,
    /// Add a grey ground plane under a model file (8 bounding radii on a side, touching the
    /// model's lowest point).
    #[arg(long)]
    pub ground: bool,
}

impl SceneArgs {
    /// Read and build the scene at `path`: a scene description (JSON), or a model file
    /// (`.glb`, `.gltf`, `.obj`, `.ply`) made into a scene by
    /// [`SceneDesc::for_model`]'s rule, which is printed.
    pub fn load(&self, path: &Path) -> Result<(SceneDesc, relight_scene::scene::Scene)> {
        let opts = relight_scene::io::LoadOptions {
            paths: relight_scene::io::PathPolicy {
                allow_outside: self.allow_outside_paths,
            },
            max_triangles: self.max_triangles,
        };
        let env = self.env.as_deref().map(env_desc).transpose()?;
        let desc = if model::is_model(path) {
            let (desc, why) = SceneDesc::for_model(path, env, self.ground, &opts)?;
            let c = &desc.camera;
            eprintln!(
                "model {}: camera {} ({}x{}); light: {}{}",
                path.display(),
                why.camera,
                c.width,
                c.height,
                why.environment,
                if self.env.is_none() {
                    " (--env chooses an .hdr/.exr)"
                } else {
                    ""
                },
            );
            desc
        } else {
            ensure!(
                !self.ground,
                "--ground adds a plane under a model file (.glb, .gltf, .obj, .ply); {} is a scene description: add a \"plane\" shape to it",
                path.display()
            );
            let mut desc = SceneDesc::read(path)?;
            if let Some(env) = env {
                desc.environment = env;
            }
            desc
        };
        let scene = desc.build_with(path, &opts)?;
        Ok((desc, scene))
    }
}

/// `--env`'s environment: `sky` is [`model::default_sky`], anything else a map file
/// (absolute when it exists, so a bundle finds it from any folder).
fn env_desc(p: &Path) -> Result<EnvDesc> {
    if p == Path::new("sky") {
        return Ok(model::default_sky());
    }
    ensure!(
        p.is_file(),
        "--env {}: no such file (an .hdr or .exr environment map, or `sky`)",
        p.display()
    );
    Ok(EnvDesc::File {
        path: p.canonicalize().unwrap_or_else(|_| p.to_path_buf()),
        layout: None,
        scale: None,
        rotate_y_deg: None,
    })
}

/// Options that choose an environment map and how it is placed.
#[derive(clap::Args, Clone, Debug)]
pub struct EnvArgs {
    /// Environment map (.hdr/.exr: latlong, vertical cross or angular probe; default: the
    /// baked scene's environment).
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Layout of --env (latlong, cube, probe); detected from the aspect ratio when absent.
    #[arg(long)]
    pub layout: Option<String>,
    /// Rotate the environment about +Y by this many degrees (Mitsuba `to_world` rotate).
    #[arg(long, alias = "rotate-y", allow_negative_numbers = true)]
    pub rotate_env: Option<f32>,
    /// Multiply the environment's radiance (a finite number >= 0).
    #[arg(long, allow_negative_numbers = true)]
    pub env_scale: Option<f32>,
}

impl EnvArgs {
    /// The environment: `--env` or the scene's, with the rotation and scale overrides.
    pub fn build(&self, scene: &SceneDesc, bundle: &Path) -> Result<Environment> {
        if let Some(r) = self.rotate_env {
            ensure!(r.is_finite(), "--rotate-env {r} is not a finite angle");
        }
        if let Some(s) = self.env_scale {
            ensure!(
                s.is_finite() && s >= 0.0,
                "--env-scale {s} is not a finite number >= 0"
            );
        }
        let lay = layout(self.layout.as_deref())?;
        let mut env = match &self.env {
            Some(p) => Environment::new(relight_scene::io::load_env(p, lay)?),
            None => scene_file::build_env(&scene.environment).with_context(|| {
                let b = bundle.display();
                format!("{b}: loading the baked scene's environment (pass --env to use another)")
            })?,
        };
        if let Some(r) = self.rotate_env {
            env.rotate_y_deg = r;
        }
        if let Some(s) = self.env_scale {
            env.scale = s;
        }
        Ok(env)
    }
}

/// The environment layout option of `render`, `project` and `decompose`.
pub fn layout(s: Option<&str>) -> Result<Option<relight_sphere::envmap::EnvLayout>> {
    s.map(|l| {
        parse_layout(l).with_context(|| format!("unknown --layout '{l}' (latlong, cube, probe)"))
    })
    .transpose()
}

/// The image extensions relight writes.
pub const IMAGE_EXTS: [&str; 3] = ["exr", "hdr", "png"];

/// Check image outputs before any work (`relight_bundle::output::check_outputs`).
pub fn check_image_outputs(outs: &[PathBuf], inputs: &[&Path]) -> Result<()> {
    let outs: Vec<&Path> = outs.iter().map(PathBuf::as_path).collect();
    Ok(relight_bundle::output::check_outputs(
        &outs,
        &IMAGE_EXTS,
        inputs,
    )?)
}

/// The arguments of a clap `Args` struct: (id, long name).
pub fn arg_names<T: clap::Args>() -> Vec<(String, String)> {
    T::augment_args(clap::Command::new("x"))
        .get_arguments()
        .filter_map(|a| Some((a.get_id().to_string(), a.get_long()?.to_string())))
        .collect()
}

/// Named arguments: `(id, long name)`.
pub type ArgNames = Vec<(String, String)>;

/// Refuse options given on the command line that do not apply to `method`: `groups` lists,
/// per set of methods, the arguments only they take.
pub fn refuse_foreign<K: clap::ValueEnum + PartialEq + Copy>(
    m: &ArgMatches,
    method: K,
    groups: &[(&[K], ArgNames)],
) -> Result<()> {
    let name = |k: K| {
        k.to_possible_value()
            .map_or_else(String::new, |v| v.get_name().to_string())
    };
    for (methods, args) in groups {
        if methods.contains(&method) {
            continue;
        }
        for (id, long) in args {
            if given(m, id) {
                let names: Vec<String> = methods.iter().map(|&k| name(k)).collect();
                bail!(
                    "--{long} applies to --method {}, not to --method {}",
                    names.join(" or "),
                    name(method)
                );
            }
        }
    }
    Ok(())
}

/// `(id, long)` of named arguments.
pub fn named(ids: &[&str]) -> Vec<(String, String)> {
    ids.iter()
        .map(|id| (id.to_string(), id.replace('_', "-")))
        .collect()
}

/// Whether the argument `id` was given on the command line.
pub fn given(m: &ArgMatches, id: &str) -> bool {
    m.try_get_raw(id).is_ok() && m.value_source(id) == Some(ValueSource::CommandLine)
}

/// Whether any of the `sg` lobe options (kernel, domain, order, shape) was given: without
/// them `bake` and `eval` choose the lobes by the scene's materials
/// (`relight_bake::sg::LobeSetting::for_materials`).
pub fn sg_lobes_given(m: &ArgMatches) -> bool {
    ["lobe_kernel", "lobe_domain", "lobe_order", "lobe_shape"]
        .iter()
        .any(|id| given(m, id))
}

/// Human lines or one JSON summary on stdout.
pub struct Out {
    /// Print JSON instead of text.
    pub json: bool,
}

impl Out {
    /// A line of the human report (nothing in JSON mode).
    pub fn line(&self, s: impl AsRef<str>) {
        if !self.json {
            println!("{}", s.as_ref());
        }
    }

    /// The JSON summary (nothing in human mode).
    pub fn summary(&self, v: serde_json::Value) {
        if self.json {
            println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        }
    }
}

/// A file's size in MiB (0 if it cannot be read).
pub fn mib(path: &Path) -> f64 {
    std::fs::metadata(path).map_or(0.0, |m| m.len() as f64 / (1 << 20) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_parse_or_are_refused() {
        assert_eq!(orders("2-4,7").unwrap(), vec![2, 3, 4, 7]);
        assert!(orders("4-2").is_err() && orders("0").is_err() && orders("x").is_err());
        assert!(vec3("1,2", "--a").is_err() && vec3("1,2,inf", "--a").is_err());
        let base = Camera::look_at([0.0; 3], [0.0, 0.0, -1.0], 45.0, 8, 8);
        let c = camera("0,1,2/0,0,0/30", &base).unwrap();
        assert_eq!((c.origin, c.fov_deg), ([0.0, 1.0, 2.0], 30.0));
    }
}
