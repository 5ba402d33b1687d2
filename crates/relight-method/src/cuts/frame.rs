//! The `cuts` frame: the environment's light samples, illumination cut and the vertex cuts
//! merged with it (once per map or rotation), then per camera the per-pixel sums of
//! `relight_render::shade_cuts`. Over a
//! bake of surface samples: the point light's lighting of the samples and its light cut
//! (once per light position, [`CutsFrame::set_point_light`]), then per camera the direct
//! light and one bounce of `relight_render::shade_local`.

use super::local::{LocalTerms, PointLightArgs};
use super::CutsBaked;
use crate::{ms_since, Frame, FrameOptions, FrameOutput, MethodError, MethodKind, PrepareTimes};
use relight_bake::cuts::light_cut::{LightCut, DEFAULT_LIGHT_SIGMA};
use relight_bake::cuts::samples::{sample_power_with, NearestSample};
use relight_render::light::PointLight;
use relight_render::raster::RasterOptions;
use relight_render::shade_cuts::CutsShader;
use relight_render::shade_local::{LocalLighting, LocalShader};
use relight_scene::accel::RayCaster;
use relight_scene::camera::Camera;
use relight_scene::error::SceneError;
use relight_scene::io::PathPolicy;
use relight_scene::material::maps::{MaterialDesc, MaterialMaps, SceneMaps};
use relight_scene::material::Material;
use relight_scene::scene::Environment;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// A material that replaces the scene's at render time (`--material`): the constant material
/// with optional maps ([`MaterialDesc`]), and the JSON file it came from, against whose
/// folder relative map paths are resolved (and which they may not leave unless
/// [`CutsFrameSettings::material_allow_outside_paths`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialOverride {
    /// The material and the maps it names.
    pub desc: MaterialDesc,
    /// The file the material was read from (inline JSON: `./<inline material>`, so maps
    /// resolve against the working folder).
    pub origin: PathBuf,
}

impl From<relight_scene::material::Material> for MaterialOverride {
    fn from(m: relight_scene::material::Material) -> Self {
        MaterialOverride {
            desc: m.into(),
            origin: PathBuf::from("./<inline material>"),
        }
    }
}

/// The maps a material of `--material` names, read from its file's folder (`None`: none).
///
/// # Errors
/// [`MethodError::Settings`] naming the file and the problem (with the hint of
/// `--material-allow-outside-paths` for a map outside the folder).
pub(crate) fn load_override_maps(
    o: &MaterialOverride,
    allow_outside: bool,
) -> Result<Option<MaterialMaps>, MethodError> {
    let Some(d) = &o.desc.maps else {
        return Ok(None);
    };
    let policy = PathPolicy { allow_outside };
    MaterialMaps::load(d, &o.desc.material, &o.origin, &policy)
        .map(Some)
        .map_err(|e| {
            let hint = match e {
                SceneError::OutsideFolder { .. } => {
                    " (for the maps of --material: --material-allow-outside-paths)"
                }
                _ => "",
            };
            MethodError::Settings(format!("--material: {e}{hint}"))
        })
}

