//! The `sh` frame on the GPU (Sloan, Kautz & Snyder 2002; `relight_method::sh::ShFrame`):
//! the environment's SH projection and rotation on the CPU, the per-vertex dot product with
//! the transfer in a compute pass (`sh_shade.wgsl`), once per environment; per frame one
//! raster pass of the per-vertex radiance (`sh.wgsl`) and the resolve pass.

use crate::layout::GpuShParams;
use crate::pipeline::{self, bind, dispatch_2d, v4, MeshBuffers, Raster, B, STORAGE, UNIFORM};
use crate::{FrameStats, Gpu, GpuError, GpuFrame, GpuOutput, PrepareStats};
use glam::Vec3;
use relight_method::sh::{world_light, ShBaked, ShFrameSettings};
use relight_method::{FrameOptions, MethodKind};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use relight_sphere::sh::{sh_count, Window};
use std::time::Instant;

/// The per-vertex SH dot product on the GPU, shared by `sh` and `hybrid`: the transfer and
/// albedo uploaded once, the lighting per environment, the radiance kept on the GPU.
pub(crate) struct ShShade {
    pipeline: wgpu::ComputePipeline,
    group: wgpu::BindGroup,
    light: wgpu::Buffer,
    pub radiance: wgpu::Buffer,
    pub albedo: wgpu::Buffer,
    params: GpuShParams,
    coeffs: usize,
}

impl ShShade {
    pub fn new(gpu: &Gpu, baked: &ShBaked, uploaded: &mut u64) -> Result<Self, GpuError> {
        let t = &baked.transfer;
        let v = t.vertex_count as u32;
        let layout = pipeline::layout(
            gpu,
            "sh shade",
            wgpu::ShaderStages::COMPUTE,
            &[B::Uniform, B::Storage, B::Storage, B::Storage, B::StorageRw],
        );
        let module = gpu.shader("sh shade", &[include_str!("shaders/sh_shade.wgsl")]);
        let pipeline = pipeline::compute_pipeline(gpu, "sh shade", &module, "shade", &layout);
        let (_, _, row_stride) = dispatch_2d(v);
        let params = GpuShParams {
            vertex_count: v,
            coeff_count: t.coeff_count() as u32,
            channels: t.channels as u32,
            row_stride,
        };
        let albedo: Vec<[f32; 4]> = baked.albedo.iter().map(|&a| v4(a, 1.0)).collect();
        let coeffs = t.coeff_count();
        let pb = gpu.buffer("sh params", bytemuck::bytes_of(&params), UNIFORM, uploaded)?;
        let transfer = gpu.buffer("transfer", bytemuck::cast_slice(&t.data), STORAGE, uploaded)?;
        let light = gpu.buffer("light sh", &vec![0u8; coeffs * 16], STORAGE, uploaded)?;
        let albedo = gpu.buffer("albedo", bytemuck::cast_slice(&albedo), STORAGE, uploaded)?;
        let radiance = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vertex radiance"),
            size: (v as u64 * 16).max(16),
            usage: STORAGE,
            mapped_at_creation: false,
        });
        let group = bind(
            gpu,
            "sh shade",
            &layout,
            &[
                pb.as_entire_binding(),
                transfer.as_entire_binding(),
                light.as_entire_binding(),
                albedo.as_entire_binding(),
                radiance.as_entire_binding(),
            ],
        );
        Ok(ShShade {
            pipeline,
            group,
            light,
            radiance,
            albedo,
            params,
            coeffs,
        })
    }

    /// Upload `light` (world-frame RGB SH, zero-padded or truncated to the bake's `n^2`) and
    /// run the compute pass.
    pub fn shade(
        &self,
        gpu: &Gpu,
        light: &[Vec3],
        stats: &mut PrepareStats,
    ) -> Result<(), GpuError> {
        let l: Vec<[f32; 4]> = (0..self.coeffs)
            .map(|i| v4(light.get(i).copied().unwrap_or(Vec3::ZERO), 0.0))
            .collect();
        gpu.write(
            &self.light,
            bytemuck::cast_slice(&l),
            &mut stats.bytes_uploaded,
        );
        let mut enc = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("sh shade"),
            });
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            let (x, y, _) = dispatch_2d(self.params.vertex_count);
            pass.dispatch_workgroups(x, y, 1);
        }
        stats.passes += 1;
        gpu.queue.submit([enc.finish()]);
        gpu.check()
    }
}

