// The `sg` frame's matching pass: once per triangle and frame, the permutation of each
// corner's lobes that matches the reference corner's (the corner of lowest vertex index;
// thesis 3.4, relight_render::shade_sg::match_corners: the assignment minimising
// |mu - mu'|^2 + 0.1 (ln lambda - ln lambda')^2, brute force up to three lobes, greedy
// beyond; identities when matching is off or a component has one lobe). The permutation
// depends only on the three corners' lobes, so the shading pass reads it instead of matching
// per sample. Packed 4 bits per slot, 8 slots per word, 2 words per (triangle, component,
// corner).

// Twin of relight_gpu::layout::GpuMatchParams.
struct MatchParams {
    triangle_count: u32,
    row_stride: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: SgParams;
@group(0) @binding(1) var<uniform> mparams: MatchParams;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read> lobes: array<Lobe>;
@group(0) @binding(4) var<storage, read_write> perms: array<u32>;

fn get_lobe(x: u32, k: u32) -> Lobe {
    return lobes[x * params.lobe_count + k];
}

@compute @workgroup_size(64)
fn match_triangles(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x + gid.y * mparams.row_stride;
    if (t >= mparams.triangle_count) {
        return;
    }
    let id = vec3<u32>(indices[3u * t], indices[3u * t + 1u], indices[3u * t + 2u]);
    // Reference corner: the lowest vertex index (first of equals).
    var r = 0u;
    if (id.y < id[r]) {
        r = 1u;
    }
    if (id.z < id[r]) {
        r = 2u;
    }
    var start = 0u;
    for (var comp = 0u; comp < 2u; comp++) {
        var count = params.direct_count;
        if (comp == 1u) {
            count = params.indirect_count;
        }
        for (var c = 0u; c < 3u; c++) {
            var p: array<u32, 10>;
            for (var k = 0u; k < MAX_LOBES; k++) {
                p[k] = k;
            }
            if (params.match_lobes != 0u && count > 1u && c != r) {
                p = match_corners(id[r], id[c], start, count);
            }
            var w0 = 0u;
            var w1 = 0u;
            for (var k = 0u; k < 8u; k++) {
                w0 |= p[k] << (4u * k);
            }
            for (var k = 8u; k < MAX_LOBES; k++) {
                w1 |= p[k] << (4u * (k - 8u));
            }
            let base = ((t * 2u + comp) * 3u + c) * 2u;
            perms[base] = w0;
            perms[base + 1u] = w1;
        }
        start += count;
    }
}
