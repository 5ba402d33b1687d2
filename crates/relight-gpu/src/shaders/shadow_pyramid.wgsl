// Hybrid's min pyramid of each shadow map (relight_render::shadowmap::ShadowMap's min-max
// pyramid, min half: the PCSS blocker search shrinks its square with it). Level l >= 1 has
// ceil(size / 2^l) entries per side, each the least depth (world units along the light) of
// its 2 x 2 children in level l - 1 (level 0: the depth map; children outside the level and
// empty texels count as "empty", INF). One dispatch per level, the layer in workgroup z.

// Twin of relight_gpu::layout::GpuPyramidLevel.
struct PyramidLevel {
    src_size: u32,
    dst_size: u32,
    src_offset: u32,
    dst_offset: u32,
    layer_stride: u32,
    from_texture: u32,
    pad0: u32,
    pad1: u32,
}

const INF: f32 = 3.0e38;

@group(0) @binding(0) var<uniform> lv: PyramidLevel;
@group(0) @binding(1) var<storage, read> lights: array<Light>;
@group(0) @binding(2) var shadow: texture_depth_2d_array;
@group(0) @binding(3) var<storage, read_write> pyramid: array<f32>;

// World depth of texel (x, y) of layer `layer`'s level below the destination.
fn child(layer: u32, x: u32, y: u32) -> f32 {
    if (lv.from_texture != 0u) {
        let d = textureLoad(shadow, vec2<u32>(x, y), layer, 0);
        if (d >= 1.0) {
            return INF;
        }
        let half = lights[layer].v.w;
        return d * 2.0 * half - half;
    }
    return pyramid[layer * lv.layer_stride + lv.src_offset + y * lv.src_size + x];
}

@compute @workgroup_size(8, 8)
fn build(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= lv.dst_size || gid.y >= lv.dst_size) {
        return;
    }
    var m = INF;
    for (var k = 0u; k < 4u; k++) {
        let cx = 2u * gid.x + (k & 1u);
        let cy = 2u * gid.y + (k >> 1u);
        if (cx < lv.src_size && cy < lv.src_size) {
            m = min(m, child(gid.z, cx, cy));
        }
    }
    pyramid[gid.z * lv.layer_stride + lv.dst_offset + gid.y * lv.dst_size + gid.x] = m;
}
