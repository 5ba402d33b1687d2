//! What every method's frame shares: explicit bind-group layouts, the mesh on the GPU, the
//! camera, the sample and output targets, the resolve pass and the read-back.

use crate::layout::{GpuBackground, GpuCamera, GpuResolveParams};
use crate::{FrameStats, Gpu, GpuError, GpuOutput, PrepareStats};
use glam::Vec3;
use relight_method::FrameOptions;
use relight_render::Image;
use relight_scene::camera::Camera;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use relight_sphere::envmap::EnvLayout;

/// Colour format of the sample and output targets: linear float radiance, alpha = coverage.
pub(crate) const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Depth format of the raster and shadow passes.
pub(crate) const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// One binding's kind, for [`layout`].
#[derive(Clone, Copy)]
pub(crate) enum B {
    Uniform,
    Storage,
    StorageRw,
    /// `texture_2d<f32>` read with `textureLoad` (not filterable).
    Tex2d,
    /// `texture_2d_array<f32>` read with `textureLoad`.
    Tex2dArray,
    /// `texture_depth_2d_array`.
    DepthArray,
}

/// A bind-group layout with bindings `0..entries.len()` of the given kinds.
pub(crate) fn layout(
    gpu: &Gpu,
    label: &str,
    visibility: wgpu::ShaderStages,
    entries: &[B],
) -> wgpu::BindGroupLayout {
    let e: Vec<wgpu::BindGroupLayoutEntry> = entries
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupLayoutEntry {
            binding: i as u32,
            visibility,
            ty: match b {
                B::Uniform => wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                B::Storage | B::StorageRw => wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage {
                        read_only: matches!(b, B::Storage),
                    },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                B::Tex2d | B::Tex2dArray => wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: if matches!(b, B::Tex2d) {
                        wgpu::TextureViewDimension::D2
                    } else {
                        wgpu::TextureViewDimension::D2Array
                    },
                    multisampled: false,
                },
                B::DepthArray => wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Depth,
                    view_dimension: wgpu::TextureViewDimension::D2Array,
                    multisampled: false,
                },
            },
            count: None,
        })
        .collect();
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &e,
        })
}

/// A bind group of `resources` at bindings `0..`.
pub(crate) fn bind(
    gpu: &Gpu,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: &[wgpu::BindingResource],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .iter()
        .enumerate()
        .map(|(i, r)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: r.clone(),
        })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A render pipeline drawing triangle lists with `vs`/`fs` of `module` into a [`COLOR`]
/// target (if `color`) and a [`DEPTH`] buffer compared with `depth_compare`.
pub(crate) fn render_pipeline(
    gpu: &Gpu,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    color: bool,
    depth_compare: Option<wgpu::CompareFunction>,
) -> wgpu::RenderPipeline {
    render_pipeline_fs(
        gpu,
        label,
        module,
        layout,
        color.then_some("fs"),
        depth_compare,
    )
}

/// [`render_pipeline`] with fragment entry point `fs` (none: depth only).
pub(crate) fn render_pipeline_fs(
    gpu: &Gpu,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    fs: Option<&str>,
    depth_compare: Option<wgpu::CompareFunction>,
) -> wgpu::RenderPipeline {
    let pl = gpu
        .device
        .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(layout)],
            immediate_size: 0,
        });
    let targets = [Some(wgpu::ColorTargetState {
        format: COLOR,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    })];
    gpu.device
        .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(&pl),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: depth_compare.map(|c| wgpu::DepthStencilState {
                format: DEPTH,
                depth_write_enabled: Some(true),
                depth_compare: Some(c),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: fs.map(|fs| wgpu::FragmentState {
                module,
                entry_point: Some(fs),
                compilation_options: Default::default(),
                targets: &targets,
            }),
            multiview_mask: None,
            cache: None,
        })
}