/// Settings of the `cuts` frame.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(
    feature = "cli",
    command(next_help_heading = "Cuts render (--method cuts)")
)]
pub struct CutsFrameSettings {
    /// Nodes of the illumination cut (the paper's budgets: 128, 256, 512), at least 1.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = CutsFrameSettings::default().light_cut))]
    pub light_cut: usize,
    /// `sigma` of the illumination cut's error phase, in units of the mean light (>= 0).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_LIGHT_SIGMA))]
    pub light_sigma: f32,
    /// Render every surface with this material instead of the scene's (and its maps, which
    /// the bundle holds; nothing of the materials is baked). Set from the command line's
    /// `--material` by [`super::apply_material_edits`].
    #[cfg_attr(feature = "cli", arg(skip))]
    pub material: Option<MaterialOverride>,
    /// Replace the materials after the bake (nothing of the materials is baked): a bare
    /// MATERIAL for every surface, or NAME=MATERIAL (repeatable) for the object NAME alone
    /// (`relight info` lists the names), the others keeping theirs. MATERIAL is a material as
    /// JSON (e.g. '{"type": "ggx_conductor", "specular": [0.9, 0.6, 0.3], "alpha": 0.1}') or
    /// a .json file holding one. It may name texture and normal maps ("maps": {"diffuse":
    /// "albedo.png", "normal": "n.png"}, paths relative to the file's folder, which they may
    /// not leave); the bake's mesh needs texture coordinates then.
    #[cfg_attr(feature = "cli", arg(long = "material", value_name = "[NAME=]MATERIAL_JSON", value_parser = super::parse_material_edit))]
    pub materials: Vec<super::MaterialEdit>,
    /// Let the maps of `--material` lead outside the material file's folder (absolute paths,
    /// `..`, symbolic links out of it).
    #[cfg_attr(feature = "cli", arg(long))]
    pub material_allow_outside_paths: bool,
    /// Average each BRDF's glossy lobe over the spread of every merged cluster's lights (five
    /// evaluations per wide cluster; the default; diffuse lobes stay at the cluster's
    /// direction, `LightCut::spread_lobes`) instead of evaluating it at the cluster's
    /// direction alone (`--cluster-spread false`: faster; measured farther from the
    /// reference on the bunny, teapot and dragon).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = true, action = clap::ArgAction::Set, num_args = 0..=1, default_missing_value = "true"))]
    pub cluster_spread: bool,
    /// The point or spot light of a bake of surface samples.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub light: PointLightArgs,
    /// Terms of local lighting: all, direct (the light alone) or indirect (one bounce).
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = LocalTerms::All))]
    pub local_terms: LocalTerms,
}

impl Default for CutsFrameSettings {
    /// 256 nodes, sigma 2, the scene's materials.
    fn default() -> Self {
        CutsFrameSettings {
            light_cut: 256,
            light_sigma: DEFAULT_LIGHT_SIGMA,
            material: None,
            materials: Vec::new(),
            material_allow_outside_paths: false,
            cluster_spread: true,
            light: PointLightArgs::default(),
            local_terms: LocalTerms::All,
        }
    }
}

/// The `cuts` frame over a bake.
pub struct CutsFrame<'a> {
    baked: &'a CutsBaked,
    shader: CutsShader<'a>,
    settings: CutsFrameSettings,
    lighting: Option<(LightCut, Environment)>,
    /// The light cut of each new environment, from the samples' grid kept across them.
    light_cut: EnvLightCut,
    /// Over a bake of surface samples: the shadow-ray caster, the light, its lighting.
    local: Option<LocalState>,
}

/// The local-lighting part of a [`CutsFrame`].
struct LocalState {
    caster: Box<dyn RayCaster>,
    materials: Vec<Material>,
    maps: SceneMaps,
    light: PointLight,
    lighting: Option<LocalLighting>,
}

