//! The `cuts` frame on the GPU (Cheslack-Postava et al. 2008; `relight_method::cuts::CutsFrame`
//! over an environment bake): the vertex cuts uploaded once (CSR offsets, `(index, leftleaf)`
//! pairs, quantised means packed two per word); per environment or rotation, the light
//! samples' power and the illumination cut built on the CPU by the CPU frame's own code
//! (`sample_power`, `LightCut::build`) and uploaded with every tree node's shading direction
//! and five-point spread; per frame, the raster pass whose fragments run the per-pixel merge
//! of sec. 3.2 and the sum of Eq. 5 (sec. 4.2; `cuts.wgsl`), then the resolve pass.
//!
//! Refused (a [`GpuError::Unsupported`] naming what): bakes of surface samples (local
//! lights), texture and normal maps (named with their samplers and texture transforms,
//! which the GPU frame does not read either), and materials other than Lambert, the GGX conductor and
//! the GGX plastic.

use crate::layout::{
    GpuCutsMaterial, GpuCutsParams, GpuLightNode, CUTS_GGX_CONDUCTOR, CUTS_GGX_PLASTIC, CUTS_GLTF,
    CUTS_LAMBERT,
};
use crate::pipeline::{self, bind, v4, MeshBuffers, Raster, B, STORAGE, UNIFORM};
use crate::{FrameStats, Gpu, GpuError, GpuFrame, GpuOutput, PrepareStats};
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::visibility::CutFunction;
use relight_method::cuts::{CutsBaked, CutsFrameSettings, EnvLightCut};
use relight_method::{FrameOptions, MethodKind};
use relight_scene::camera::Camera;
use relight_scene::material::maps::{MaterialMaps, MAP_KINDS};
use relight_scene::material::microfacet::PlasticTables;
use relight_scene::material::Material;
use relight_scene::scene::Environment;
use relight_scene::texture::{Filter, UvTransform, Wrap};
use std::time::Instant;

/// The `cuts` frame on the GPU.
pub(crate) struct CutsGpuFrame<'a> {
    gpu: &'a Gpu,
    baked: &'a CutsBaked,
    settings: CutsFrameSettings,
    mesh: MeshBuffers,
    raster: Raster,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    tables: wgpu::Buffer,
    materials: wgpu::Buffer,
    cuts: wgpu::Buffer,
    /// `keys_base`, `values_base`, `materials_base` of [`GpuCutsParams`].
    bases: [u32; 3],
    /// The prepared light cut and the bind group reading it.
    prepared: Option<(LightCut, wgpu::BindGroup)>,
    /// The light cut of each new environment, from the samples' grid kept across them.
    light_cut: EnvLightCut,
}

/// The GPU form of `m` (a plastic's transmittance table appended to `tables`), or why it is
/// refused.
fn gpu_material(
    m: &Material,
    spread: bool,
    tables: &mut Vec<f32>,
) -> Result<GpuCutsMaterial, GpuError> {
    let mut g = GpuCutsMaterial {
        color: [0.0; 4],
        diffuse: [0.0; 4],
        kind: CUTS_LAMBERT,
        alpha: 0.0,
        spread: (spread && !m.is_diffuse_only()) as u32,
        ior: 1.0,
        table: 0,
        internal_reflectance: 0.0,
        pad: [0; 2],
    };
    match *m {
        Material::Lambert { albedo } => g.color = v4(albedo, 0.0),
        Material::GgxConductor { specular, alpha } => {
            (g.kind, g.color, g.alpha) = (CUTS_GGX_CONDUCTOR, v4(specular, 0.0), alpha);
        }
        Material::GgxPlastic {
            diffuse,
            specular,
            alpha,
            ior,
        } => {
            // The CPU's own tables (MaterialEval fetches the same cached ones).
            let t = PlasticTables::get(alpha, ior);
            g.kind = CUTS_GGX_PLASTIC;
            (g.color, g.diffuse) = (v4(specular, 0.0), v4(diffuse, 0.0));
            (g.alpha, g.ior) = (alpha, ior);
            g.table = tables.len() as u32;
            g.internal_reflectance = t.internal_reflectance;
            tables.extend_from_slice(&t.external_transmittance);
        }
        Material::Gltf {
            base_color,
            metallic,
            roughness,
        } => {
            g.kind = CUTS_GLTF;
            g.color = v4(base_color, metallic);
            g.alpha = relight_scene::material::gltf_pbr::alpha(roughness);
        }
        ref other => {
            return Err(GpuError::Unsupported(format!(
                "--method cuts --gpu shades Lambert, GGX conductor, GGX plastic and glTF materials; {other:?} is not supported on the GPU yet (render it without --gpu)"
            )))
        }
    }
    Ok(g)
}