/// A compute pipeline running `entry` of `module`.
pub(crate) fn compute_pipeline(
    gpu: &Gpu,
    label: &str,
    module: &wgpu::ShaderModule,
    entry: &str,
    layout: &wgpu::BindGroupLayout,
) -> wgpu::ComputePipeline {
    let pl = gpu
        .device
        .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(layout)],
            immediate_size: 0,
        });
    gpu.device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&pl),
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
}

/// `[x, y, z, w]` of a vector.
pub(crate) fn v4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// Storage usage.
pub(crate) const STORAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE;
/// Uniform usage.
pub(crate) const UNIFORM: wgpu::BufferUsages = wgpu::BufferUsages::UNIFORM;

/// A mesh on the GPU: positions and normals as `vec4`, triangle corners as `u32`.
pub(crate) struct MeshBuffers {
    pub positions: wgpu::Buffer,
    pub normals: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub triangles: u32,
}

impl MeshBuffers {
    pub fn new(gpu: &Gpu, mesh: &TriMesh, uploaded: &mut u64) -> Result<Self, GpuError> {
        let p: Vec<[f32; 4]> = mesh.positions.iter().map(|&p| v4(p, 1.0)).collect();
        let n: Vec<[f32; 4]> = mesh.normals.iter().map(|&n| v4(n, 0.0)).collect();
        let i: Vec<u32> = mesh.indices.iter().flatten().copied().collect();
        let triangles = u32::try_from(mesh.indices.len())
            .ok()
            .filter(|t| (*t as u64) * 3 <= u32::MAX as u64)
            .ok_or_else(|| GpuError::Unsupported("more than 2^32 / 3 triangles".into()))?;
        Ok(MeshBuffers {
            positions: gpu.buffer("positions", bytemuck::cast_slice(&p), STORAGE, uploaded)?,
            normals: gpu.buffer("normals", bytemuck::cast_slice(&n), STORAGE, uploaded)?,
            indices: gpu.buffer("indices", bytemuck::cast_slice(&i), STORAGE, uploaded)?,
            triangles,
        })
    }
}

/// The camera uniform of `camera` over `mesh` (the CPU rasteriser's near plane).
pub(crate) fn camera_uniform(camera: &Camera, mesh: &TriMesh) -> GpuCamera {
    let f = camera.frame();
    let far = mesh
        .positions
        .iter()
        .fold(0.0f32, |m, &p| m.max((p - f.origin).length()));
    GpuCamera {
        origin: v4(f.origin, 1.0),
        right: v4(f.right, 0.0),
        up: v4(f.up, 0.0),
        forward: v4(f.forward, 0.0),
        tan_half: [f.tan_half_x, f.tan_half_y],
        near: (1e-5 * far).max(f32::MIN_POSITIVE),
        pad: 0.0,
    }
}

/// Sample and output targets of one size.
struct Targets {
    key: (u32, u32, u32),
    samples: wgpu::TextureView,
    depth: wgpu::TextureView,
    out: wgpu::Texture,
    out_view: wgpu::TextureView,
}

/// The shared end of every frame: camera uniform, targets, the main pass, the resolve pass
/// and the read-back.
pub(crate) struct Raster {
    pub camera: wgpu::Buffer,
    resolve_layout: wgpu::BindGroupLayout,
    resolve: wgpu::RenderPipeline,
    resolve_background: wgpu::RenderPipeline,
    resolve_params: wgpu::Buffer,
    targets: Option<Targets>,
    /// The background's parameters and texels (zeros until an environment is set).
    background: (wgpu::Buffer, wgpu::Buffer),
    /// Why the prepared environment cannot be drawn as background, if it cannot.
    no_background: Option<String>,
}

