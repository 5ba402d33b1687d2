// The `hybrid` frame's shading pass (thesis 4.4, Fig. 4.6; relight_render::hybrid):
//   L = L_prt + albedo / pi * sum_i E_i f(n . l_i, a_i) V_i
// * L_prt: per-vertex PRT radiance of the environment's SH part (sh_shade.wgsl), and the
//   albedo, both interpolated with the fragment's perspective-correct weights.
// * f: max(0, n.l) for the thesis' point lights; for area lights the clipped-cap cosine
//   (Snyder 1996; Lagarde & de Rousiers 2014, eq. 19), normalised to 1 at normal incidence.
// * V_i: the light's shadow map (shadow.wgsl) with the receiver-plane depth bias (Isidoro
//   2006) and PCF (Reeves, Salesin & Cook 1987) or PCSS (Fernando 2005) for area lights.
// Shading normal: interpolated vertex normal (the geometric one where it vanishes); the bias
// uses the geometric normal; one-sided surfaces, as relight_render::hybrid.
//
// The PCSS blocker search shrinks its square with each map's min pyramid
// (shadow_pyramid.wgsl), as the CPU does with the min half of its min-max pyramid. The CPU's
// early outs on that pyramid return the same values as the full filters and are not needed.

const PI: f32 = 3.14159265358979;
const INF: f32 = 3.0e38;
const MAX_SLOPE: f32 = 8.0;
const EXACT_MAX_WIDTH: f32 = 12.0;
const SEARCH_TAPS: u32 = 5u;

// Twin of relight_gpu::layout::GpuHybridParams.
struct HybridParams {
    light_count: u32,
    level_count: u32,
    layer_stride: u32,
    pad: u32,
    levels: array<vec4<u32>, 16>,
}

@group(0) @binding(0) var<uniform> cam: Camera;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;
@group(0) @binding(4) var<storage, read> radiance: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> albedo: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> lights: array<Light>;
@group(0) @binding(7) var shadow: texture_depth_2d_array;
@group(0) @binding(8) var<uniform> params: HybridParams;
@group(0) @binding(9) var<storage, read> pyramid: array<f32>;

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

// relight_render::hybrid::cap_cosine (through relight_sphere::decompose::cap_cosine).
fn cap_cosine(cos_theta: f32, cap_radius: f32) -> f32 {
    let c = clamp(cos_theta, -1.0, 1.0);
    let s2 = pow(sin(cap_radius), 2.0);
    if (c * c >= s2 || s2 < 1e-12) {
        return max(c, 0.0);
    }
    let r = min(cap_radius, PI / 2.0 - 1e-6);
    let rs2 = pow(sin(r), 2.0);
    let s = sqrt(1.0 - c * c);
    let x = sqrt(1.0 / rs2 - 1.0);
    let y = clamp(-x * c / s, -1.0, 1.0);
    let sy = s * sqrt(1.0 - y * y);
    let e = max((c * acos(y) - x * sy) * rs2 + atan(sy / x), 0.0);
    let solid = 4.0 * PI * pow(sin(0.5 * r), 2.0);
    let per_solid_angle = e / solid;
    let cap_solid = 4.0 * PI * pow(sin(0.5 * cap_radius), 2.0);
    return per_solid_angle * cap_solid / (PI * s2);
}

struct Receiver {
    s: f32,
    t: f32,
    z: f32,
    gs: f32,
    gt: f32,
    bias: f32,
}

fn receiver(l: Light, p: vec3<f32>, ng: vec3<f32>) -> Receiver {
    let q = to_map(l, p);
    let nu = dot(ng, l.u.xyz);
    let nv = dot(ng, l.v.xyz);
    let nd = dot(ng, l.dir.xyz);
    var gs = 0.0;
    var gt = 0.0;
    if (abs(nd) > 1e-6) {
        gs = clamp(nu / nd, -MAX_SLOPE, MAX_SLOPE);
        gt = clamp(nv / nd, -MAX_SLOPE, MAX_SLOPE);
    }
    let steep = min(sqrt(gs * gs + gt * gt), MAX_SLOPE);
    let texel = l.u.w;
    return Receiver(q.x, q.y, q.z, gs * texel, gt * texel, l.center.w * texel * (1.0 + steep));
}

