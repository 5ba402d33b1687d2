// A hybrid light and its shadow map's frame (prepended to shadow.wgsl and hybrid.wgsl).
// Conventions of relight_render::shadowmap: `dir` points towards the light, (u, v) complete
// it, the map covers [-half, half]^2 around `center`; map coordinates (s, t) in texels,
// s = (d.u + half) size / (2 half); depth z = -(p - center).dir, smaller = nearer the light.
// The depth texture stores (z + half) / (2 half) in [0, 1); 1 (the clear value) = empty.

// Twin of relight_gpu::layout::GpuLight.
struct Light {
    dir: vec4<f32>,      // w: cap radius
    u: vec4<f32>,        // w: texel (world size)
    v: vec4<f32>,        // w: half
    center: vec4<f32>,   // w: depth bias, texels
    power: vec4<f32>,    // w: least depth of the mesh
    kernel: f32,
    taps: u32,
    size: u32,
    area: u32,
}

// (s, t, z) of a world point in the light's map.
fn to_map(l: Light, p: vec3<f32>) -> vec3<f32> {
    let d = p - l.center.xyz;
    let half = l.v.w;
    let k = 0.5 * f32(l.size) / half;
    return vec3<f32>((dot(d, l.u.xyz) + half) * k, (dot(d, l.v.xyz) + half) * k, -dot(d, l.dir.xyz));
}