/// The vertex cuts as one `u32` array (offsets, key pairs, packed means, then the triangles'
/// material indices) and the three bases.
/// The maps of a material for a refusal: each kind, with its sampler and texture transform
/// when they are not the defaults (e.g. `maps diffuse (wrap clamp-to-edge x repeat, nearest
/// filter, KHR_texture_transform)`).
fn describe_maps(maps: &MaterialMaps) -> String {
    let wrap = |w: Wrap| match w {
        Wrap::Repeat => "repeat",
        Wrap::ClampToEdge => "clamp-to-edge",
        Wrap::MirroredRepeat => "mirrored-repeat",
    };
    let each: Vec<String> = MAP_KINDS
        .iter()
        .zip(maps.textures())
        .filter_map(|(kind, t)| {
            let t = t.as_ref()?;
            let s = t.sampler();
            let mut what = Vec::new();
            if (s.wrap_s, s.wrap_t) != (Wrap::Repeat, Wrap::Repeat) {
                what.push(format!("wrap {} x {}", wrap(s.wrap_s), wrap(s.wrap_t)));
            }
            if s.filter == Filter::Nearest {
                what.push("nearest filter".into());
            }
            if t.transform().is_some_and(|t| t != UvTransform::default()) {
                what.push("KHR_texture_transform".into());
            }
            Some(if what.is_empty() {
                kind.to_string()
            } else {
                format!("{kind} ({})", what.join(", "))
            })
        })
        .collect();
    format!("maps {}", each.join(", "))
}

fn pack_cuts(baked: &CutsBaked, max_bytes: u64) -> Result<(Vec<u32>, [u32; 3]), GpuError> {
    let c = &baked.bake.cuts;
    let mesh = &baked.scene.mesh;
    let entries = c.index.len();
    let words = c.offsets.len() as u64
        + 2 * entries as u64
        + entries.div_ceil(2) as u64
        + mesh.indices.len() as u64;
    if words * 4 > max_bytes || words > u32::MAX as u64 {
        return Err(GpuError::Unsupported(format!(
            "{entries} vertex-cut entries need {} bytes in one storage buffer, beyond the device's {max_bytes}",
            words * 4
        )));
    }
    let mut out = Vec::with_capacity(words as usize);
    out.extend(c.offsets.iter().map(|&o| o as u32));
    let keys_base = out.len() as u32;
    for (&i, &l) in c.index.iter().zip(&c.leftleaf) {
        out.extend([i, l]);
    }
    let values_base = out.len() as u32;
    out.extend(
        c.value
            .chunks(2)
            .map(|p| p[0] as u32 | (p.get(1).copied().unwrap_or(0) as u32) << 16),
    );
    let materials_base = out.len() as u32;
    if mesh.material_ids.len() == mesh.indices.len() {
        out.extend_from_slice(&mesh.material_ids);
    } else {
        out.extend(std::iter::repeat_n(0, mesh.indices.len()));
    }
    Ok((out, [keys_base, values_base, materials_base]))
}

impl<'a> CutsGpuFrame<'a> {
    pub fn new(
        gpu: &'a Gpu,
        baked: &'a CutsBaked,
        s: &CutsFrameSettings,
    ) -> Result<Self, GpuError> {
        if baked.bake.surface.is_some() {
            return Err(GpuError::Unsupported(
                "--method cuts --gpu renders environment-light bakes; this bundle holds surface samples (a point or spot light), not supported on the GPU yet (render it without --gpu)"
                    .into(),
            ));
        }
        let scene = &baked.scene;
        let materials: Vec<Material> = match &s.material {
            Some(o) if o.desc.maps.is_some() => {
                return Err(GpuError::Unsupported(
                    "--material with texture or normal maps is not supported by --method cuts --gpu yet (render it without --gpu)".into(),
                ))
            }
            Some(o) => vec![o.desc.material; scene.materials.len().max(1)],
            None => {
                if let Some((id, maps)) = (0..scene.materials.len() as u32)
                    .find_map(|id| scene.maps.of(id).map(|m| (id, m)))
                {
                    return Err(GpuError::Unsupported(format!(
                        "material {id} ({}) has {}: textured materials are not supported by --method cuts --gpu yet (render it without --gpu)",
                        scene.materials[id as usize].kind_name(),
                        describe_maps(maps)
                    )));
                }
                scene.materials.clone()
            }
        };
        let mut table_data = Vec::new();
        let gm = materials
            .iter()
            .map(|m| gpu_material(m, s.cluster_spread, &mut table_data))
            .collect::<Result<Vec<_>, _>>()?;
        if table_data.is_empty() {
            table_data.push(0.0); // no plastic: a binding still needs a buffer
        }
        let mut up = 0;
        let mesh = MeshBuffers::new(gpu, &scene.mesh, &mut up)?;
        let raster = Raster::new(gpu, &mut up)?;
        let (packed, bases) = pack_cuts(baked, gpu.limits().max_storage_buffer_binding_size)?;
        let cuts = gpu.buffer(
            "vertex cuts",
            bytemuck::cast_slice(&packed),
            STORAGE,
            &mut up,
        )?;
        let tables = gpu.buffer(
            "plastic tables",
            bytemuck::cast_slice(&table_data),
            STORAGE,
            &mut up,
        )?;
        let materials = gpu.buffer("materials", bytemuck::cast_slice(&gm), STORAGE, &mut up)?;
        let layout = pipeline::layout(
            gpu,
            "cuts",
            wgpu::ShaderStages::VERTEX_FRAGMENT,
            &[
                B::Uniform,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Uniform,
            ],
        );
        let module = gpu.shader(
            "cuts",
            &[
                include_str!("shaders/common.wgsl"),
                include_str!("shaders/cuts.wgsl"),
            ],
        );
        let pipeline = pipeline::render_pipeline(
            gpu,
            "cuts",
            &module,
            &layout,
            true,
            Some(wgpu::CompareFunction::Greater),
        );
        gpu.check()?;
        Ok(CutsGpuFrame {
            gpu,
            baked,
            settings: s.clone(),
            mesh,
            raster,
            layout,
            pipeline,
            tables,
            materials,
            cuts,
            bases,
            prepared: None,
            light_cut: EnvLightCut::default(),
        })
    }
}

