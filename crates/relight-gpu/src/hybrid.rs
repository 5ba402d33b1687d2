//! The `hybrid` frame on the GPU (thesis 4.3-4.4; `relight_method::hybrid::HybridFrame`):
//! per environment, the decomposition and the SH part on the CPU (as the CPU frame) and the
//! per-vertex dot product in a compute pass; per frame, one depth pass per light into a
//! layer of a depth texture array and the maps' min pyramids (a compute pass,
//! `shadow_pyramid.wgsl`, for the PCSS blocker search) **only when the lights changed**
//! (cache key: each light's direction bits and the map size;
//! [`FrameStats::shadow_maps_rendered`] counts the maps), then the shading pass
//! (`hybrid.wgsl`) and the resolve pass.

use crate::layout::{GpuHybridParams, GpuLight, GpuPyramidLevel, MAX_PYRAMID_LEVELS};
use crate::pipeline::{self, bind, v4, MeshBuffers, Raster, B, DEPTH, STORAGE, UNIFORM};
use crate::sh::ShShade;
use crate::{FrameStats, Gpu, GpuError, GpuFrame, GpuOutput, PrepareStats};
use glam::Vec3;
use relight_method::hybrid::{decompose_env, hybrid_lights, HybridSettings};
use relight_method::sh::ShBaked;
use relight_method::{FrameOptions, MethodKind};
use relight_render::hybrid::{HybridLight, ShadowSettings};
use relight_scene::camera::Camera;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use relight_sphere::decompose::DecomposeSettings;
use relight_sphere::sh::sh_count;
use relight_sphere::sh_rotate::ShRotation;
use std::time::Instant;

/// The shadow maps' cache key: map size and each light's direction, bit for bit.
type ShadowKey = (u32, Vec<[u32; 3]>);

/// The GPU layout of `lights` over `mesh` (`relight_render::shadowmap::ShadowMap::build`'s
/// frame: centre of the bounding box, half its diagonal plus 0.1 %, `any_orthonormal_pair`),
/// lights without power dropped (the CPU skips them too).
pub(crate) fn gpu_lights(
    mesh: &TriMesh,
    lights: &[HybridLight],
    s: &ShadowSettings,
) -> Vec<GpuLight> {
    let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let center = (lo + hi) * 0.5;
    let half = ((hi - lo).length() * 0.5 * 1.001).max(1e-6);
    lights
        .iter()
        .filter(|l| l.power.max_element() > 0.0)
        .map(|l| {
            let (u, v) = l.dir.any_orthonormal_pair();
            GpuLight {
                dir: v4(l.dir, l.cap_radius),
                u: v4(u, 2.0 * half / s.map_size as f32),
                v: v4(v, half),
                center: v4(center, s.depth_bias),
                power: v4(l.power, 0.0),
                kernel: s.pcf_taps.max(1) as f32,
                taps: s.area_taps.max(2),
                size: s.map_size,
                area: s.area_light as u32,
            }
        })
        .collect()
}

/// The min pyramid of an `n`-texel map (`ShadowMap`'s levels: level 1 of `ceil(n / 2)`
/// entries per side, each the next halved, down to 1): `(size, offset)` per level and the
/// floats of one layer.
fn pyramid_levels(n: u32) -> (Vec<(u32, u32)>, u32) {
    let (mut levels, mut m, mut offset) = (vec![], n, 0);
    while m > 1 {
        m = m.div_ceil(2);
        levels.push((m, offset));
        offset += m * m;
    }
    (levels, offset)
}

/// What the prepared environment gives the GPU.
struct Prepared {
    lights: Vec<GpuLight>,
    shadow: wgpu::Texture,
    /// The maps' min pyramids (kept with the maps).
    pyramid: wgpu::Buffer,
    group: wgpu::BindGroup,
    shadow_group: wgpu::BindGroup,
    /// One bind group per pyramid level, with the level's size (dispatch).
    pyramid_groups: Vec<(wgpu::BindGroup, u32)>,
    /// The key of the lights the maps were rendered for (`None`: not rendered yet).
    rendered: Option<ShadowKey>,
    key: ShadowKey,
}

