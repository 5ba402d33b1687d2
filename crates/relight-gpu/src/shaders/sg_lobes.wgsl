// Spherical Gaussian lobes of the `sg` frame (Green 2005, thesis 2.3, 3.4;
// relight_render::shade_sg and its blend.rs): the lobe and parameter structs, the lobe
// integral, the blends and the corner matching. Prepended to sg.wgsl (shading) and
// sg_match.wgsl (per-triangle matching); each of those defines `get_lobe(vertex, slot)` over
// its own binding of the per-vertex lobes.

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
    kernel_rate: vec4<f32>,
    kernel_weight: vec4<f32>,
    env_from_world: array<vec4<f32>, 3>,
    half_vector: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
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

// relight_render::shade_sg::kernel_integral_f32: sum_j w_j unit_integral(c_j lambda) over the
// lobe kernel's terms (relight_sphere::sg_kernel; terms of weight 0 are unused).
fn kernel_integral(lambda: f32) -> f32 {
    var s = 0.0;
    for (var j = 0u; j < 4u; j++) {
        let w = params.kernel_weight[j];
        if (w != 0.0) {
            s += w * unit_integral(params.kernel_rate[j] * lambda);
        }
    }
    return s;
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
    let e0 = l0.amplitude.xyz * kernel_integral(l0.axis_sharpness.w);
    let e1 = l1.amplitude.xyz * kernel_integral(l1.axis_sharpness.w);
    let e2 = l2.amplitude.xyz * kernel_integral(l2.axis_sharpness.w);
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
    return Lobe(vec4<f32>(axis, sharp), vec4<f32>(energy / kernel_integral(sharp), 0.0));
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