impl GpuFrame for CutsGpuFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Cuts
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareStats, GpuError> {
        // The CPU frame's light cut (`EnvLightCut`, shared).
        let t0 = Instant::now();
        let light = self
            .light_cut
            .build(self.baked, &self.settings, env)
            .map_err(|e| {
                GpuError::Method(relight_method::MethodError::Environment(e.to_string()))
            })?;
        let mut stats = PrepareStats {
            environment_ms: t0.elapsed().as_secs_f64() * 1e3,
            ..Default::default()
        };
        let t1 = Instant::now();
        self.raster.set_environment(self.gpu, env, &mut stats)?;
        let nodes: Vec<GpuLightNode> = (0..light.len())
            .map(|k| GpuLightNode {
                value: v4(light.value[k], 0.0),
                index: light.index[k],
                leftleaf: light.leftleaf[k],
                pad: [0; 2],
            })
            .collect();
        // Per tree node: direction, and cos theta_p where the cluster spreads (else 1, which
        // the shader reads as "one evaluation"), so the CPU's own `spreads` decides.
        let dirs: Vec<[f32; 4]> = (0..light.dirs.len() as u32)
            .map(|i| {
                let c = if light.spreads(i) {
                    light.spread_cos[i as usize]
                } else {
                    1.0
                };
                v4(light.direction(i), c)
            })
            .collect();
        let params = GpuCutsParams {
            light_len: light.len() as u32,
            cosine_in_cuts: (self.baked.settings.function == CutFunction::VisibilityCosine) as u32,
            keys_base: self.bases[0],
            values_base: self.bases[1],
            materials_base: self.bases[2],
            pad: [0; 3],
        };
        let gpu = self.gpu;
        let up = &mut stats.bytes_uploaded;
        let nb = gpu.buffer("light cut", bytemuck::cast_slice(&nodes), STORAGE, up)?;
        let db = gpu.buffer("node directions", bytemuck::cast_slice(&dirs), STORAGE, up)?;
        let pb = gpu.buffer("cuts params", bytemuck::bytes_of(&params), UNIFORM, up)?;
        let m = &self.mesh;
        let group = bind(
            gpu,
            "cuts",
            &self.layout,
            &[
                self.raster.camera.as_entire_binding(),
                m.positions.as_entire_binding(),
                m.normals.as_entire_binding(),
                m.indices.as_entire_binding(),
                self.tables.as_entire_binding(),
                self.materials.as_entire_binding(),
                self.cuts.as_entire_binding(),
                nb.as_entire_binding(),
                db.as_entire_binding(),
                pb.as_entire_binding(),
            ],
        );
        gpu.check()?;
        stats.gpu_ms = t1.elapsed().as_secs_f64() * 1e3;
        self.prepared = Some((light, group));
        Ok(stats)
    }

    fn render(&mut self, camera: &Camera, opts: &FrameOptions) -> Result<GpuOutput, GpuError> {
        let Some((_, group)) = self.prepared.as_ref() else {
            return Err(GpuError::Unsupported(
                "set_environment before render".into(),
            ));
        };
        Raster::check(self.gpu, camera, opts)?;
        let mut stats = FrameStats::default();
        self.raster.draw(
            self.gpu,
            &self.baked.scene.mesh,
            camera,
            opts,
            &self.pipeline,
            group,
            self.mesh.triangles,
            &mut stats,
        )
    }

    fn summary(&self) -> String {
        let light = self.prepared.as_ref().map_or(String::new(), |(l, _)| {
            format!(
                ", light cut {} nodes (error bound {})",
                l.len(),
                if l.error_bound_met { "met" } else { "not met" }
            )
        });
        format!(
            "GPU cuts: {} vertices, {} lights, mean visibility cut {:.1} nodes, cluster spread {}{light}",
            self.baked.scene.mesh.vertex_count(),
            self.baked.settings.lights,
            self.baked.bake.cuts.mean_len(),
            if self.settings.cluster_spread { "on" } else { "off" }
        )
    }
}