fn depth_at(r: Receiver, j: i32, i: i32) -> f32 {
    return r.z + r.gs * (f32(j) + 0.5 - r.s) + r.gt * (f32(i) + 0.5 - r.t);
}

fn texel_depth(l: Light, layer: u32, j: i32, i: i32) -> f32 {
    let n = i32(l.size);
    if (j < 0 || i < 0 || j >= n || i >= n) {
        return INF;
    }
    let d = textureLoad(shadow, vec2<i32>(j, i), layer, 0);
    if (d >= 1.0) {
        return INF;
    }
    let half = l.v.w;
    return d * 2.0 * half - half;
}

fn ifloor(x: f32) -> i32 {
    return i32(floor(x));
}

// Least depth stored in layer `layer`'s map (the top of its pyramid).
fn min_depth(layer: u32) -> f32 {
    let top = params.levels[params.level_count - 1u];
    return pyramid[layer * params.layer_stride + top.y];
}

// Least stored depth over a superset of the texels floor(s - half) ..= floor(s + half) (same
// in t): at most 4 entries of the pyramid level whose blocks are at least as wide as the span
// (ShadowMap::block_bounds, its `lo`).
fn block_lo(layer: u32, r: Receiver, half: f32) -> f32 {
    let s0 = ifloor(r.s - half);
    let s1 = ifloor(r.s + half);
    let t0 = ifloor(r.t - half);
    let t1 = ifloor(r.t + half);
    let span = max(max(s1 - s0 + 1, t1 - t0 + 1), 1);
    let l = max(32u - countLeadingZeros(u32(span - 1)), 1u);
    if (l - 1u >= params.level_count) {
        return min_depth(layer);
    }
    let level = params.levels[l - 1u];
    let m = i32(level.x);
    let base = layer * params.layer_stride + level.y;
    var lo = INF;
    for (var i = t0 >> l; i <= (t1 >> l); i++) {
        for (var j = s0 >> l; j <= (s1 >> l); j++) {
            if (j >= 0 && i >= 0 && j < m && i < m) {
                lo = min(lo, pyramid[base + u32(i * m + j)]);
            }
        }
    }
    return lo;
}

// Exact box filter of `width` texels: each texel's test weighted by its overlap.
fn box_exact(l: Light, layer: u32, r: Receiver, width: f32) -> f32 {
    let s0 = r.s - 0.5 * width;
    let s1 = r.s + 0.5 * width;
    let t0 = r.t - 0.5 * width;
    let t1 = r.t + 0.5 * width;
    var lit = 0.0;
    var total = 0.0;
    for (var i = ifloor(t0); i <= ifloor(t1); i++) {
        let wi = max(min(t1, f32(i) + 1.0) - max(t0, f32(i)), 0.0);
        for (var j = ifloor(s0); j <= ifloor(s1); j++) {
            let w = wi * max(min(s1, f32(j) + 1.0) - max(s0, f32(j)), 0.0);
            total += w;
            if (texel_depth(l, layer, j, i) >= depth_at(r, j, i) - r.bias) {
                lit += w;
            }
        }
    }
    if (total > 0.0) {
        return min(lit / total, 1.0);
    }
    return 1.0;
}

// Wellons' lowbias32, as relight_render::shadowmap::hash.
fn hash(x0: u32) -> u32 {
    var x = x0;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    return x ^ (x >> 16u);
}

// taps x taps stratified point taps jittered per receiver texel.
fn box_jittered(l: Light, layer: u32, r: Receiver, width: f32, taps: u32) -> f32 {
    let ti = u32(ifloor(r.t));
    let seed = hash(u32(ifloor(r.s)) ^ ((ti << 16u) | (ti >> 16u)));
    var lit = 0u;
    for (var a = 0u; a < taps; a++) {
        for (var b = 0u; b < taps; b++) {
            let h = hash(seed ^ ((a * taps + b) * 0x9e3779b9u));
            let ja = f32(h & 0xffffu) / 65536.0;
            let jb = f32(h >> 16u) / 65536.0;
            let s = r.s + width * ((f32(a) + ja) / f32(taps) - 0.5);
            let t = r.t + width * ((f32(b) + jb) / f32(taps) - 0.5);
            let j = ifloor(s);
            let i = ifloor(t);
            if (texel_depth(l, layer, j, i) >= depth_at(r, j, i) - r.bias) {
                lit += 1u;
            }
        }
    }
    return f32(lit) / f32(taps * taps);
}

