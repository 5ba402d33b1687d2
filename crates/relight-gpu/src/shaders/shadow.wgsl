// Hybrid's shadow pass (thesis 4.4, Fig. 4.6: one depth map per extracted light): an
// orthographic depth map of the mesh along each light, one render pass per layer, the light
// chosen by the instance index. NDC (s / size 2 - 1, 1 - t / size 2) puts texel row i = floor(t)
// at framebuffer row i, as relight_render::shadowmap's rows.

@group(0) @binding(0) var<storage, read> lights: array<Light>;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;

@vertex
fn vs(@builtin(vertex_index) vi: u32, @builtin(instance_index) li: u32) -> @builtin(position) vec4<f32> {
    let l = lights[li];
    let q = to_map(l, positions[indices[vi]].xyz);
    let n = f32(l.size);
    let half = l.v.w;
    return vec4<f32>(q.x / n * 2.0 - 1.0, 1.0 - q.y / n * 2.0, (q.z + half) / (2.0 * half), 1.0);
}