impl<'a> CutsFrame<'a> {
    /// A frame over `baked` (a whole bake).
    ///
    /// # Errors
    /// [`MethodError::Settings`] for a light cut of 0 nodes, a bad sigma, an invalid
    /// material, or maps that cannot be read (the message names the file and the problem) or
    /// applied (a mesh without texture coordinates).
    pub fn new(baked: &'a CutsBaked, s: &CutsFrameSettings) -> Result<Self, MethodError> {
        let n = baked.scene.materials.len();
        if !s.materials.is_empty() {
            return Err(MethodError::Settings(
                "--material edits are applied to the bake before its frame (cuts::apply_material_edits)".into(),
            ));
        }
        let (materials, maps) = match &s.material {
            Some(o) => {
                let m = o.desc.material;
                m.validate()
                    .map_err(|e| MethodError::Settings(format!("material {m:?}: {e}")))?;
                let maps = match load_override_maps(o, s.material_allow_outside_paths)? {
                    None => SceneMaps::default(),
                    Some(loaded) => SceneMaps::new(
                        &baked.scene.mesh,
                        vec![Some(Arc::new(loaded)); n],
                    )
                    .map_err(|e| {
                        MethodError::Settings(format!("--material {}: {e}", o.origin.display()))
                    })?,
                };
                (vec![m; n], maps)
            }
            None => (baked.scene.materials.clone(), baked.scene.maps.clone()),
        };
        if s.light_cut == 0 || !(s.light_sigma.is_finite() && s.light_sigma >= 0.0) {
            return Err(MethodError::Settings(format!(
                "light cut of {} nodes with sigma {} (need >= 1 node and sigma >= 0)",
                s.light_cut, s.light_sigma
            )));
        }
        let local = match (s.light.light()?, baked.bake.surface.is_some()) {
            (None, false) => None,
            (Some(_), false) => {
                return Err(MethodError::Settings(
                    "--point-light needs a bake of surface samples (relight bake --method cuts --cut-samples surface); this bundle holds environment directions, lit with --env"
                        .into(),
                ))
            }
            (None, true) => {
                return Err(MethodError::Settings(
                    "this bundle holds surface samples (local lights): give --point-light x,y,z and --light-intensity r,g,b (the environment does not light it)"
                        .into(),
                ))
            }
            (Some(light), true) => {
                let caster = relight_scene::accel::build_default(&baked.scene.mesh);
                Some(LocalState {
                    caster,
                    materials: materials.clone(),
                    maps: maps.clone(),
                    light,
                    lighting: None,
                })
            }
        };
        Ok(CutsFrame {
            baked,
            shader: CutsShader::new(
                &baked.scene.mesh,
                materials,
                &baked.bake,
                baked.settings.function,
            )
            .with_maps(maps)
            .with_cluster_spread(s.cluster_spread),
            settings: s.clone(),
            lighting: None,
            light_cut: EnvLightCut::default(),
            local,
        })
    }

    /// Move the point light of a bake of surface samples: its lighting of the samples and
    /// its light cut are recomputed (before the next [`Frame::render`]).
    ///
    /// # Errors
    /// [`MethodError::Settings`] for a bundle of environment directions, a bad light or
    /// one inside geometry.
    pub fn set_point_light(&mut self, light: PointLight) -> Result<PrepareTimes, MethodError> {
        let baked = self.baked;
        let (light_sigma, light_cut) = (self.settings.light_sigma, self.settings.light_cut);
        let Some(state) = self.local.as_mut() else {
            return Err(MethodError::Settings(
                "a point light needs a bake of surface samples (--cut-samples surface)".into(),
            ));
        };
        let shader = LocalShader::new(
            &baked.scene.mesh,
            state.materials.clone(),
            &baked.bake,
            baked.settings.function,
            state.caster.as_ref(),
        )
        .map_err(|e| MethodError::Settings(e.to_string()))?
        .with_maps(state.maps.clone());
        let lighting = shader
            .prepare(light, light_sigma, light_cut)
            .map_err(MethodError::Settings)?;
        let times = PrepareTimes {
            environment_ms: lighting.sample_ms,
            shade_ms: lighting.cut_ms,
        };
        state.light = lighting.light;
        state.lighting = Some(lighting);
        Ok(times)
    }
}

/// The light cut of a bake under an environment (sec. 3.2, 4.2), as the CPU frame and the GPU
/// frame (`relight_gpu`) build it: the light samples' power, then the cut. The samples'
/// nearest-sample grid is built at the first environment and kept, so every later
/// environment or rotation costs the texels' pass alone (`sample_power_with`).
#[derive(Default)]
pub struct EnvLightCut {
    grid: Option<NearestSample>,
}

impl EnvLightCut {
    /// The light cut of `baked` under `env` with `settings`' budget and sigma.
    ///
    /// # Errors
    /// A bad environment (NaN, infinite or negative texels or scale, a rotation that is not
    /// finite) or bad settings, as `sample_power_with` and `LightCut::build` say.
    pub fn build(
        &mut self,
        baked: &CutsBaked,
        settings: &CutsFrameSettings,
        env: &Environment,
    ) -> Result<LightCut, relight_bake::cuts::CutsError> {
        let samples = &baked.bake.samples;
        let grid = self
            .grid
            .get_or_insert_with(|| NearestSample::new(&samples.dirs));
        let power = sample_power_with(samples, grid, env)?;
        LightCut::build(
            &baked.bake.tree,
            &power,
            settings.light_sigma,
            settings.light_cut,
        )
    }
}