fn visibility(l: Light, layer: u32, p: vec3<f32>, ng: vec3<f32>) -> f32 {
    let r = receiver(l, p, ng);
    if (l.area == 0u) {
        return box_exact(l, layer, r, l.kernel);
    }
    let texel = l.u.w;
    let tan_a = tan(min(l.dir.w, 1.5));
    // Blocker search over the widest possible penumbra (Fernando 2005): start with the
    // nearest geometry of the whole map, then shrink with the nearest geometry inside the
    // current square (sound: any relevant blocker lies inside every square).
    var reach = min(max(r.z - min_depth(layer), 0.0) * tan_a / texel, 64.0);
    for (var it = 0; it < 4; it++) {
        let lo = block_lo(layer, r, max(reach, 0.5 * l.kernel));
        let next = min(max(r.z - lo, 0.0) * tan_a / texel, reach);
        if (next > 0.9 * reach) {
            break;
        }
        reach = next;
    }
    let search = max(reach, 0.5 * l.kernel);
    let n = min(SEARCH_TAPS, u32(ceil(2.0 * search)) + 1u);
    var sum = 0.0;
    var count = 0u;
    for (var a = 0u; a < n; a++) {
        for (var b = 0u; b < n; b++) {
            let ds = search * (2.0 * f32(a) / f32(n - 1u) - 1.0);
            let dt = search * (2.0 * f32(b) / f32(n - 1u) - 1.0);
            let j = ifloor(r.s + ds);
            let i = ifloor(r.t + dt);
            let gap = depth_at(r, j, i) - texel_depth(l, layer, j, i);
            if (gap > r.bias) {
                sum += gap;
                count += 1u;
            }
        }
    }
    if (count == 0u) {
        return 1.0;
    }
    let penumbra = 2.0 * (sum / f32(count)) * tan_a / texel;
    let width = min(max(penumbra, l.kernel), 2.0 * search);
    if (width <= EXACT_MAX_WIDTH) {
        return box_exact(l, layer, r, width);
    }
    return box_jittered(l, layer, r, width, l.taps);
}

@fragment
fn fs(f: VOut) -> @location(0) vec4<f32> {
    let b = f.bary / (f.bary.x + f.bary.y + f.bary.z);
    let ia = indices[3u * f.tri];
    let ib = indices[3u * f.tri + 1u];
    let ic = indices[3u * f.tri + 2u];
    let pa = positions[ia].xyz;
    let pb = positions[ib].xyz;
    let pc = positions[ic].xyz;
    let p = pa * b.x + pb * b.y + pc * b.z;
    let gn = cross(pb - pa, pc - pa);
    let gl = length(gn);
    var ng = vec3<f32>(0.0);
    if (gl > 1e-30) {
        ng = gn / gl;
    }
    let sn = normals[ia].xyz * b.x + normals[ib].xyz * b.y + normals[ic].xyz * b.z;
    let sl = length(sn);
    var n = ng;
    if (sl > 1e-30) {
        n = sn / sl;
    }
    let prt = radiance[ia].xyz * b.x + radiance[ib].xyz * b.y + radiance[ic].xyz * b.z;
    let rho = albedo[ia].xyz * b.x + albedo[ib].xyz * b.y + albedo[ic].xyz * b.z;
    var direct = vec3<f32>(0.0);
    for (var i = 0u; i < params.light_count; i++) {
        let l = lights[i];
        let c = dot(n, l.dir.xyz);
        var g = max(c, 0.0);
        if (l.area != 0u) {
            g = cap_cosine(c, min(l.dir.w, PI / 2.0));
        }
        if (g > 0.0) {
            direct += l.power.xyz * (g * visibility(l, i, p, ng));
        }
    }
    return vec4<f32>(prt + rho / PI * direct, 1.0);
}
