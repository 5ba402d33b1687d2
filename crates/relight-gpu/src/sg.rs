//! The `sg` frame on the GPU (Green 2005; `relight_method::sg::SgFrame`): per environment,
//! the Gaussian-prefiltered cube chain (CPU, `relight_render::shade_sg::SgLighting`)
//! uploaded as a 6-layer texture with one mip level per chain level (level `k` has face
//! size `n >> k`, as `default_levels`); per frame, the per-vertex view blend on the CPU
//! (`SgRenderer::prepare`: view location on the icosahedron, lobe matching and blending,
//! diffuse SH), the upload of its lobes and diffuse radiance, then the matching of each
//! triangle's corner lobes (a compute pass, `sg_match.wgsl`), the per-pixel lobe blend and
//! prefiltered fetches (`sg.wgsl`) and the resolve pass. Lobes in the half-vector domain
//! (`--lobe-domain half-vector`) are integrated for the fragment's own view with the warp
//! table of `relight_sphere::half_vector` (a storage buffer, five fetches per Gaussian
//! term, `sg_half.wgsl`), their blends keeping the corners' integrals as the CPU's
//! `keep_mass` (each vertex lobe's unit mass at its view, from
//! `SgFrame::masses`, rides in the uploaded lobe's fourth amplitude component).

use crate::layout::{GpuLobe, GpuMatchParams, GpuSgParams, MAX_CHAIN_LEVELS};
use crate::pipeline::{self, bind, dispatch_2d, v4, MeshBuffers, Raster, B, STORAGE, UNIFORM};
use crate::{FrameStats, Gpu, GpuError, GpuFrame, GpuOutput, PrepareStats};
use glam::Vec3;
use relight_bake::sg::SgDomain;
use relight_method::sg::{SgBaked, SgFrameSettings};
use relight_method::{FrameOptions, MethodKind};
use relight_render::shade_sg::{LobeBlend, SgLighting, SgRenderer};
use relight_scene::camera::Camera;
use relight_scene::scene::Environment;
use relight_sphere::half_vector;
use std::time::Instant;

/// The shading pass's WGSL: the camera, the lobes, `sg.wgsl`, and the half-vector lobes'
/// table constants and functions (`sg_half.wgsl`).
pub(crate) fn shading_source() -> String {
    [
        include_str!("shaders/common.wgsl"),
        include_str!("shaders/sg_lobes.wgsl"),
        include_str!("shaders/sg.wgsl"),
        &half_vector_constants(),
        include_str!("shaders/sg_half.wgsl"),
    ]
    .concat()
}

/// The grid of `relight_sphere::half_vector`'s table as WGSL constants (`sg_half.wgsl`).
fn half_vector_constants() -> String {
    use half_vector::*;
    format!(
        "const HV_LN_S_MIN: f32 = {LN_S_MIN:?};\nconst HV_LN_S_STEP: f32 = {LN_S_STEP:?};\n\
         const HV_S_COUNT: u32 = {S_COUNT}u;\nconst HV_THETA_STEP: f32 = {THETA_STEP:?};\n\
         const HV_THETA_COUNT: u32 = {THETA_COUNT}u;\nconst HV_S_MIN: f32 = {S_MIN:?};\n\
         const HV_TAPS: u32 = {TAPS}u;\nconst HV_MASS_LEN: u32 = {}u;\n",
        S_COUNT * THETA_COUNT
    )
}

/// The `sg` frame on the GPU.
pub(crate) struct SgGpuFrame<'a> {
    gpu: &'a Gpu,
    baked: &'a SgBaked,
    renderer: SgRenderer<'a>,
    prefilter_size: usize,
    mesh: MeshBuffers,
    raster: Raster,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    lobes: wgpu::Buffer,
    diffuse: wgpu::Buffer,
    params: wgpu::Buffer,
    perms: wgpu::Buffer,
    half_table: wgpu::Buffer,
    matching: wgpu::ComputePipeline,
    match_group: wgpu::BindGroup,
    prepared: Option<(SgLighting, wgpu::BindGroup)>,
}

