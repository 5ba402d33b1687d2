// Shared by every method's raster pass (prepended to sh.wgsl, hybrid.wgsl, sg.wgsl).
//
// Conventions (relight_render::raster's, so GPU and CPU frames match pixel for pixel):
// * Camera: Mitsuba's perspective sensor. Camera space x right, y up, z forward.
// * Clip space: (x / tan_half_x, y / tan_half_y, near, z): NDC is the CPU rasteriser's
//   (sx, sy), depth is near / z (reverse depth, infinite far plane), so a larger depth is
//   nearer (depth test GREATER, cleared to 0) and primitives are clipped at z = near, as the
//   CPU clips at 1e-5 x the farthest vertex.
// * Ties go to the triangle drawn first (GREATER fails on equal depth), as on the CPU.
// * Per-vertex values are interpolated perspective-correctly (the GPU default), as the CPU's
//   `c = (sum w_i c_i / z_i) / (sum w_i / z_i)`.

// Twin of relight_gpu::layout::GpuCamera.
struct Camera {
    origin: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    forward: vec4<f32>,
    tan_half: vec2<f32>,
    near: f32,
    pad: f32,
}

fn project(cam: Camera, p: vec3<f32>) -> vec4<f32> {
    let d = p - cam.origin.xyz;
    let c = vec3<f32>(dot(d, cam.right.xyz), dot(d, cam.up.xyz), dot(d, cam.forward.xyz));
    return vec4<f32>(c.x / cam.tan_half.x, c.y / cam.tan_half.y, cam.near, c.z);
}

// The corner's unit barycentric vector: interpolated, it gives the fragment's
// perspective-correct corner weights (the CPU G-buffer's `Corner::Barycentric`).
fn corner_bary(corner: u32) -> vec3<f32> {
    return vec3<f32>(f32(corner == 0u), f32(corner == 1u), f32(corner == 2u));
}