/// Whether `env` sends no light (scale 0 or every texel black).
fn is_black(env: &Environment) -> bool {
    env.scale == 0.0
        || (0..env.map.texel_count()).all(|i| env.map.texel(i).value == glam::Vec3::ZERO)
}

impl Frame for CutsFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Cuts
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareTimes, MethodError> {
        if let Some(state) = &self.local {
            if !is_black(env) {
                return Err(MethodError::Environment(
                    "a bake of surface samples is lit by its point light only: the environment must be black (a constant [0, 0, 0])"
                        .into(),
                ));
            }
            self.lighting = None;
            let light = state.light;
            return self.set_point_light(light);
        }
        let t0 = Instant::now();
        let light = self
            .light_cut
            .build(self.baked, &self.settings, env)
            .map_err(|e| MethodError::Environment(e.to_string()))?;
        let environment_ms = ms_since(t0);
        let t1 = Instant::now();
        // Every vertex's cut merged with the light cut (the frame's corner lists), camera-
        // and material-independent: here rather than in the first frame.
        self.shader.prepare(&light);
        self.lighting = Some((light, env.clone()));
        Ok(PrepareTimes {
            environment_ms,
            shade_ms: ms_since(t1),
        })
    }

    fn render(&self, camera: &Camera, opts: &FrameOptions) -> FrameOutput {
        if let Some(state) = &self.local {
            let lighting = state
                .lighting
                .as_ref()
                .expect("set_environment before render");
            let t0 = Instant::now();
            let shader = LocalShader::new(
                &self.baked.scene.mesh,
                state.materials.clone(),
                &self.baked.bake,
                self.baked.settings.function,
                state.caster.as_ref(),
            )
            .expect("checked by set_point_light")
            .with_maps(state.maps.clone());
            let img = shader.render(
                lighting,
                camera,
                &RasterOptions {
                    supersample: opts.supersample,
                },
                self.settings.local_terms.terms(),
            );
            return FrameOutput::rasterised_since(img.image, t0);
        }
        let (light, env) = self
            .lighting
            .as_ref()
            .expect("set_environment before render");
        let t0 = Instant::now();
        let img = self.shader.render(
            light,
            camera,
            opts.background.then_some(env),
            &RasterOptions {
                supersample: opts.supersample,
            },
        );
        FrameOutput::rasterised_since(img.image, t0)
    }

    fn summary(&self) -> String {
        let c = &self.baked.bake.cuts;
        if let Some(state) = &self.local {
            let cut = state.lighting.as_ref().map_or(String::new(), |l| {
                format!(
                    ", light cut {} nodes (error bound {}), lighting {:.1} ms + cut {:.1} ms",
                    l.cut.len(),
                    if l.cut.error_bound_met {
                        "met"
                    } else {
                        "not met"
                    },
                    l.sample_ms,
                    l.cut_ms
                )
            });
            return format!(
                "cuts (local light at {}, {:?}): {} vertices, {} surface samples, mean visibility cut {:.1} nodes{cut}",
                state.light.position,
                self.settings.local_terms,
                self.baked.scene.mesh.vertex_count(),
                self.baked.settings.lights,
                c.mean_len()
            );
        }
        let light = self.lighting.as_ref().map_or(String::new(), |(l, _)| {
            format!(
                ", light cut {} nodes (error bound {})",
                l.len(),
                if l.error_bound_met { "met" } else { "not met" }
            )
        });
        format!(
            "cuts: {} vertices, {} lights, mean visibility cut {:.1} nodes{light}",
            self.baked.scene.mesh.vertex_count(),
            self.baked.settings.lights,
            c.mean_len()
        )
    }
}
