//! The `sg` method in the CLI (Green 2005 view-dependent glossy PRT): `relight bake --method
//! sg` options and driver, and the frame of `relight render --method sg`.

use crate::store::{SgBundle, SgRecordedSettings};
use anyhow::{anyhow, bail, Context, Result};
use glam::Vec3;
use relight_bake::sg::{self, SgBakeSettings, SgFitSettings, VIEW_FREQUENCY};
use relight_render::raster::RasterOptions;
use relight_render::shade_sg::{SgLighting, SgRenderer, SgTimes};
use relight_render::Image;
use relight_scene::accel::{self, Backend};
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::scene::{Environment, Scene};
use relight_scene::scene_file::SceneDesc;
use std::path::Path;
use std::time::Instant;

/// Options of `relight bake --method sg` (defaults: `SgBakeSettings::default()`, the thesis'
/// section 3.1 settings). `--seed`, `--f16`, `--backend` and `--threads` are shared with `sh`.
#[derive(clap::Args, Clone, Debug)]
#[command(next_help_heading = "SG bake (--method sg)")]
pub struct SgBakeOpts {
    /// Face size of the direct-glossy cube map per view (6 x N x N texels).
    #[arg(long, default_value_t = SgBakeSettings::default().direct_res)]
    pub direct_res: usize,
    /// Face size of the indirect-glossy cube map per view.
    #[arg(long, default_value_t = SgBakeSettings::default().indirect_res)]
    pub indirect_res: usize,
    /// Indirect paths per (vertex, view).
    #[arg(long, default_value_t = SgBakeSettings::default().indirect_paths)]
    pub indirect_paths: u32,
    /// Bounces of an indirect path after leaving the vertex.
    #[arg(long, default_value_t = SgBakeSettings::default().max_depth)]
    pub max_depth: u32,
    /// SH order of the view-independent diffuse part.
    #[arg(long, default_value_t = SgBakeSettings::default().diffuse_order)]
    pub diffuse_order: usize,
    /// Views below this elevation over the shading horizon (degrees) are clamped to it.
    #[arg(long, default_value_t = SgBakeSettings::default().horizon_deg, allow_hyphen_values = true)]
    pub horizon_deg: f32,
    /// Keep the least-squares amplitudes instead of rescaling each fit to the data's integral.
    #[arg(long)]
    pub no_energy: bool,
    /// Ignore visibility: bake the transport of prefiltered environment mapping (no
    /// shadowing), the baseline of Green 2005's Fig. 3-5.
    #[arg(long)]
    pub no_visibility: bool,
    /// Gaussians per (vertex, view) for direct glossy transport, 1..=10.
    #[arg(long, default_value_t = SgBakeSettings::default().direct_lobes)]
    pub direct_lobes: usize,
    /// Gaussians per (vertex, view) for indirect glossy transport, 0..=10 (0: none).
    #[arg(long, default_value_t = SgBakeSettings::default().indirect_lobes)]
    pub indirect_lobes: usize,
    /// Levenberg-Marquardt iterations per (vertex, view) fit.
    #[arg(long, default_value_t = SgFitSettings::default().max_iterations)]
    pub fit_iterations: usize,
    /// Weight of the mean-alignment term across neighbouring views (eq. 2.4).
    #[arg(long, default_value_t = SgFitSettings::default().mean_weight)]
    pub mean_weight: f64,
    /// Weight of the width-alignment term across neighbouring views (eq. 2.5).
    #[arg(long, default_value_t = SgFitSettings::default().width_weight)]
    pub width_weight: f64,
    /// Weight of the spatial arrangement term across processed neighbours (eq. 2.6).
    #[arg(long, default_value_t = SgFitSettings::default().spatial_weight)]
    pub spatial_weight: f64,
    /// Relaxation sweeps after the flood fill (the paper's future work; each sweep re-fits
    /// the vertices on flipped edges with priors from all their neighbours).
    #[arg(long, default_value_t = SgFitSettings::default().relax_sweeps)]
    pub relax_sweeps: usize,
    /// Independent flood-fill regions (units of parallel work); 0 = automatic.
    #[arg(long, default_value_t = SgFitSettings::default().regions)]
    pub regions: usize,
    /// Blend the scene's material into this one across the mesh (spatially varying BRDF,
    /// thesis 2.3.1): a material as JSON (e.g. '{"type": "ggx_plastic", "diffuse": [0.1, 0.6,
    /// 0.1], "specular": [1, 1, 1], "alpha": 0.05, "ior": 1.5}') or a .json file holding one.
    #[arg(long, value_name = "MATERIAL_JSON")]
    pub blend_to: Option<String>,
    /// Axis of the blend, x,y,z: the scene's material at the lowest vertex along it, the
    /// --blend-to material at the highest.
    #[arg(long, default_value = "0,1,0", allow_hyphen_values = true)]
    pub blend_axis: String,
}

