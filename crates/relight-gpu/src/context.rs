//! The device: adapter choice (Vulkan only), buffer uploads that count their bytes, and the
//! read-back of a frame.

use crate::GpuError;
use std::sync::{Arc, Mutex};

/// A Vulkan device and its queue, shared by every frame made from it.
pub struct Gpu {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    limits: wgpu::Limits,
    /// The first error wgpu reported since the last [`Gpu::check`].
    error: Arc<Mutex<Option<String>>>,
}

/// Preference of adapter types when no name is asked for: real GPUs first, then the CPU
/// driver (lavapipe).
fn rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

impl Gpu {
    /// Open a Vulkan adapter: the one whose name contains `$WGPU_ADAPTER_NAME` (case
    /// insensitive) if that is set, else the first real GPU, else a CPU driver (Mesa's
    /// lavapipe). Only the Vulkan back-end is built in.
    ///
    /// # Errors
    /// [`GpuError::NoAdapter`] when the Vulkan loader or a driver is missing (the message
    /// says what to install), or no adapter has the name asked for; [`GpuError::Device`] when
    /// the device cannot be opened.
    pub fn new() -> Result<Gpu, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        desc.backends = wgpu::Backends::VULKAN;
        let instance = wgpu::Instance::new(desc);
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
        let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
        let wanted = std::env::var("WGPU_ADAPTER_NAME").ok();
        let adapter = match &wanted {
            Some(w) => {
                let w = w.to_lowercase();
                adapters
                    .into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&w))
                    .ok_or_else(|| {
                        GpuError::NoAdapter(format!(
                            "WGPU_ADAPTER_NAME={w} matches none of the adapters {names:?}"
                        ))
                    })?
            }
            None => adapters
                .into_iter()
                .min_by_key(|a| rank(a.get_info().device_type))
                .ok_or_else(|| {
                    GpuError::NoAdapter(
                        "the Vulkan loader (libvulkan1) or every Vulkan driver is missing".into(),
                    )
                })?,
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("relight-gpu"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        let error = Arc::new(Mutex::new(None));
        let sink = error.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut slot = sink.lock().unwrap_or_else(|p| p.into_inner());
            slot.get_or_insert_with(|| e.to_string());
        }));
        Ok(Gpu {
            device,
            queue,
            info,
            limits,
            error,
        })
    }

    /// The adapter's name (e.g. `llvmpipe (LLVM 19.1.7, 256 bits)` for lavapipe).
    pub fn adapter_name(&self) -> &str {
        &self.info.name
    }

    /// Whether the adapter is a CPU driver (lavapipe): its timings are a CPU rasteriser's.
    pub fn is_cpu(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The device's limits.
    pub fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }

    /// The first error wgpu reported since the last call, as an `Err`.
    pub(crate) fn check(&self) -> Result<(), GpuError> {
        let mut slot = self.error.lock().unwrap_or_else(|p| p.into_inner());
        match slot.take() {
            Some(e) => Err(GpuError::Render(e)),
            None => Ok(()),
        }
    }

    /// A storage (or other `usage`) buffer holding `data`, at least 16 bytes; its size is
    /// added to `*uploaded`.
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] when `data` exceeds the device's storage binding size.
    pub(crate) fn buffer(
        &self,
        label: &str,
        data: &[u8],
        usage: wgpu::BufferUsages,
        uploaded: &mut u64,
    ) -> Result<wgpu::Buffer, GpuError> {
        if usage.contains(wgpu::BufferUsages::STORAGE)
            && data.len() as u64 > self.limits.max_storage_buffer_binding_size
        {
            return Err(GpuError::Unsupported(format!(
                "{label}: {} bytes exceed the device's storage buffer limit of {} bytes",
                data.len(),
                self.limits.max_storage_buffer_binding_size
            )));
        }
        let size = (data.len() as u64).max(16).next_multiple_of(4);
        let b = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.write(&b, data, uploaded);
        Ok(b)
    }

    /// Write `data` at the start of `b`, counting its bytes.
    pub(crate) fn write(&self, b: &wgpu::Buffer, data: &[u8], uploaded: &mut u64) {
        if data.is_empty() {
            return;
        }
        if data.len().is_multiple_of(4) {
            self.queue.write_buffer(b, 0, data);
        } else {
            let mut v = data.to_vec();
            v.resize(data.len().next_multiple_of(4), 0);
            self.queue.write_buffer(b, 0, &v);
        }
        *uploaded += data.len() as u64;
    }

    /// A shader module from WGSL pieces concatenated (shared snippets first).
    pub(crate) fn shader(&self, label: &str, parts: &[&str]) -> wgpu::ShaderModule {
        self.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(parts.concat().into()),
            })
    }

    /// Submit `encoder`, copy `texture` (Rgba32Float, `w x h`) to the host and wait.
    pub(crate) fn read_rgba32f(
        &self,
        mut encoder: wgpu::CommandEncoder,
        texture: &wgpu::Texture,
        w: u32,
        h: u32,
    ) -> Result<Vec<[f32; 4]>, GpuError> {
        let row = (w as u64 * 16).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT as u64);
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back"),
            size: row * h as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row as u32),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        self.queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .map_err(|e| GpuError::Render(e.to_string()))?;
        self.check()?;
        rx.recv()
            .map_err(|e| GpuError::Render(e.to_string()))?
            .map_err(|e| GpuError::Render(e.to_string()))?;
        let view = staging
            .get_mapped_range(..)
            .map_err(|e| GpuError::Render(e.to_string()))?;
        let mut out = Vec::with_capacity((w * h) as usize);
        for y in 0..h as usize {
            let r = &view[y * row as usize..y * row as usize + w as usize * 16];
            out.extend(
                bytemuck::pod_collect_to_vec::<u8, f32>(r)
                    .chunks_exact(4)
                    .map(|c| [c[0], c[1], c[2], c[3]]),
            );
        }
        drop(view);
        staging.unmap();
        Ok(out)
    }
}