/// The `hybrid` frame on the GPU.
pub(crate) struct HybridGpuFrame<'a> {
    gpu: &'a Gpu,
    baked: &'a ShBaked,
    thesis: bool,
    decompose: DecomposeSettings,
    shadows: ShadowSettings,
    shade: ShShade,
    mesh: MeshBuffers,
    raster: Raster,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    shadow_layout: wgpu::BindGroupLayout,
    shadow_pipeline: wgpu::RenderPipeline,
    pyramid_layout: wgpu::BindGroupLayout,
    pyramid_pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    prepared: Option<Prepared>,
}

impl<'a> HybridGpuFrame<'a> {
    pub fn new(gpu: &'a Gpu, baked: &'a ShBaked, s: &HybridSettings) -> Result<Self, GpuError> {
        let (decompose, shadows) = s.resolve(baked.transfer.order)?;
        if shadows.map_size > gpu.limits().max_texture_dimension_2d {
            return Err(GpuError::Unsupported(format!(
                "shadow map size {} exceeds the device's {}-texel textures",
                shadows.map_size,
                gpu.limits().max_texture_dimension_2d
            )));
        }
        let mut up = 0;
        let shade = ShShade::new(gpu, baked, &mut up)?;
        let mesh = MeshBuffers::new(gpu, &baked.scene.mesh, &mut up)?;
        let raster = Raster::new(gpu, &mut up)?;
        let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let layout = pipeline::layout(
            gpu,
            "hybrid",
            vf,
            &[
                B::Uniform,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::DepthArray,
                B::Uniform,
                B::Storage,
            ],
        );
        let light_wgsl = include_str!("shaders/light.wgsl");
        let module = gpu.shader(
            "hybrid",
            &[
                include_str!("shaders/common.wgsl"),
                light_wgsl,
                include_str!("shaders/hybrid.wgsl"),
            ],
        );
        let pipeline = pipeline::render_pipeline(
            gpu,
            "hybrid",
            &module,
            &layout,
            true,
            Some(wgpu::CompareFunction::Greater),
        );
        let shadow_layout = pipeline::layout(
            gpu,
            "shadow",
            wgpu::ShaderStages::VERTEX,
            &[B::Storage, B::Storage, B::Storage],
        );
        let smod = gpu.shader("shadow", &[light_wgsl, include_str!("shaders/shadow.wgsl")]);
        let shadow_pipeline = pipeline::render_pipeline(
            gpu,
            "shadow",
            &smod,
            &shadow_layout,
            false,
            Some(wgpu::CompareFunction::Less),
        );
        let (levels, _) = pyramid_levels(shadows.map_size);
        if levels.len() > MAX_PYRAMID_LEVELS {
            return Err(GpuError::Unsupported(format!(
                "shadow map size {} has more than {MAX_PYRAMID_LEVELS} pyramid levels",
                shadows.map_size
            )));
        }
        let params = gpu.buffer(
            "hybrid params",
            bytemuck::bytes_of(&<GpuHybridParams as bytemuck::Zeroable>::zeroed()),
            UNIFORM,
            &mut up,
        )?;
        let pyramid_layout = pipeline::layout(
            gpu,
            "shadow pyramid",
            wgpu::ShaderStages::COMPUTE,
            &[B::Uniform, B::Storage, B::DepthArray, B::StorageRw],
        );
        let pmod = gpu.shader(
            "shadow pyramid",
            &[light_wgsl, include_str!("shaders/shadow_pyramid.wgsl")],
        );
        let pyramid_pipeline =
            pipeline::compute_pipeline(gpu, "shadow pyramid", &pmod, "build", &pyramid_layout);
        gpu.check()?;
        Ok(HybridGpuFrame {
            gpu,
            baked,
            thesis: s.thesis,
            decompose,
            shadows,
            shade,
            mesh,
            raster,
            layout,
            pipeline,
            shadow_layout,
            shadow_pipeline,
            pyramid_layout,
            pyramid_pipeline,
            params,
            prepared: None,
        })
    }