impl<'a> SgGpuFrame<'a> {
    pub fn new(gpu: &'a Gpu, baked: &'a SgBaked, s: &SgFrameSettings) -> Result<Self, GpuError> {
        let renderer = SgRenderer::new(&baked.scene.mesh, &baked.bake)
            .with_options(s.shade_options(&baked.bake));
        let mut up = 0;
        let mesh = MeshBuffers::new(gpu, &baked.scene.mesh, &mut up)?;
        let raster = Raster::new(gpu, &mut up)?;
        let layout = pipeline::layout(
            gpu,
            "sg",
            wgpu::ShaderStages::VERTEX_FRAGMENT,
            &[
                B::Uniform,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Storage,
                B::Tex2dArray,
                B::Uniform,
                B::Storage,
                B::Storage,
            ],
        );
        let lobes_wgsl = include_str!("shaders/sg_lobes.wgsl");
        let module = gpu.shader("sg", &[&shading_source()]);
        let pipeline = pipeline::render_pipeline(
            gpu,
            "sg",
            &module,
            &layout,
            true,
            Some(wgpu::CompareFunction::Greater),
        );
        let v = baked.scene.mesh.vertex_count();
        let n = renderer.lobe_count();
        let lobes = gpu.buffer("lobes", &vec![0u8; (v * n.max(1)) * 32], STORAGE, &mut up)?;
        let diffuse = gpu.buffer("diffuse", &vec![0u8; v * 16], STORAGE, &mut up)?;
        // The warp table of half-vector lobes (sg_half.wgsl), bound for every bake (42 KiB).
        let (mass, taps) = half_vector::table_data();
        let table: Vec<f32> = mass
            .iter()
            .copied()
            .chain(taps.iter().flatten().flatten().copied())
            .collect();
        let half_table = gpu.buffer(
            "half-vector table",
            bytemuck::cast_slice(&table),
            STORAGE,
            &mut up,
        )?;
        let params = gpu.buffer(
            "sg params",
            &[0u8; std::mem::size_of::<GpuSgParams>()],
            UNIFORM,
            &mut up,
        )?;
        // The matching pass: one permutation per (triangle, component, corner), 2 words each.
        let perms = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("lobe permutations"),
            size: (mesh.triangles as u64 * 12 * 4).max(16),
            usage: STORAGE,
            mapped_at_creation: false,
        });
        let match_layout = pipeline::layout(
            gpu,
            "sg match",
            wgpu::ShaderStages::COMPUTE,
            &[B::Uniform, B::Uniform, B::Storage, B::Storage, B::StorageRw],
        );
        let mmod = gpu.shader(
            "sg match",
            &[lobes_wgsl, include_str!("shaders/sg_match.wgsl")],
        );
        let matching =
            pipeline::compute_pipeline(gpu, "sg match", &mmod, "match_triangles", &match_layout);
        let (_, _, row_stride) = dispatch_2d(mesh.triangles);
        let mp = GpuMatchParams {
            triangle_count: mesh.triangles,
            row_stride,
            pad: [0; 2],
        };
        let mparams = gpu.buffer("match params", bytemuck::bytes_of(&mp), UNIFORM, &mut up)?;
        let match_group = bind(
            gpu,
            "sg match",
            &match_layout,
            &[
                params.as_entire_binding(),
                mparams.as_entire_binding(),
                mesh.indices.as_entire_binding(),
                lobes.as_entire_binding(),
                perms.as_entire_binding(),
            ],
        );
        gpu.check()?;
        Ok(SgGpuFrame {
            gpu,
            baked,
            renderer,
            prefilter_size: s.prefilter_size,
            mesh,
            raster,
            layout,
            pipeline,
            lobes,
            diffuse,
            params,
            perms,
            half_table,
            matching,
            match_group,
            prepared: None,
        })
    }
}

