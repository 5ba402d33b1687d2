// The `sg` frame's shading pass (Green 2005, thesis 2.3 and 3.2; relight_render::shade_sg).
// The per-vertex pass (view location on the icosahedron, blend of the three nearest views'
// lobes, axes rotated to the map frame, diffuse SH) runs on the CPU
// (relight_render::shade_sg::SgRenderer::prepare) and is uploaded each frame; per pixel:
// * the three corners' lobes are matched to the reference corner's (the corner of lowest
//   vertex index; thesis 3.4, relight_render::shade_sg::match_corners: the assignment
//   minimising |mu - mu'|^2 + 0.1 (ln lambda - ln lambda')^2, brute force up to three lobes,
//   greedy beyond) and blended with the fragment's perspective-correct weights (the per-pixel
//   interpolation of the paper's figure 2-2): by energy (blend3_energy, the default) or
//   linearly (blend3, the thesis');
// * each lobe is integrated against the lighting with one trilinear fetch of the
//   Gaussian-prefiltered cube chain (eq. 2.7, figure 3-2's shader):
//   L_o = sum_k a_k unit_integral(lambda_k) P(mu_k, lambda_k) scale,
//   plus the Gouraud-interpolated diffuse radiance.
// The chain is a 6-layer texture with one mip level per chain level; fetches are manual
// bilinear textureLoads with the CPU's rules (texel centres at (i + 0.5) / n, clamped at each
// face's edges, no filtering across faces), linear in ln lambda between the two levels that
// bracket it (SgLighting::sample).

const TWO_PI: f32 = 6.28318530717959;
const MAX_LOBES: u32 = 10u;

// Twin of relight_gpu::layout::GpuLobe.
struct Lobe {
    axis_sharpness: vec4<f32>,
    amplitude: vec4<f32>,
}

// Twin of relight_gpu::layout::GpuSgParams.
struct SgParams {
    lobe_count: u32,
    direct_count: u32,
    indirect_count: u32,
    level_count: u32,
    scale: f32,
    energy_blend: u32,
    match_lobes: u32,
    base_size: u32,
    ln_lambda: array<vec4<f32>, 4>,
}

@group(0) @binding(0) var<uniform> cam: Camera;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read> lobes: array<Lobe>;
@group(0) @binding(4) var<storage, read> diffuse: array<vec4<f32>>;
@group(0) @binding(5) var chain: texture_2d_array<f32>;
@group(0) @binding(6) var<uniform> params: SgParams;

struct VOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) bary: vec3<f32>,
    @location(1) @interpolate(flat) tri: u32,
}

@vertex
fn vs(@builtin(vertex_index) vi: u32) -> VOut {
    var o: VOut;
    o.pos = project(cam, positions[indices[vi]].xyz);
    o.bary = corner_bary(vi % 3u);
    o.tri = vi / 3u;
    return o;
}

// relight_render::shade_sg::unit_integral_f32: 2 pi (1 - exp(-2 lambda)) / lambda.
fn unit_integral(lambda: f32) -> f32 {
    if (lambda > 9.0) {
        return TWO_PI / lambda;
    } else if (lambda > 1e-6) {
        let x = -2.0 * lambda;
        var em1 = exp(x) - 1.0;
        if (abs(x) < 1e-3) {
            em1 = x * (1.0 + x * (0.5 + x / 6.0));
        }
        return -TWO_PI * em1 / lambda;
    }
    return 2.0 * TWO_PI;
}

fn ln_lambda(k: u32) -> f32 {
    return params.ln_lambda[k / 4u][k % 4u];
}

// relight_sphere::cubemap::dir_to_face_st: face index and (s, t) in [0, 1]^2.
fn face_st(dir: vec3<f32>) -> vec3<f32> {
    let a = abs(dir);
    var face = 0.0;
    var sc = 0.0;
    var tc = 0.0;
    var ma = 0.0;
    if (a.x >= a.y && a.x >= a.z) {
        if (dir.x >= 0.0) {
            face = 0.0; sc = -dir.z; tc = -dir.y;
        } else {
            face = 1.0; sc = dir.z; tc = -dir.y;
        }
        ma = a.x;
    } else if (a.y >= a.z) {
        if (dir.y >= 0.0) {
            face = 2.0; sc = dir.x; tc = dir.z;
        } else {
            face = 3.0; sc = dir.x; tc = -dir.z;
        }
        ma = a.y;
    } else {
        if (dir.z >= 0.0) {
            face = 4.0; sc = dir.x; tc = -dir.y;
        } else {
            face = 5.0; sc = -dir.x; tc = -dir.y;
        }
        ma = a.z;
    }
    var inv = 0.0;
    if (ma > 0.0) {
        inv = 1.0 / ma;
    }
    return vec3<f32>(face, 0.5 * (sc * inv + 1.0), 0.5 * (tc * inv + 1.0));
}