    /// Shadow maps of the prepared lights into `enc`, if their key changed.
    fn shadow_passes(&mut self, enc: &mut wgpu::CommandEncoder, stats: &mut FrameStats) {
        let Some(p) = self.prepared.as_mut() else {
            return;
        };
        if p.rendered.as_ref() == Some(&p.key) {
            return;
        }
        for i in 0..p.lights.len() as u32 {
            let view = p.shadow.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: i,
                array_layer_count: Some(1),
                ..Default::default()
            });
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("shadow map"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &view,
                    // 1 = empty (light.wgsl).
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_pipeline(&self.shadow_pipeline);
            pass.set_bind_group(0, &p.shadow_group, &[]);
            // The instance index picks the light (shadow.wgsl).
            pass.draw(0..3 * self.mesh.triangles, i..i + 1);
            stats.passes += 1;
            stats.draw_calls += 1;
            stats.shadow_maps_rendered += 1;
        }
        // The maps' min pyramids, level by level (each dispatch sees the previous one's
        // writes).
        if !p.lights.is_empty() {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pyramid_pipeline);
            for (g, size) in &p.pyramid_groups {
                pass.set_bind_group(0, g, &[]);
                pass.dispatch_workgroups(size.div_ceil(8), size.div_ceil(8), p.lights.len() as u32);
            }
            stats.passes += 1;
        }
        p.rendered = Some(p.key.clone());
    }
}

