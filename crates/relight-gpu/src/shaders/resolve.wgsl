// Box filter of the n x n samples of each pixel (relight_render::raster's supersampling:
// sub-pixel centres (j + (a + 0.5) / n, i + (b + 0.5) / n), equal weights). The sample
// target holds radiance and alpha = 1 where covered, 0 where not: the mean alpha is the
// pixel's coverage. Uncovered samples add black, or with the background on the environment's
// radiance through the sample (relight_render::raster::resolve: `env.radiance(dir_at(x, y))`,
// the map's bilinear eval of env_from_world dir, times scale; common.wgsl's Camera).

// Twin of relight_gpu::layout::GpuResolveParams.
struct ResolveParams {
    supersample: u32,
    background: u32,
    width: u32,
    height: u32,
}

// Twin of relight_gpu::layout::GpuBackground.
struct Background {
    env_from_world: array<vec4<f32>, 3>,
    map_layout: u32,
    width: u32,
    height: u32,
    scale: f32,
}

const PI: f32 = 3.14159265358979;

@group(0) @binding(0) var samples: texture_2d<f32>;
@group(0) @binding(1) var<uniform> params: ResolveParams;
@group(0) @binding(2) var<uniform> cam: Camera;
@group(0) @binding(3) var<uniform> bg: Background;
@group(0) @binding(4) var<storage, read> texels: array<vec4<f32>>;

@vertex
fn vs(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the screen.
    let x = f32((vi << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vi & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

fn texel(i: u32) -> vec3<f32> {
    return texels[i].xyz;
}

// relight_sphere::latlong::bilinear (Mitsuba's latlong: u = atan2(x, -z) / 2 pi, row j at
// theta = pi j / (H - 1), columns wrap).
fn eval_latlong(d: vec3<f32>) -> vec3<f32> {
    let w = i32(bg.width);
    let h = bg.height;
    var u = atan2(d.x, -d.z) * (0.5 / PI);
    if (u < 0.0) {
        u += 1.0;
    }
    if (u >= 1.0) {
        u -= 1.0;
    }
    let v = acos(clamp(d.y, -1.0, 1.0)) * (1.0 / PI);
    let x = u * f32(w) - 0.5;
    let y = v * f32(h - 1u);
    let xf = floor(x);
    let fx = x - xf;
    let c0 = u32(((i32(xf) % w) + w) % w);
    var c1 = c0 + 1u;
    if (c1 == u32(w)) {
        c1 = 0u;
    }
    let r0 = min(u32(max(floor(y), 0.0)), h - 2u);
    let fy = clamp(y - f32(r0), 0.0, 1.0);
    let r1 = r0 + 1u;
    let ww = u32(w);
    return texel(r0 * ww + c0) * ((1.0 - fx) * (1.0 - fy)) + texel(r0 * ww + c1) * (fx * (1.0 - fy))
        + texel(r1 * ww + c0) * ((1.0 - fx) * fy) + texel(r1 * ww + c1) * (fx * fy);
}

// relight_sphere::cubemap::bilinear (faces +X -X +Y -Y +Z -Z, clamped at each face's edges).
fn eval_cube(d: vec3<f32>) -> vec3<f32> {
    let a = abs(d);
    var face = 0u;
    var sc = 0.0;
    var tc = 0.0;
    var ma = 0.0;
    if (a.x >= a.y && a.x >= a.z) {
        if (d.x >= 0.0) {
            face = 0u; sc = -d.z; tc = -d.y;
        } else {
            face = 1u; sc = d.z; tc = -d.y;
        }
        ma = a.x;
    } else if (a.y >= a.z) {
        if (d.y >= 0.0) {
            face = 2u; sc = d.x; tc = d.z;
        } else {
            face = 3u; sc = d.x; tc = -d.z;
        }
        ma = a.y;
    } else {
        if (d.z >= 0.0) {
            face = 4u; sc = d.x; tc = -d.y;
        } else {
            face = 5u; sc = -d.x; tc = -d.y;
        }
        ma = a.z;
    }
    var inv = 0.0;
    if (ma > 0.0) {
        inv = 1.0 / ma;
    }
    let n = bg.width;
    let nf = f32(n);
    let x = clamp(0.5 * (sc * inv + 1.0) * nf - 0.5, 0.0, nf - 1.0);
    let y = clamp(0.5 * (tc * inv + 1.0) * nf - 0.5, 0.0, nf - 1.0);
    let lo = max(i32(n) - 2, 0);
    let c0 = u32(min(i32(x), lo));
    let r0 = u32(min(i32(y), lo));
    let fx = min(x - f32(c0), 1.0);
    let fy = min(y - f32(r0), 1.0);
    let c1 = min(c0 + 1u, n - 1u);
    let r1 = min(r0 + 1u, n - 1u);
    let base = face * n * n;
    return texel(base + r0 * n + c0) * ((1.0 - fx) * (1.0 - fy)) + texel(base + r0 * n + c1) * (fx * (1.0 - fy))
        + texel(base + r1 * n + c0) * ((1.0 - fx) * fy) + texel(base + r1 * n + c1) * (fx * fy);
}

// The environment's radiance arriving through continuous pixel position (x, y)
// (CameraFrame::dir_at, Environment::radiance).
fn background(x: f32, y: f32) -> vec3<f32> {
    let sx = 2.0 * x / f32(params.width) - 1.0;
    let sy = 1.0 - 2.0 * y / f32(params.height);
    let dir = normalize(cam.forward.xyz + cam.right.xyz * (sx * cam.tan_half.x) + cam.up.xyz * (sy * cam.tan_half.y));
    let m = bg.env_from_world;
    let d = m[0].xyz * dir.x + m[1].xyz * dir.y + m[2].xyz * dir.z;
    if (bg.map_layout == 0u) {
        return eval_latlong(d) * bg.scale;
    }
    return eval_cube(d) * bg.scale;
}

// The box filter of pixel `px`, uncovered samples from the background if `background`.
fn resolve(px: vec2<u32>, background_on: bool) -> vec4<f32> {
    let n = params.supersample;
    let base = px * n;
    var sum = vec4<f32>(0.0);
    for (var b = 0u; b < n; b++) {
        for (var a = 0u; a < n; a++) {
            let s = textureLoad(samples, base + vec2<u32>(a, b), 0);
            if (s.w > 0.0 || !background_on) {
                sum += s;
            } else {
                let x = f32(px.x) + (f32(a) + 0.5) / f32(n);
                let y = f32(px.y) + (f32(b) + 0.5) / f32(n);
                sum += vec4<f32>(background(x, y), 0.0);
            }
        }
    }
    return sum * (1.0 / f32(n * n));
}

// Two entry points, two pipelines: lavapipe ran the background's code for every sample of a
// frame without background when one shader chose at run time (+300 ms at 1280 x 720).
@fragment
fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    return resolve(vec2<u32>(pos.xy), false);
}

@fragment
fn fs_background(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    return resolve(vec2<u32>(pos.xy), true);
}
