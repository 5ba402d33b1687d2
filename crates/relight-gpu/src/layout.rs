//! Every structure the GPU reads, defined once: `#[repr(C)]`, [`bytemuck::Pod`], its size
//! asserted at compile time, and its WGSL twin named in its doc comment. A field added here
//! must be added to the twin in the same order (WGSL's `vec4<f32>` is 16 bytes, 16-aligned;
//! scalars are 4 bytes; every struct here is a multiple of 16 bytes so arrays of it need no
//! padding on either side). The tests parse the shaders with naga (wgpu's WGSL front-end)
//! and check every twin's size and field offsets against the Rust struct.

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
    /// 1 when the frame draws the background ([`GpuBackground`]). The shader does not read
    /// it: the entry point (`fs_background` or `fs`) decides, so a frame without background
    /// runs none of its code.
    pub background: u32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}
const _: () = assert!(size_of::<GpuResolveParams>() == 16);

/// The environment behind the objects (`relight_scene::scene::Environment::radiance`: the
/// map's bilinear `eval` of `env_from_world * dir`, times `scale`). The texels go in a
/// storage buffer, row-major as `EnvMap::texels`.
/// WGSL twin: `Background` in `shaders/resolve.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuBackground {
    /// Columns of `env_from_world` (w unused).
    pub env_from_world: [[f32; 4]; 3],
    /// 0: latlong, 1: cube (`EnvLayout`; probes are not drawn on the GPU yet).
    pub map_layout: u32,
    /// Map width (latlong width, cube face size).
    pub width: u32,
    /// Map height (latlong height, 6 x face size).
    pub height: u32,
    /// Radiance scale.
    pub scale: f32,
}
const _: () = assert!(size_of::<GpuBackground>() == 64);

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
    /// Irradiance at normal incidence (RGB); w unused (the least depth comes from the map's
    /// pyramid).
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

/// Most levels of a shadow map's min pyramid (a 16384-texel map has 14).
pub const MAX_PYRAMID_LEVELS: usize = 16;

/// The hybrid shading pass's parameters. WGSL twin: `HybridParams` in `shaders/hybrid.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuHybridParams {
    /// Lights (and shadow-map layers).
    pub light_count: u32,
    /// Levels of each map's min pyramid (level 1 first).
    pub level_count: u32,
    /// Floats of one layer's pyramid.
    pub layer_stride: u32,
    /// Padding.
    pub pad: u32,
    /// Per level: entries per side, offset in the layer's pyramid (then two unused).
    pub levels: [[u32; 4]; MAX_PYRAMID_LEVELS],
}
const _: () = assert!(size_of::<GpuHybridParams>() == 16 + 16 * MAX_PYRAMID_LEVELS);

/// One level of the shadow maps' min pyramid to build.
/// WGSL twin: `PyramidLevel` in `shaders/shadow_pyramid.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuPyramidLevel {
    /// Entries per side of the level read.
    pub src_size: u32,
    /// Entries per side of the level written.
    pub dst_size: u32,
    /// Offset of the level read in a layer's pyramid.
    pub src_offset: u32,
    /// Offset of the level written.
    pub dst_offset: u32,
    /// Floats of one layer's pyramid.
    pub layer_stride: u32,
    /// 1: read the depth texture (level 1), 0: the pyramid.
    pub from_texture: u32,
    /// Padding.
    pub pad: [u32; 2],
}
const _: () = assert!(size_of::<GpuPyramidLevel>() == 32);

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

/// The SG matching pass's parameters. WGSL twin: `MatchParams` in `shaders/sg_match.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuMatchParams {
    /// Triangles of the mesh.
    pub triangle_count: u32,
    /// Invocations per row of the 2D dispatch (`workgroups_x * 64`).
    pub row_stride: u32,
    /// Padding.
    pub pad: [u32; 2],
}
const _: () = assert!(size_of::<GpuMatchParams>() == 16);

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
    /// The lobe kernel's rates `c_j` (`relight_sphere::sg_kernel`; unused terms 0).
    pub kernel_rate: [f32; 4],
    /// The lobe kernel's weights `w_j` (unused terms 0: skipped).
    pub kernel_weight: [f32; 4],
    /// Rows of `env_from_world` (`w` unused): the fragment's view into the map frame.
    pub env_from_world: [[f32; 4]; 3],
    /// 1: lobes in the half-vector domain (`sg_half.wgsl`), 0: in the light direction.
    pub half_vector: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}
const _: () = assert!(size_of::<GpuSgParams>() == 32 + 4 * MAX_CHAIN_LEVELS + 32 + 64);