impl Raster {
    pub fn new(gpu: &Gpu, uploaded: &mut u64) -> Result<Self, GpuError> {
        let resolve_layout = layout(
            gpu,
            "resolve",
            wgpu::ShaderStages::FRAGMENT,
            &[B::Tex2d, B::Uniform, B::Uniform, B::Uniform, B::Storage],
        );
        let module = gpu.shader(
            "resolve",
            &[
                include_str!("shaders/common.wgsl"),
                include_str!("shaders/resolve.wgsl"),
            ],
        );
        let resolve = render_pipeline(gpu, "resolve", &module, &resolve_layout, true, None);
        let resolve_background = render_pipeline_fs(
            gpu,
            "resolve + background",
            &module,
            &resolve_layout,
            Some("fs_background"),
            None,
        );
        let cam = [GpuCamera::zeroed_default()];
        Ok(Raster {
            camera: gpu.buffer("camera", bytemuck::cast_slice(&cam), UNIFORM, uploaded)?,
            resolve_params: gpu.buffer(
                "resolve params",
                bytemuck::bytes_of(&GpuResolveParams {
                    supersample: 1,
                    background: 0,
                    width: 1,
                    height: 1,
                }),
                UNIFORM,
                uploaded,
            )?,
            resolve_layout,
            resolve,
            resolve_background,
            targets: None,
            background: (
                gpu.buffer("background", &[0; 64], UNIFORM, uploaded)?,
                gpu.buffer("background texels", &[0; 16], STORAGE, uploaded)?,
            ),
            no_background: Some("no environment prepared".into()),
        })
    }

    /// Upload `env`'s map, rotation and scale for the background (latlong and cube maps;
    /// an angular probe is kept out, and refused only if a frame asks for a background).
    pub fn set_environment(
        &mut self,
        gpu: &Gpu,
        env: &Environment,
        stats: &mut PrepareStats,
    ) -> Result<(), GpuError> {
        let map = &env.map;
        let layout = match map.layout() {
            EnvLayout::LatLong => 0,
            EnvLayout::Cube => 1,
            EnvLayout::Probe => {
                self.no_background =
                    Some("the GPU renderer draws no angular-probe background yet".into());
                return Ok(());
            }
        };
        let m = env.env_from_world();
        let params = GpuBackground {
            env_from_world: [v4(m.x_axis, 0.0), v4(m.y_axis, 0.0), v4(m.z_axis, 0.0)],
            map_layout: layout,
            width: map.width() as u32,
            height: map.height() as u32,
            scale: env.scale,
        };
        let texels: Vec<[f32; 4]> = map.texels().iter().map(|&t| v4(t, 0.0)).collect();
        let up = &mut stats.bytes_uploaded;
        let p = gpu.buffer("background", bytemuck::bytes_of(&params), UNIFORM, up)?;
        let t = gpu.buffer(
            "background texels",
            bytemuck::cast_slice(&texels),
            STORAGE,
            up,
        )?;
        self.background = (p, t);
        self.no_background = None;
        Ok(())
    }

    /// Check `opts` and the image size against the device.
    pub fn check(gpu: &Gpu, camera: &Camera, opts: &FrameOptions) -> Result<(), GpuError> {
        relight_method::check_frame_options(opts, camera)?;
        let max = gpu.limits().max_texture_dimension_2d;
        let (w, h) = (
            camera.width as u64 * opts.supersample as u64,
            camera.height as u64 * opts.supersample as u64,
        );
        if w > max as u64 || h > max as u64 || camera.width == 0 || camera.height == 0 {
            return Err(GpuError::Unsupported(format!(
                "{} x {} pixels x {} samples per axis is {w} x {h} samples, beyond the device's {max}-texel textures",
                camera.width, camera.height, opts.supersample
            )));
        }
        Ok(())
    }