impl SgBakeOpts {
    /// The bake settings these options give.
    pub fn settings(&self, seed: u64) -> SgBakeSettings {
        SgBakeSettings {
            direct_res: self.direct_res,
            indirect_res: self.indirect_res,
            indirect_paths: self.indirect_paths,
            max_depth: self.max_depth,
            diffuse_order: self.diffuse_order,
            horizon_deg: self.horizon_deg,
            visibility: !self.no_visibility,
            direct_lobes: self.direct_lobes,
            indirect_lobes: self.indirect_lobes,
            fit: SgFitSettings {
                max_iterations: self.fit_iterations,
                mean_weight: self.mean_weight,
                width_weight: self.width_weight,
                spatial_weight: self.spatial_weight,
                relax_sweeps: self.relax_sweeps,
                regions: self.regions,
                energy: !self.no_energy,
            },
            seed,
            threads: None,
            progress: true,
        }
    }
}

/// Parse `x,y,z`.
fn parse_vec3(s: &str, flag: &str) -> Result<Vec3> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{flag} '{s}' is not three numbers x,y,z"))?;
    match v[..] {
        [x, y, z] => Ok(Vec3::new(x, y, z)),
        _ => bail!("{flag} '{s}' is not three numbers x,y,z"),
    }
}

/// A material given inline as JSON or as a .json file.
fn parse_material(s: &str) -> Result<Material> {
    let (text, origin) = if s.trim_start().starts_with('{') {
        (s.to_string(), "--blend-to".to_string())
    } else {
        let text = std::fs::read_to_string(s).with_context(|| {
            format!("--blend-to {s}: not inline JSON, and cannot read it as a file")
        })?;
        (text, s.to_string())
    };
    let m: Material =
        serde_json::from_str(&text).with_context(|| format!("{origin}: not a valid material"))?;
    m.validate().map_err(|e| anyhow!("{origin}: {e}"))?;
    Ok(m)
}

/// Per-vertex materials of a `--blend-to` bake (`None` without one).
fn blend(scene: &Scene, o: &SgBakeOpts) -> Result<Option<(Vec<Material>, String)>> {
    let Some(to) = &o.blend_to else {
        return Ok(None);
    };
    let b = parse_material(to)?;
    let axis = parse_vec3(&o.blend_axis, "--blend-axis")?;
    let used: Vec<u32> = {
        let mut ids = scene.mesh.material_ids.clone();
        ids.sort_unstable();
        ids.dedup();
        ids
    };
    let [only] = used[..] else {
        bail!(
            "--blend-to needs a scene with one material (this one uses {})",
            used.len()
        );
    };
    let a = scene.materials[only as usize];
    let v = sg::transport::blend_along_axis(&scene.mesh, &a, &b, axis)
        .map_err(|e| anyhow!("--blend-to: {e}"))?;
    Ok(Some((v, format!("{to} along {}", o.blend_axis))))
}

/// Bake a loaded scene with the SG method.
pub fn bake_scene(
    desc: &SceneDesc,
    scene: &Scene,
    opts: &SgBakeOpts,
    seed: u64,
    backend: Backend,
    f16: bool,
    origin: &Path,
) -> Result<SgBundle> {
    let settings = opts.settings(seed);
    settings.validate()?;
    let blended = blend(scene, opts)?;
    let t0 = Instant::now();
    let caster = accel::build(&scene.mesh, backend)
        .map_err(|e| anyhow!("{}: cannot build the ray caster: {e}", origin.display()))?;
    let bake = sg::bake(
        &scene.mesh,
        &scene.materials,
        blended.as_ref().map(|b| &b.0[..]),
        caster.as_ref(),
        &settings,
    )
    .with_context(|| format!("baking {}", origin.display()))?;
    let mut rec = SgRecordedSettings::new(&settings, bake.view_frequency);
    rec.blend = blended.map(|b| b.1);
    rec.f16 = f16;
    rec.backend = caster.name().into();
    rec.seconds = t0.elapsed().as_secs_f64();
    Ok(SgBundle {
        scene: desc.clone(),
        mesh: scene.mesh.clone(),
        materials: scene.materials.clone(),
        bake,
        settings: rec,
    })
}