/// The `sh` frame on the GPU.
pub(crate) struct ShGpuFrame<'a> {
    gpu: &'a Gpu,
    baked: &'a ShBaked,
    window: Window,
    order: usize,
    shade: ShShade,
    mesh: MeshBuffers,
    raster: Raster,
    pipeline: wgpu::RenderPipeline,
    group: wgpu::BindGroup,
    ready: bool,
}

impl<'a> ShGpuFrame<'a> {
    pub fn new(gpu: &'a Gpu, baked: &'a ShBaked, s: &ShFrameSettings) -> Result<Self, GpuError> {
        let mut up = 0;
        let shade = ShShade::new(gpu, baked, &mut up)?;
        let mesh = MeshBuffers::new(gpu, &baked.scene.mesh, &mut up)?;
        let raster = Raster::new(gpu, &mut up)?;
        let layout = pipeline::layout(
            gpu,
            "sh",
            wgpu::ShaderStages::VERTEX_FRAGMENT,
            &[B::Uniform, B::Storage, B::Storage, B::Storage],
        );
        let module = gpu.shader(
            "sh",
            &[
                include_str!("shaders/common.wgsl"),
                include_str!("shaders/sh.wgsl"),
            ],
        );
        let pipeline = pipeline::render_pipeline(
            gpu,
            "sh",
            &module,
            &layout,
            true,
            Some(wgpu::CompareFunction::Greater),
        );
        let group = bind(
            gpu,
            "sh",
            &layout,
            &[
                raster.camera.as_entire_binding(),
                mesh.positions.as_entire_binding(),
                mesh.indices.as_entire_binding(),
                shade.radiance.as_entire_binding(),
            ],
        );
        gpu.check()?;
        Ok(ShGpuFrame {
            gpu,
            baked,
            window: s.window,
            order: s.sh_order.unwrap_or(baked.transfer.order),
            shade,
            mesh,
            raster,
            pipeline,
            group,
            ready: false,
        })
    }
}

impl GpuFrame for ShGpuFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Sh
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareStats, GpuError> {
        let t0 = Instant::now();
        let mut light = world_light(env, self.order, self.window);
        // Truncation: zero lighting above the order asked for.
        light.resize(sh_count(self.baked.transfer.order), Vec3::ZERO);
        let mut stats = PrepareStats {
            environment_ms: t0.elapsed().as_secs_f64() * 1e3,
            ..Default::default()
        };
        let t1 = Instant::now();
        self.raster.set_environment(self.gpu, env, &mut stats)?;
        self.shade.shade(self.gpu, &light, &mut stats)?;
        stats.gpu_ms = t1.elapsed().as_secs_f64() * 1e3;
        self.ready = true;
        Ok(stats)
    }

    fn render(&mut self, camera: &Camera, opts: &FrameOptions) -> Result<GpuOutput, GpuError> {
        if !self.ready {
            return Err(GpuError::Unsupported(
                "set_environment before render".into(),
            ));
        }
        Raster::check(self.gpu, camera, opts)?;
        let mut stats = FrameStats::default();
        self.raster.draw(
            self.gpu,
            &self.baked.scene.mesh,
            camera,
            opts,
            &self.pipeline,
            &self.group,
            self.mesh.triangles,
            &mut stats,
        )
    }

    fn summary(&self) -> String {
        format!(
            "GPU: SH order {} ({} transfer), {} vertices",
            self.order,
            self.baked.transfer.kind.name(),
            self.baked.transfer.vertex_count
        )
    }
}
