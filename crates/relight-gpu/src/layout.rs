//! Every structure the GPU reads, defined once: `#[repr(C)]`, [`bytemuck::Pod`], its size
//! asserted at compile time, and its WGSL twin named in its doc comment. A field added here
//! must be added to the twin in the same order (WGSL's `vec4<f32>` is 16 bytes, 16-aligned;
//! scalars are 4 bytes; every struct here is a multiple of 16 bytes so arrays of it need no
//! padding on either side).

use bytemuck::{Pod, Zeroable};
use std::mem::size_of;

/// The camera of a frame (Mitsuba's perspective sensor as `relight_scene::camera::CameraFrame`).
/// WGSL twin: `Camera` in `shaders/common.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuCamera {
    /// Eye position (w unused).
    pub origin: [f32; 4],
    /// Unit right (w unused).
    pub right: [f32; 4],
    /// Unit up (w unused).
    pub up: [f32; 4],
    /// Unit forward (w unused).
    pub forward: [f32; 4],
    /// `tan(fov_x / 2)`, `tan(fov_y / 2)`.
    pub tan_half: [f32; 2],
    /// Near plane distance along `forward` (the CPU rasteriser's `1e-5 x` farthest vertex).
    pub near: f32,
    /// Padding.
    pub pad: f32,
}
const _: () = assert!(size_of::<GpuCamera>() == 80);

/// Parameters of the per-vertex SH dot product (`sh` and `hybrid`).
/// WGSL twin: `ShParams` in `shaders/sh_shade.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuShParams {
    /// Vertices.
    pub vertex_count: u32,
    /// Coefficients per channel, `n^2`.
    pub coeff_count: u32,
    /// 1 (mono transfer, albedo applied) or 3 (RGB transfer with albedo).
    pub channels: u32,
    /// Invocations per row of the 2D dispatch (`workgroups_x * 64`).
    pub row_stride: u32,
}
const _: () = assert!(size_of::<GpuShParams>() == 16);

/// The resolve pass's parameters. WGSL twin: `ResolveParams` in `shaders/resolve.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuResolveParams {
    /// Samples per pixel along each axis.
    pub supersample: u32,
    /// Padding.
    pub pad: [u32; 3],
}
const _: () = assert!(size_of::<GpuResolveParams>() == 16);

/// One extracted light of `hybrid` with its shadow map's frame and filter
/// (`relight_render::hybrid::HybridLight` + `relight_render::shadowmap::ShadowMap`).
/// WGSL twin: `Light` in `shaders/hybrid.wgsl` (and `shaders/shadow.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLight {
    /// Unit direction towards the light; w: cap radius (radians).
    pub dir: [f32; 4],
    /// The map's first axis; w: world size of one texel.
    pub u: [f32; 4],
    /// The map's second axis; w: half the map's side (world units).
    pub v: [f32; 4],
    /// Centre of the map; w: depth bias in texels.
    pub center: [f32; 4],
    /// Irradiance at normal incidence (RGB); w: least depth of the mesh along the light.
    pub power: [f32; 4],
    /// PCF kernel width (texels): the filter's minimum width.
    pub kernel: f32,
    /// Jittered taps per axis of wide penumbrae.
    pub taps: u32,
    /// Texels per side of the map.
    pub size: u32,
    /// 1: area light (clipped-cap cosine, PCSS); 0: the thesis' point light (PCF).
    pub area: u32,
}
const _: () = assert!(size_of::<GpuLight>() == 96);

/// The hybrid shading pass's parameters. WGSL twin: `HybridParams` in `shaders/hybrid.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuHybridParams {
    /// Lights (and shadow-map layers).
    pub light_count: u32,
    /// Padding.
    pub pad: [u32; 3],
}
const _: () = assert!(size_of::<GpuHybridParams>() == 16);

/// One spherical Gaussian lobe, axis in the environment map's frame
/// (`relight_sphere::sg::SgLobe`). WGSL twin: `Lobe` in `shaders/sg.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLobe {
    /// Unit axis; w: sharpness `lambda`.
    pub axis_sharpness: [f32; 4],
    /// Amplitude (RGB); w unused.
    pub amplitude: [f32; 4],
}
const _: () = assert!(size_of::<GpuLobe>() == 32);

/// Most levels of the prefiltered chain (a 1024-texel finest level has 11).
pub const MAX_CHAIN_LEVELS: usize = 16;

/// The SG shading pass's parameters. WGSL twin: `SgParams` in `shaders/sg.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuSgParams {
    /// Lobes per vertex (direct + indirect).
    pub lobe_count: u32,
    /// Direct lobes per vertex (first).
    pub direct_count: u32,
    /// Indirect lobes per vertex (after the direct ones).
    pub indirect_count: u32,
    /// Levels of the prefiltered chain (mip levels of the cube texture).
    pub level_count: u32,
    /// Radiance scale of the environment.
    pub scale: f32,
    /// 1: energy blend (`blend3_energy`), 0: linear blend (`blend3`).
    pub energy_blend: u32,
    /// 1: match the corners' lobes before blending (`match_corners`).
    pub match_lobes: u32,
    /// Face size of the finest level (level `k` has `base_size >> k`).
    pub base_size: u32,
    /// `ln lambda` of each level, sharpest first (4 per vec4).
    pub ln_lambda: [[f32; 4]; MAX_CHAIN_LEVELS / 4],
}
const _: () = assert!(size_of::<GpuSgParams>() == 32 + 4 * MAX_CHAIN_LEVELS);