impl GpuFrame for SgGpuFrame<'_> {
    fn method(&self) -> MethodKind {
        MethodKind::Sg
    }

    fn set_environment(&mut self, env: &Environment) -> Result<PrepareStats, GpuError> {
        let t0 = Instant::now();
        let lighting = SgLighting::new(env, self.baked.bake.diffuse.order, self.prefilter_size);
        let mut stats = PrepareStats {
            environment_ms: t0.elapsed().as_secs_f64() * 1e3,
            ..Default::default()
        };
        let t1 = Instant::now();
        self.raster.set_environment(self.gpu, env, &mut stats)?;
        let pre = lighting.prefiltered();
        let levels = pre.levels();
        let n = levels[0].size;
        if levels.len() > MAX_CHAIN_LEVELS
            || levels
                .iter()
                .enumerate()
                .any(|(k, l)| l.size != (n >> k).max(1))
        {
            return Err(GpuError::Unsupported(format!(
                "a prefiltered chain whose level sizes are not a mip chain ({:?})",
                levels.iter().map(|l| l.size).collect::<Vec<_>>()
            )));
        }
        let gpu = self.gpu;
        let tex = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("prefiltered chain"),
            size: wgpu::Extent3d {
                width: n as u32,
                height: n as u32,
                depth_or_array_layers: 6,
            },
            mip_level_count: levels.len() as u32,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: pipeline::COLOR,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        for (k, l) in levels.iter().enumerate() {
            // Cube layout (face, row, col) = layer, row, col.
            let texels: Vec<[f32; 4]> = pre.level_texels(k).iter().map(|&t| v4(t, 1.0)).collect();
            let bytes: &[u8] = bytemuck::cast_slice(&texels);
            gpu.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &tex,
                    mip_level: k as u32,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                bytes,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(l.size as u32 * 16),
                    rows_per_image: Some(l.size as u32),
                },
                wgpu::Extent3d {
                    width: l.size as u32,
                    height: l.size as u32,
                    depth_or_array_layers: 6,
                },
            );
            stats.bytes_uploaded += bytes.len() as u64;
        }
        let mut ln_lambda = [[0f32; 4]; MAX_CHAIN_LEVELS / 4];
        for (k, l) in levels.iter().enumerate() {
            ln_lambda[k / 4][k % 4] = l.lambda.ln();
        }
        let b = &self.baked.bake;
        let opts = self.renderer.options();
        let params = GpuSgParams {
            lobe_count: self.renderer.lobe_count() as u32,
            direct_count: b.direct.lobe_count as u32,
            indirect_count: b.indirect.as_ref().map_or(0, |l| l.lobe_count) as u32,
            level_count: levels.len() as u32,
            scale: lighting.scale,
            energy_blend: (opts.corners == LobeBlend::Energy) as u32,
            match_lobes: opts.match_corners as u32,
            base_size: n as u32,
            ln_lambda,
            kernel_rate: std::array::from_fn(|j| b.kernel.terms().get(j).map_or(0.0, |t| t.0)),
            kernel_weight: std::array::from_fn(|j| b.kernel.terms().get(j).map_or(0.0, |t| t.1)),
            env_from_world: {
                let m = lighting.env_from_world.transpose();
                [m.x_axis, m.y_axis, m.z_axis].map(|r| v4(r, 0.0))
            },
            half_vector: (b.domain == SgDomain::HalfVector) as u32,
            pad: [0; 3],
        };
        gpu.write(
            &self.params,
            bytemuck::bytes_of(&params),
            &mut stats.bytes_uploaded,
        );
        let view = tex.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let m = &self.mesh;
        let group = bind(
            gpu,
            "sg",
            &self.layout,
            &[
                self.raster.camera.as_entire_binding(),
                m.positions.as_entire_binding(),
                m.indices.as_entire_binding(),
                self.lobes.as_entire_binding(),
                self.diffuse.as_entire_binding(),
                wgpu::BindingResource::TextureView(&view),
                self.params.as_entire_binding(),
                self.perms.as_entire_binding(),
                self.half_table.as_entire_binding(),
            ],
        );
        gpu.check()?;
        stats.gpu_ms = t1.elapsed().as_secs_f64() * 1e3;
        self.prepared = Some((lighting, group));
        Ok(stats)
    }

    fn render(&mut self, camera: &Camera, opts: &FrameOptions) -> Result<GpuOutput, GpuError> {
        let Some((lighting, group)) = self.prepared.as_ref() else {
            return Err(GpuError::Unsupported(
                "set_environment before render".into(),
            ));
        };
        Raster::check(self.gpu, camera, opts)?;
        let mut stats = FrameStats::default();
        // The per-vertex pass on the CPU, as the CPU frame's.
        let t0 = Instant::now();
        let frame = self.renderer.prepare(lighting, Vec3::from(camera.origin));
        // Half-vector bakes: each lobe's unit mass at its vertex's view rides in `w`.
        let masses = &frame.masses;
        let lobes: Vec<GpuLobe> = frame
            .lobes
            .iter()
            .enumerate()
            .map(|(i, l)| GpuLobe {
                axis_sharpness: v4(l.axis, l.sharpness),
                amplitude: v4(l.amplitude, masses.get(i).copied().unwrap_or(0.0)),
            })
            .collect();
        let diffuse: Vec<[f32; 4]> = frame.diffuse.iter().map(|&d| v4(d, 1.0)).collect();
        self.gpu.write(
            &self.lobes,
            bytemuck::cast_slice(&lobes),
            &mut stats.bytes_uploaded,
        );
        self.gpu.write(
            &self.diffuse,
            bytemuck::cast_slice(&diffuse),
            &mut stats.bytes_uploaded,
        );
        stats.cpu_ms = t0.elapsed().as_secs_f64() * 1e3;
        // Match each triangle's corners once (sg_match.wgsl), then shade.
        let mut enc = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("sg match"),
            });
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.matching);
            pass.set_bind_group(0, &self.match_group, &[]);
            let (x, y, _) = dispatch_2d(self.mesh.triangles);
            pass.dispatch_workgroups(x, y, 1);
        }
        stats.passes += 1;
        self.gpu.queue.submit([enc.finish()]);
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
        let b = &self.baked.bake;
        format!(
            "GPU SG: {} vertices, {} direct + {} indirect lobes, diffuse SH order {}",
            self.baked.scene.mesh.vertex_count(),
            b.direct.lobe_count,
            b.indirect.as_ref().map_or(0, |l| l.lobe_count),
            b.diffuse.order
        )
    }
}