/// `relight bake --method sg`: bake, write, print a summary with the bytes per vertex.
pub fn run_bake(a: &crate::bake::Args) -> Result<()> {
    let desc = SceneDesc::read(&a.scene)?;
    let scene = desc.build(&a.scene)?;
    let o = &a.sg;
    o.settings(a.seed).validate()?;
    eprintln!(
        "baking {} ({} vertices, {} triangles): SG, {} views, {} direct + {} indirect lobes, cube maps 6x{}x{} / 6x{}x{}, diffuse SH order {}",
        a.scene.display(),
        scene.mesh.vertex_count(),
        scene.mesh.triangle_count(),
        10 * VIEW_FREQUENCY * VIEW_FREQUENCY + 2,
        o.direct_lobes,
        o.indirect_lobes,
        o.direct_res,
        o.direct_res,
        o.indirect_res,
        o.indirect_res,
        o.diffuse_order
    );
    let backend = crate::bake::parse_backend(a.backend.as_deref())?;
    let baked = bake_scene(&desc, &scene, o, a.seed, backend, a.f16, &a.scene)?;
    baked.to_bundle()?.write(&a.out)?;
    let size = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    let v = baked.mesh.vertex_count().max(1);
    let s = &baked.bake.stats;
    println!(
        "wrote {} ({:.2} MiB, {} bytes per vertex in the file, {} of them transfer as {}) in {:.2} s with {}",
        a.out.display(),
        size as f64 / (1 << 20) as f64,
        size as usize / v,
        baked.transfer_bytes_per_vertex(),
        if a.f16 { "f16" } else { "f32" },
        baked.settings.seconds,
        baked.settings.backend
    );
    println!(
        "fit: mean relative L2 error {:.4} direct, {:.4} indirect; {} LM iterations; flips {} -> {} after relaxation",
        s.mean_relative_error[0],
        s.mean_relative_error[1],
        s.iterations,
        s.flips,
        s.flips_after_relaxation
    );
    Ok(())
}

/// Options of `relight render --method sg`.
#[derive(clap::Args, Clone, Debug)]
#[command(next_help_heading = "SG render (--method sg)")]
pub struct SgRenderOpts {
    /// Face size of the finest level of the Gaussian-prefiltered cube chain (a power of two;
    /// levels halve down to 1 texel).
    #[arg(long, default_value_t = 128)]
    pub prefilter_size: usize,
}

/// Times of one `render --method sg` frame.
pub struct SgRenderTimes {
    /// Prefiltering and SH projection (once per environment map).
    pub prefilter_ms: f64,
    /// The frame.
    pub frame: SgTimes,
}

/// Render an `sg` bundle under `env` from `camera`.
pub fn relight_sg(
    b: &SgBundle,
    env: &Environment,
    camera: &Camera,
    o: &SgRenderOpts,
    supersample: u32,
    background: bool,
) -> Result<(Image, SgRenderTimes)> {
    if !o.prefilter_size.is_power_of_two() || o.prefilter_size > 1024 {
        bail!(
            "--prefilter-size {} is not a power of two up to 1024",
            o.prefilter_size
        );
    }
    let t0 = Instant::now();
    let lighting = SgLighting::new(env, b.bake.diffuse.order, o.prefilter_size);
    let prefilter_ms = t0.elapsed().as_secs_f64() * 1e3;
    let r = SgRenderer::new(&b.mesh, &b.bake);
    let (img, frame) = r.render(
        &lighting,
        camera,
        background.then_some(env),
        &RasterOptions { supersample },
    );
    Ok((
        img.image,
        SgRenderTimes {
            prefilter_ms,
            frame,
        },
    ))
}
