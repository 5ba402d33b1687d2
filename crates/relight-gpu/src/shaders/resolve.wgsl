// Box filter of the n x n samples of each pixel (relight_render::raster's supersampling:
// sub-pixel centres (j + (a + 0.5) / n, i + (b + 0.5) / n), equal weights). The sample
// target holds radiance and alpha = 1 where covered, 0 where not: the mean alpha is the
// pixel's coverage, and uncovered samples add black (no background on the GPU yet).

// Twin of relight_gpu::layout::GpuResolveParams.
struct ResolveParams {
    supersample: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var samples: texture_2d<f32>;
@group(0) @binding(1) var<uniform> params: ResolveParams;

@vertex
fn vs(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the screen.
    let x = f32((vi << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vi & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let n = params.supersample;
    let base = vec2<u32>(pos.xy) * n;
    var sum = vec4<f32>(0.0);
    for (var b = 0u; b < n; b++) {
        for (var a = 0u; a < n; a++) {
            sum += textureLoad(samples, base + vec2<u32>(a, b), 0);
        }
    }
    return sum * (1.0 / f32(n * n));
}