    fn targets(&mut self, gpu: &Gpu, w: u32, h: u32, ss: u32) -> &Targets {
        let key = (w, h, ss);
        if self.targets.as_ref().is_none_or(|t| t.key != key) {
            let tex = |label, format, width, height, usage| {
                gpu.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d {
                        width,
                        height,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
            };
            use wgpu::TextureUsages as U;
            let samples = tex(
                "samples",
                COLOR,
                w * ss,
                h * ss,
                U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
            );
            let depth = tex("depth", DEPTH, w * ss, h * ss, U::RENDER_ATTACHMENT);
            let out = tex("out", COLOR, w, h, U::RENDER_ATTACHMENT | U::COPY_SRC);
            self.targets = Some(Targets {
                key,
                samples: samples.create_view(&Default::default()),
                depth: depth.create_view(&Default::default()),
                out_view: out.create_view(&Default::default()),
                out,
            });
        }
        self.targets.as_ref().expect("targets made above")
    }

    /// Write the camera, draw `3 * triangles` vertices with `pipeline` and `group` into the
    /// sample target, resolve and read back.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        gpu: &Gpu,
        mesh: &TriMesh,
        camera: &Camera,
        opts: &FrameOptions,
        pipeline: &wgpu::RenderPipeline,
        group: &wgpu::BindGroup,
        triangles: u32,
        stats: &mut FrameStats,
    ) -> Result<GpuOutput, GpuError> {
        if let (true, Some(why)) = (opts.background, &self.no_background) {
            return Err(GpuError::Unsupported(format!(
                "background: {why} (drop --background, or --gpu)"
            )));
        }
        let t0 = std::time::Instant::now();
        let cam = camera_uniform(camera, mesh);
        gpu.write(
            &self.camera,
            bytemuck::bytes_of(&cam),
            &mut stats.bytes_uploaded,
        );
        let ss = opts.supersample;
        gpu.write(
            &self.resolve_params,
            bytemuck::bytes_of(&GpuResolveParams {
                supersample: ss,
                background: opts.background as u32,
                width: camera.width,
                height: camera.height,
            }),
            &mut stats.bytes_uploaded,
        );
        stats.cpu_ms += t0.elapsed().as_secs_f64() * 1e3;
        let (w, h) = (camera.width, camera.height);
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        let rl = self.resolve_layout.clone();
        let rp = if opts.background {
            self.resolve_background.clone()
        } else {
            self.resolve.clone()
        };
        let params = self.resolve_params.clone();
        let camera_buffer = self.camera.clone();
        let (bg, texels) = self.background.clone();
        let t = self.targets(gpu, w, h, ss);
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("shade"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &t.samples,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &t.depth,
                    // Reverse depth (common.wgsl): 0 is infinitely far.
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.draw(0..3 * triangles, 0..1);
        }
        let rg = bind(
            gpu,
            "resolve",
            &rl,
            &[
                wgpu::BindingResource::TextureView(&t.samples),
                params.as_entire_binding(),
                camera_buffer.as_entire_binding(),
                bg.as_entire_binding(),
                texels.as_entire_binding(),
            ],
        );
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("resolve"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &t.out_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                ..Default::default()
            });
            pass.set_pipeline(&rp);
            pass.set_bind_group(0, &rg, &[]);
            pass.draw(0..3, 0..1);
        }
        stats.passes += 2;
        stats.draw_calls += 2;
        let px = gpu.read_rgba32f(enc, &t.out, w, h)?;
        let (pixels, coverage) = px
            .into_iter()
            .map(|p| (Vec3::new(p[0], p[1], p[2]), p[3]))
            .unzip();
        stats.adapter = gpu.adapter_name().to_string();
        stats.total_ms += t0.elapsed().as_secs_f64() * 1e3;
        Ok(GpuOutput {
            image: Image {
                width: w as usize,
                height: h as usize,
                pixels,
            },
            coverage,
            stats: stats.clone(),
        })
    }
}

impl GpuCamera {
    fn zeroed_default() -> GpuCamera {
        bytemuck::Zeroable::zeroed()
    }
}

/// Dispatch size of `n` invocations of 64 in at most 65535 workgroups per row: `(x, y)` and
/// the invocations per row.
pub(crate) fn dispatch_2d(n: u32) -> (u32, u32, u32) {
    let groups = n.div_ceil(64).max(1);
    let x = groups.min(65535);
    (x, groups.div_ceil(x), x * 64)
}