/// The `cuts` shading pass's parameters. WGSL twin: `CutsParams` in `shaders/cuts.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuCutsParams {
    /// Nodes of the illumination cut.
    pub light_len: u32,
    /// 0: the cuts hold binary visibility (`CutFunction::Visibility`), 1: visibility times
    /// the cosine (`CutFunction::VisibilityCosine`).
    pub cosine_in_cuts: u32,
    /// Offset (in `u32` words) of the vertex cuts' `(index, leftleaf)` pairs in the cuts
    /// buffer (the `vertex_count + 1` offsets come first).
    pub keys_base: u32,
    /// Offset (in `u32` words) of the packed quantised means (two `u16` per word).
    pub values_base: u32,
    /// Offset (in `u32` words) of the triangles' material indices.
    pub materials_base: u32,
    /// Padding.
    pub pad: [u32; 3],
}
const _: () = assert!(size_of::<GpuCutsParams>() == 32);

/// One node of the illumination cut. WGSL twin: `LightNode` in `shaders/cuts.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLightNode {
    /// Cluster mean `<L O>` (RGB; w unused).
    pub value: [f32; 4],
    /// Post-order index.
    pub index: u32,
    /// Leftmost leaf.
    pub leftleaf: u32,
    /// Padding.
    pub pad: [u32; 2],
}
const _: () = assert!(size_of::<GpuLightNode>() == 32);

/// Kinds of [`GpuCutsMaterial`]: Lambert.
pub const CUTS_LAMBERT: u32 = 0;
/// The GGX conductor.
pub const CUTS_GGX_CONDUCTOR: u32 = 1;
/// The GGX plastic.
pub const CUTS_GGX_PLASTIC: u32 = 2;
/// The glTF metallic-roughness BRDF (`relight_scene::material::gltf_pbr`).
pub const CUTS_GLTF: u32 = 3;

/// A material of the `cuts` frame. WGSL twin: `CutsMaterial` in `shaders/cuts.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuCutsMaterial {
    /// Lambert's albedo, the conductor's or the plastic's specular reflectance (w unused);
    /// glTF's base colour, with `metallic` in w.
    pub color: [f32; 4],
    /// The plastic's diffuse reflectance (w unused).
    pub diffuse: [f32; 4],
    /// [`CUTS_LAMBERT`], [`CUTS_GGX_CONDUCTOR`], [`CUTS_GGX_PLASTIC`] or [`CUTS_GLTF`].
    pub kind: u32,
    /// GGX roughness (glTF: `alpha = roughness^2`, [`relight_scene::material::gltf_pbr::alpha`]).
    pub alpha: f32,
    /// 1: averaged over each merged cluster's spread (the CPU's `spreads`: spread on and
    /// the material not purely diffuse).
    pub spread: u32,
    /// The plastic's index of refraction.
    pub ior: f32,
    /// The plastic's first entry in the transmittance tables (`TABLE_RES` entries).
    pub table: u32,
    /// The plastic's internal reflectance `Fdr` (`PlasticTables::internal_reflectance`).
    pub internal_reflectance: f32,
    /// Padding.
    pub pad: [u32; 2],
}
const _: () = assert!(size_of::<GpuCutsMaterial>() == 64);

