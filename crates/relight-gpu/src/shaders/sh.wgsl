// The `sh` frame's raster pass: Gouraud shading of the per-vertex PRT radiance (computed by
// sh_shade.wgsl once per environment), interpolated perspective-correctly as
// relight_render::raster::render_with does. Alpha = 1 marks covered samples (coverage).

@group(0) @binding(0) var<uniform> cam: Camera;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read> radiance: array<vec4<f32>>;

struct VOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) color: vec3<f32>,
}

@vertex
fn vs(@builtin(vertex_index) vi: u32) -> VOut {
    let v = indices[vi];
    var o: VOut;
    o.pos = project(cam, positions[v].xyz);
    o.color = radiance[v].xyz;
    return o;
}

@fragment
fn fs(i: VOut) -> @location(0) vec4<f32> {
    return vec4<f32>(i.color, 1.0);
}