// Bilinear fetch in level k (SgLighting::level_eval).
fn level_eval(k: u32, fst: vec3<f32>) -> vec3<f32> {
    // Face size of level k from the uniform: lavapipe's textureDimensions of a mip level of
    // this array texture returned the base level's size.
    let n = max(i32(params.base_size >> k), 1);
    let nf = f32(n);
    let x = clamp(fst.y * nf - 0.5, 0.0, nf - 1.0);
    let y = clamp(fst.z * nf - 0.5, 0.0, nf - 1.0);
    let c0 = min(i32(x), max(n - 2, 0));
    let r0 = min(i32(y), max(n - 2, 0));
    let fx = min(x - f32(c0), 1.0);
    let fy = min(y - f32(r0), 1.0);
    let c1 = min(c0 + 1, n - 1);
    let r1 = min(r0 + 1, n - 1);
    let face = i32(fst.x);
    let lk = i32(k);
    let a00 = textureLoad(chain, vec2<i32>(c0, r0), face, lk).xyz;
    let a01 = textureLoad(chain, vec2<i32>(c1, r0), face, lk).xyz;
    let a10 = textureLoad(chain, vec2<i32>(c0, r1), face, lk).xyz;
    let a11 = textureLoad(chain, vec2<i32>(c1, r1), face, lk).xyz;
    return (a00 * (1.0 - fx) + a01 * fx) * (1.0 - fy) + (a10 * (1.0 - fx) + a11 * fx) * fy;
}

// SgLighting::sample: trilinear in (face st, ln lambda).
fn sample_chain(dir: vec3<f32>, lambda: f32) -> vec3<f32> {
    let fst = face_st(dir);
    let x = log(max(lambda, 1e-30));
    let last = params.level_count - 1u;
    if (x >= ln_lambda(0u)) {
        return level_eval(0u, fst);
    }
    if (x <= ln_lambda(last)) {
        return level_eval(last, fst);
    }
    var k = 0u;
    while (ln_lambda(k + 1u) >= x) {
        k += 1u;
    }
    let t = (ln_lambda(k) - x) / (ln_lambda(k) - ln_lambda(k + 1u));
    return level_eval(k, fst) * (1.0 - t) + level_eval(k + 1u, fst) * t;
}

fn get_lobe(x: u32, k: u32) -> Lobe {
    return lobes[x * params.lobe_count + k];
}

fn normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    if (l > 1e-30) {
        return v / l;
    }
    return fallback;
}

fn heaviest(w: vec3<f32>) -> u32 {
    if (w.x >= w.y && w.x >= w.z) {
        return 0u;
    } else if (w.y >= w.z) {
        return 1u;
    }
    return 2u;
}

// blend3: axes summed and renormalised, sharpness and amplitude linear.
fn blend_linear(l0: Lobe, l1: Lobe, l2: Lobe, w: vec3<f32>) -> Lobe {
    var axes = array<vec3<f32>, 3>(l0.axis_sharpness.xyz, l1.axis_sharpness.xyz, l2.axis_sharpness.xyz);
    let axis = normalize_or(axes[0] * w.x + axes[1] * w.y + axes[2] * w.z, axes[heaviest(w)]);
    let sharp = l0.axis_sharpness.w * w.x + l1.axis_sharpness.w * w.y + l2.axis_sharpness.w * w.z;
    let amp = l0.amplitude.xyz * w.x + l1.amplitude.xyz * w.y + l2.amplitude.xyz * w.z;
    return Lobe(vec4<f32>(axis, sharp), vec4<f32>(amp, 0.0));
}

// blend3_energy: energies linear, axis and sharpness weighted by each corner's energy.
fn blend_energy(l0: Lobe, l1: Lobe, l2: Lobe, w: vec3<f32>) -> Lobe {
    let e0 = l0.amplitude.xyz * unit_integral(l0.axis_sharpness.w);
    let e1 = l1.amplitude.xyz * unit_integral(l1.axis_sharpness.w);
    let e2 = l2.amplitude.xyz * unit_integral(l2.axis_sharpness.w);
    let energy = e0 * w.x + e1 * w.y + e2 * w.z;
    var u = vec3<f32>(w.x * (e0.x + e0.y + e0.z), w.y * (e1.x + e1.y + e1.z), w.z * (e2.x + e2.y + e2.z));
    let total = u.x + u.y + u.z;
    if (!(total > 0.0)) {
        var b = blend_linear(l0, l1, l2, w);
        b.amplitude = vec4<f32>(0.0);
        return b;
    }
    u = u / total;
    var axes = array<vec3<f32>, 3>(l0.axis_sharpness.xyz, l1.axis_sharpness.xyz, l2.axis_sharpness.xyz);
    let axis = normalize_or(axes[0] * u.x + axes[1] * u.y + axes[2] * u.z, axes[heaviest(u)]);
    let sharp = l0.axis_sharpness.w * u.x + l1.axis_sharpness.w * u.y + l2.axis_sharpness.w * u.z;
    return Lobe(vec4<f32>(axis, sharp), vec4<f32>(energy / unit_integral(sharp), 0.0));
}