/// Each Rust struct against the WGSL that declares its twin, parsed by naga (wgpu's own
/// front-end) and laid out as the GPU sees it.
#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::offset_of;

    const COMMON: &str = include_str!("shaders/common.wgsl");
    const LIGHT: &str = include_str!("shaders/light.wgsl");

    /// Size and member offsets of struct `name` in the WGSL `source`, as naga lays it out for
    /// the GPU.
    fn wgsl_layout(source: &str, name: &str) -> (u32, Vec<u32>) {
        let module = naga::front::wgsl::parse_str(source)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("layout");
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no struct {name}"));
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!("{name} is not a struct");
        };
        (
            layouter[handle].size,
            members.iter().map(|m| m.offset).collect(),
        )
    }

    /// Every Rust struct against its WGSL twin: same size, same field offsets in order.
    #[test]
    fn every_struct_matches_its_wgsl_twin() {
        let sh_shade = include_str!("shaders/sh_shade.wgsl");
        let resolve_src = [COMMON, include_str!("shaders/resolve.wgsl")].concat();
        let resolve = resolve_src.as_str();
        let hybrid = [COMMON, LIGHT, include_str!("shaders/hybrid.wgsl")].concat();
        let lobes = include_str!("shaders/sg_lobes.wgsl");
        let sg = crate::sg::shading_source();
        let sg_match = [lobes, include_str!("shaders/sg_match.wgsl")].concat();
        let o = |v: &[usize]| v.iter().map(|&x| x as u32).collect::<Vec<u32>>();
        type C = GpuCamera;
        type L = GpuLight;
        type S = GpuSgParams;
        let pyramid = [LIGHT, include_str!("shaders/shadow_pyramid.wgsl")].concat();
        let cuts = [COMMON, include_str!("shaders/cuts.wgsl")].concat();
        let cases: [(&str, &str, usize, Vec<u32>); 13] = [
            (
                &cuts,
                "CutsParams",
                size_of::<GpuCutsParams>(),
                o(&[0, 4, 8, 12, 16, 20, 24, 28]),
            ),
            (
                &cuts,
                "LightNode",
                size_of::<GpuLightNode>(),
                o(&[
                    offset_of!(GpuLightNode, value),
                    offset_of!(GpuLightNode, index),
                    offset_of!(GpuLightNode, leftleaf),
                    offset_of!(GpuLightNode, pad),
                ]),
            ),
            (
                &cuts,
                "CutsMaterial",
                size_of::<GpuCutsMaterial>(),
                o(&[
                    offset_of!(GpuCutsMaterial, color),
                    offset_of!(GpuCutsMaterial, diffuse),
                    offset_of!(GpuCutsMaterial, kind),
                    offset_of!(GpuCutsMaterial, alpha),
                    offset_of!(GpuCutsMaterial, spread),
                    offset_of!(GpuCutsMaterial, ior),
                    offset_of!(GpuCutsMaterial, table),
                    offset_of!(GpuCutsMaterial, internal_reflectance),
                    offset_of!(GpuCutsMaterial, pad),
                ]),
            ),
            (
                &sg_match,
                "MatchParams",
                size_of::<GpuMatchParams>(),
                o(&[0, 4, 8, 12]),
            ),
            (
                &sg,
                "Camera",
                size_of::<C>(),
                o(&[
                    offset_of!(C, origin),
                    offset_of!(C, right),
                    offset_of!(C, up),
                    offset_of!(C, forward),
                    offset_of!(C, tan_half),
                    offset_of!(C, near),
                    offset_of!(C, pad),
                ]),
            ),
            (
                sh_shade,
                "ShParams",
                size_of::<GpuShParams>(),
                o(&[0, 4, 8, 12]),
            ),
            (
                resolve,
                "ResolveParams",
                size_of::<GpuResolveParams>(),
                o(&[0, 4, 8, 12]),
            ),
            (
                resolve,
                "Background",
                size_of::<GpuBackground>(),
                o(&[
                    offset_of!(GpuBackground, env_from_world),
                    offset_of!(GpuBackground, map_layout),
                    offset_of!(GpuBackground, width),
                    offset_of!(GpuBackground, height),
                    offset_of!(GpuBackground, scale),
                ]),
            ),
            (
                &hybrid,
                "Light",
                size_of::<L>(),
                o(&[
                    offset_of!(L, dir),
                    offset_of!(L, u),
                    offset_of!(L, v),
                    offset_of!(L, center),
                    offset_of!(L, power),
                    offset_of!(L, kernel),
                    offset_of!(L, taps),
                    offset_of!(L, size),
                    offset_of!(L, area),
                ]),
            ),
            (
                &hybrid,
                "HybridParams",
                size_of::<GpuHybridParams>(),
                o(&[0, 4, 8, 12, 16]),
            ),
            (
                &pyramid,
                "PyramidLevel",
                size_of::<GpuPyramidLevel>(),
                o(&[0, 4, 8, 12, 16, 20, 24, 28]),
            ),
            (
                &sg,
                "Lobe",
                size_of::<GpuLobe>(),
                o(&[
                    offset_of!(GpuLobe, axis_sharpness),
                    offset_of!(GpuLobe, amplitude),
                ]),
            ),
            (
                &sg,
                "SgParams",
                size_of::<S>(),
                o(&[
                    offset_of!(S, lobe_count),
                    offset_of!(S, direct_count),
                    offset_of!(S, indirect_count),
                    offset_of!(S, level_count),
                    offset_of!(S, scale),
                    offset_of!(S, energy_blend),
                    offset_of!(S, match_lobes),
                    offset_of!(S, base_size),
                    offset_of!(S, ln_lambda),
                    offset_of!(S, kernel_rate),
                    offset_of!(S, kernel_weight),
                    offset_of!(S, env_from_world),
                    offset_of!(S, half_vector),
                    offset_of!(S, pad),
                    offset_of!(S, pad) + 4,
                    offset_of!(S, pad) + 8,
                ]),
            ),
        ];
        for (source, name, size, offsets) in cases {
            let (wsize, woffsets) = wgsl_layout(source, name);
            assert_eq!(wsize as usize, size, "size of {name}");
            assert_eq!(woffsets, offsets, "field offsets of {name}");
        }
    }

    /// The shadow pass's shader (no Rust struct of its own) parses with the shared snippet.
    #[test]
    fn every_shader_parses() {
        for (name, src) in [
            (
                "shadow",
                [LIGHT, include_str!("shaders/shadow.wgsl")].concat(),
            ),
            ("sh", [COMMON, include_str!("shaders/sh.wgsl")].concat()),
        ] {
            naga::front::wgsl::parse_str(&src)
                .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
        }
    }
}