impl GpuFrame for HybridGpuFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Hybrid
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareStats, GpuError> {
        let t0 = Instant::now();
        let decomposition = decompose_env(env, &self.decompose)?;
        // SH part: map frame -> world, scaled, zero-padded to the bake's order (as the CPU).
        let order = self.baked.transfer.order;
        let mut light =
            ShRotation::new(self.decompose.sh_order, env.world_from_env()).apply(&decomposition.sh);
        light.iter_mut().for_each(|c| *c *= env.scale);
        light.resize(sh_count(order), Vec3::ZERO);
        let lights = hybrid_lights(&decomposition, env, self.thesis);
        let lights = gpu_lights(&self.baked.scene.mesh, &lights, &self.shadows);
        let mut stats = PrepareStats {
            environment_ms: t0.elapsed().as_secs_f64() * 1e3,
            ..Default::default()
        };
        let t1 = Instant::now();
        self.raster.set_environment(self.gpu, env, &mut stats)?;
        self.shade.shade(self.gpu, &light, &mut stats)?;
        let key: ShadowKey = (
            self.shadows.map_size,
            lights
                .iter()
                .map(|l| [l.dir[0].to_bits(), l.dir[1].to_bits(), l.dir[2].to_bits()])
                .collect(),
        );
        let gpu = self.gpu;
        let up = &mut stats.bytes_uploaded;
        let (levels, layer_stride) = pyramid_levels(self.shadows.map_size);
        let mut hp = GpuHybridParams {
            light_count: lights.len() as u32,
            level_count: levels.len() as u32,
            layer_stride,
            pad: 0,
            levels: [[0; 4]; MAX_PYRAMID_LEVELS],
        };
        for (k, &(size, offset)) in levels.iter().enumerate() {
            hp.levels[k] = [size, offset, 0, 0];
        }
        gpu.write(&self.params, bytemuck::bytes_of(&hp), up);
        // Keep the maps (and their texture) when the lights did not move.
        let keep = self
            .prepared
            .take()
            .filter(|p| p.key == key && p.lights.len() == lights.len());
        let layers = (lights.len() as u64).max(1);
        let pyramid_bytes = layer_stride as u64 * 4 * layers;
        if pyramid_bytes > gpu.limits().max_storage_buffer_binding_size {
            return Err(GpuError::Unsupported(format!(
                "{} shadow maps of {} texels need a {pyramid_bytes}-byte depth pyramid, beyond the device's storage buffer limit",
                lights.len(),
                self.shadows.map_size
            )));
        }
        let (shadow, pyramid, rendered) = match keep {
            Some(p) => (p.shadow, p.pyramid, p.rendered),
            None => {
                let n = self.shadows.map_size;
                let layers = (lights.len() as u32).max(1);
                let t = gpu.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("shadow maps"),
                    size: wgpu::Extent3d {
                        width: n,
                        height: n,
                        depth_or_array_layers: layers,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: DEPTH,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                        | wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                });
                let pyramid = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("shadow pyramids"),
                    size: pyramid_bytes.max(16),
                    usage: STORAGE,
                    mapped_at_creation: false,
                });
                (t, pyramid, None)
            }
        };
        // A binding holds at least one light (unused when there are none).
        let padded = if lights.is_empty() {
            vec![bytemuck::Zeroable::zeroed()]
        } else {
            lights.clone()
        };
        let light_buffer = gpu.buffer("lights", bytemuck::cast_slice(&padded), STORAGE, up)?;
        let sview = shadow.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let mut pyramid_groups = vec![];
        let mut src = (self.shadows.map_size, 0u32, 1u32);
        for &(size, offset) in &levels {
            let lv = GpuPyramidLevel {
                src_size: src.0,
                dst_size: size,
                src_offset: src.1,
                dst_offset: offset,
                layer_stride,
                from_texture: src.2,
                pad: [0; 2],
            };
            let b = gpu.buffer("pyramid level", bytemuck::bytes_of(&lv), UNIFORM, up)?;
            let sv = shadow.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            });
            let g = bind(
                gpu,
                "pyramid level",
                &self.pyramid_layout,
                &[
                    b.as_entire_binding(),
                    light_buffer.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&sv),
                    pyramid.as_entire_binding(),
                ],
            );
            pyramid_groups.push((g, size));
            src = (size, offset, 0);
        }
        let m = &self.mesh;
        let group = bind(
            gpu,
            "hybrid",
            &self.layout,
            &[
                self.raster.camera.as_entire_binding(),
                m.positions.as_entire_binding(),
                m.normals.as_entire_binding(),
                m.indices.as_entire_binding(),
                self.shade.radiance.as_entire_binding(),
                self.shade.albedo.as_entire_binding(),
                light_buffer.as_entire_binding(),
                wgpu::BindingResource::TextureView(&sview),
                self.params.as_entire_binding(),
                pyramid.as_entire_binding(),
            ],
        );
        let shadow_group = bind(
            gpu,
            "shadow",
            &self.shadow_layout,
            &[
                light_buffer.as_entire_binding(),
                m.positions.as_entire_binding(),
                m.indices.as_entire_binding(),
            ],
        );
        self.prepared = Some(Prepared {
            lights,
            shadow,
            pyramid,
            group,
            shadow_group,
            pyramid_groups,
            rendered,
            key,
        });
        gpu.check()?;
        stats.gpu_ms = t1.elapsed().as_secs_f64() * 1e3;
        Ok(stats)
    }

    fn render(&mut self, camera: &Camera, opts: &FrameOptions) -> Result<GpuOutput, GpuError> {
        if self.prepared.is_none() {
            return Err(GpuError::Unsupported(
                "set_environment before render".into(),
            ));
        }
        Raster::check(self.gpu, camera, opts)?;
        let mut stats = FrameStats::default();
        // The shadow passes go first in the frame's encoder; recorded here (they need
        // `&mut self`), then the shading pass reads the maps.
        let mut enc = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("shadows"),
            });
        self.shadow_passes(&mut enc, &mut stats);
        self.gpu.queue.submit([enc.finish()]);
        let p = self.prepared.as_ref().expect("checked above");
        self.raster.draw(
            self.gpu,
            &self.baked.scene.mesh,
            camera,
            opts,
            &self.pipeline,
            &p.group,
            self.mesh.triangles,
            &mut stats,
        )
    }

    fn summary(&self) -> String {
        let lights = self.prepared.as_ref().map_or(0, |p| p.lights.len());
        format!(
            "GPU hybrid: {lights} lights ({}-texel shadow maps) + SH order {}",
            self.shadows.map_size, self.decompose.sh_order
        )
    }
}