fn lobe_distance(a: Lobe, b: Lobe) -> f32 {
    let dl = log(a.axis_sharpness.w) - log(b.axis_sharpness.w);
    let d = a.axis_sharpness.xyz - b.axis_sharpness.xyz;
    return dot(d, d) + 0.1 * dl * dl;
}

// match_corners: the permutation p (slot k takes other[p[k]]) best matching corner `other`'s
// lobes [start, start + n) to the reference corner's; the identity wins ties.
fn match_corners(reference: u32, other: u32, start: u32, n: u32) -> array<u32, 10> {
    var p: array<u32, 10>;
    for (var k = 0u; k < MAX_LOBES; k++) {
        p[k] = k;
    }
    var d: array<array<f32, 10>, 10>;
    for (var k = 0u; k < n; k++) {
        let a = get_lobe(reference, start + k);
        for (var j = 0u; j < n; j++) {
            d[k][j] = lobe_distance(a, get_lobe(other, start + j));
        }
    }
    if (n == 2u) {
        if (d[0][1] + d[1][0] < d[0][0] + d[1][1]) {
            p[0] = 1u;
            p[1] = 0u;
        }
    } else if (n == 3u) {
        var perms = array<vec3<u32>, 6>(
            vec3<u32>(0u, 1u, 2u), vec3<u32>(0u, 2u, 1u), vec3<u32>(1u, 0u, 2u),
            vec3<u32>(1u, 2u, 0u), vec3<u32>(2u, 0u, 1u), vec3<u32>(2u, 1u, 0u));
        var best = d[0][0] + d[1][1] + d[2][2];
        var bi = 0u;
        for (var i = 1u; i < 6u; i++) {
            let q = perms[i];
            let c = d[0][q.x] + d[1][q.y] + d[2][q.z];
            if (c < best) {
                best = c;
                bi = i;
            }
        }
        p[0] = perms[bi].x;
        p[1] = perms[bi].y;
        p[2] = perms[bi].z;
    } else if (n > 3u) {
        var used: array<bool, 10>;
        for (var k = 0u; k < n; k++) {
            var bj = k;
            var bd = 3.0e38;
            var found = false;
            for (var j = 0u; j < n; j++) {
                if (!used[j] && (!found || d[k][j] < bd)) {
                    bd = d[k][j];
                    bj = j;
                    found = true;
                }
            }
            used[bj] = true;
            p[k] = bj;
        }
    }
    return p;
}

@fragment
fn fs(f: VOut) -> @location(0) vec4<f32> {
    let b = f.bary / (f.bary.x + f.bary.y + f.bary.z);
    let id = vec3<u32>(indices[3u * f.tri], indices[3u * f.tri + 1u], indices[3u * f.tri + 2u]);
    var sum = diffuse[id.x].xyz * b.x + diffuse[id.y].xyz * b.y + diffuse[id.z].xyz * b.z;
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
        var p: array<array<u32, 10>, 3>;
        for (var c = 0u; c < 3u; c++) {
            for (var k = 0u; k < MAX_LOBES; k++) {
                p[c][k] = k;
            }
            if (params.match_lobes != 0u && count > 1u && c != r) {
                p[c] = match_corners(id[r], id[c], start, count);
            }
        }
        for (var k = 0u; k < count; k++) {
            let l0 = get_lobe(id.x, start + p[0][k]);
            let l1 = get_lobe(id.y, start + p[1][k]);
            let l2 = get_lobe(id.z, start + p[2][k]);
            var lobe: Lobe;
            if (params.energy_blend != 0u) {
                lobe = blend_energy(l0, l1, l2, b);
            } else {
                lobe = blend_linear(l0, l1, l2, b);
            }
            let amp = lobe.amplitude.xyz;
            let lambda = lobe.axis_sharpness.w;
            if (any(amp != vec3<f32>(0.0)) && lambda > 0.0) {
                sum += amp * sample_chain(lobe.axis_sharpness.xyz, lambda) * (params.scale * unit_integral(lambda));
            }
        }
        start += count;
    }
    return vec4<f32>(sum, 1.0);
}
