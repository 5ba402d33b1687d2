// Per-vertex SH relighting, the per-environment work of `sh` and of hybrid's SH part
// (relight_render::shade_sh; Sloan, Kautz & Snyder 2002, eq. 4 / thesis 4.2):
//   mono transfer:  L_o(v) = rho_v sum_i T_v,i L_i
//   RGB transfer:   L_o(v)_c = sum_i T_v,i,c L_i,c      (albedo baked in)
// `light` is the environment's RGB SH, rotated to the world frame and scaled (only n^2 used);
// the transfer layout is relight_bake::sh::ShTransfer's: data[(v n^2 + i) channels + c].

// Twin of relight_gpu::layout::GpuShParams.
struct ShParams {
    vertex_count: u32,
    coeff_count: u32,
    channels: u32,
    row_stride: u32,
}

@group(0) @binding(0) var<uniform> params: ShParams;
@group(0) @binding(1) var<storage, read> transfer: array<f32>;
@group(0) @binding(2) var<storage, read> light: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> albedo: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> radiance: array<vec4<f32>>;

@compute @workgroup_size(64)
fn shade(@builtin(global_invocation_id) id: vec3<u32>) {
    let v = id.x + id.y * params.row_stride;
    if (v >= params.vertex_count) {
        return;
    }
    let n2 = params.coeff_count;
    var sum = vec3<f32>(0.0);
    if (params.channels == 1u) {
        let base = v * n2;
        for (var i = 0u; i < n2; i++) {
            sum += transfer[base + i] * light[i].xyz;
        }
        sum *= albedo[v].xyz;
    } else {
        let base = v * n2 * 3u;
        for (var i = 0u; i < n2; i++) {
            let t = vec3<f32>(transfer[base + 3u * i], transfer[base + 3u * i + 1u], transfer[base + 3u * i + 2u]);
            sum += t * light[i].xyz;
        }
    }
    radiance[v] = vec4<f32>(sum, 1.0);
}
