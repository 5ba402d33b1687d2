// The `cuts` frame's shading pass (Cheslack-Postava et al. 2008; relight_render::shade_cuts,
// its per-sample reference `CutsShader::shade_fragment`). Per sample, as the paper's sec. 4.2
// per-pixel shading: the illumination cut (built on the CPU once per environment or rotation)
// and the three vertex cuts of the sample's triangle are merged in one linear traversal
// (the pseudo-code of sec. 3.2, relight_bake::cuts::merge::merge_cuts), and Eq. 5 is summed
// over the merged clusters C'_k:
//   B = sum_k |C'_k| <L>_k (sum_j b_j <v_j>_k) f(w_k),
// with b_j the perspective-correct barycentric weights, <v_j>_k the corner's quantised mean
// (u16 / 65535) and f the material's BRDF (Material::eval: Lambert, the GGX conductor and
// the GGX plastic) at the cluster's luminance-weighted
// direction w_k, or, for materials that are not purely diffuse when the spread is on, its
// glossy lobe averaged over the cluster's spread by the five-point rule and its diffuse lobe
// at w_k (LightCut::spread_lobes).
//
// Cuts buffer (u32 words): vertex_count + 1 offsets, then (index, leftleaf) pairs from
// params.keys_base, then the quantised means, two u16 per word (low half first), from
// params.values_base, then each triangle's material index from params.materials_base.

const PI: f32 = 3.14159265358979323846;
// relight_scene::material::microfacet::MIN_ALPHA.
const MIN_ALPHA: f32 = 1e-4;
// relight_render::shade_cuts::HORIZON (visibility-cosine cuts lift directions below it).
const HORIZON: f32 = 1e-3;
// relight_scene::material::microfacet::TABLE_RES.
const TABLE_RES: u32 = 64u;

// Twin of relight_gpu::layout::GpuCutsParams.
struct CutsParams {
    light_len: u32,
    cosine_in_cuts: u32,
    keys_base: u32,
    values_base: u32,
    materials_base: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// Twin of relight_gpu::layout::GpuLightNode.
struct LightNode {
    value: vec4<f32>,
    index: u32,
    leftleaf: u32,
    pad: vec2<u32>,
}

// Twin of relight_gpu::layout::GpuCutsMaterial.
struct CutsMaterial {
    color: vec4<f32>,
    diffuse: vec4<f32>,
    kind: u32,
    alpha: f32,
    spread: u32,
    ior: f32,
    table: u32,
    internal_reflectance: f32,
    pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> cam: Camera;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;
// The GGX plastics' transmittance tables (PlasticTables::external_transmittance, TABLE_RES
// entries each, from CutsMaterial::table).
@group(0) @binding(4) var<storage, read> tables: array<f32>;
@group(0) @binding(5) var<storage, read> materials: array<CutsMaterial>;
@group(0) @binding(6) var<storage, read> cuts: array<u32>;
@group(0) @binding(7) var<storage, read> light: array<LightNode>;
// Per tree node (post-order index): the luminance-weighted mean direction (xyz) and, in w,
// cos theta_p of the five-point rule where the cluster spreads (LightCut::spreads), else 1.
@group(0) @binding(8) var<storage, read> dirs: array<vec4<f32>>;
@group(0) @binding(9) var<uniform> params: CutsParams;

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

// relight_sphere::warp::Frame::from_normal (Duff et al. 2017): (s, t) around unit n.
struct Frame {
    s: vec3<f32>,
    t: vec3<f32>,
    n: vec3<f32>,
}

fn frame_from_normal(n: vec3<f32>) -> Frame {
    var sign = 1.0;
    if (n.z < 0.0 || (n.z == 0.0 && bitcast<u32>(n.z) != 0u)) {
        sign = -1.0; // copysign: -0.0 counts as negative
    }
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    var f: Frame;
    f.s = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    f.t = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    f.n = n;
    return f;
}

fn to_local(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f.s), dot(v, f.t), dot(v, f.n));
}

// microfacet::ggx_d.
fn ggx_d(m: vec3<f32>, alpha: f32) -> f32 {
    if (m.z <= 0.0) {
        return 0.0;
    }
    let a = max(alpha, MIN_ALPHA);
    let x = m.x / a;
    let y = m.y / a;
    let s = x * x + y * y + m.z * m.z;
    let d = 1.0 / (PI * a * a * s * s);
    if (d * m.z > 1e-20) {
        return d;
    }
    return 0.0;
}

// microfacet::smith_g1.
fn smith_g1(v: vec3<f32>, m: vec3<f32>, alpha: f32) -> f32 {
    if (dot(v, m) * v.z <= 0.0) {
        return 0.0;
    }
    let a = max(alpha, MIN_ALPHA);
    let ax = a * v.x;
    let ay = a * v.y;
    let xy2 = ax * ax + ay * ay;
    if (xy2 == 0.0) {
        return 1.0;
    }
    let tan2 = xy2 / (v.z * v.z);
    return 2.0 / (1.0 + sqrt(1.0 + tan2));
}

// microfacet::fresnel_dielectric.
fn fresnel_dielectric(cos_in: f32, eta_in: f32) -> f32 {
    var eta = eta_in;
    var cos_i = cos_in;
    if (cos_i < 0.0) {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_t = max(1.0 - cos_i * cos_i, 0.0) / (eta * eta);
    if (sin2_t >= 1.0) {
        return 1.0;
    }
    let cos_t = sqrt(1.0 - sin2_t);
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// PlasticTables::transmittance (microfacet::lerp_table) of the table at `base`.
fn transmittance(base: u32, x: f32) -> f32 {
    let f = clamp(x, 0.0, 1.0) * f32(TABLE_RES - 1u);
    let i = min(u32(f), TABLE_RES - 2u);
    let w = f - f32(i);
    return tables[base + i] * (1.0 - w) + tables[base + i + 1u] * w;
}

// Material::eval (the BSDF times max(0, cos theta_o)) in the shading frame, as its glossy and
// diffuse lobes (MaterialEval::lobes), whose sum it is; the diffuse lobe left at zero unless
// `diffuse` (the five-point rule's ring needs the glossy lobe only).
struct Lobes {
    glossy: vec3<f32>,
    diffuse: vec3<f32>,
}

fn eval_lobes(m: CutsMaterial, wi: vec3<f32>, wo: vec3<f32>, diffuse: bool) -> Lobes {
    if (wi.z <= 0.0 || wo.z <= 0.0) {
        return Lobes(vec3<f32>(0.0), vec3<f32>(0.0));
    }
    if (m.kind == 0u) {
        return Lobes(vec3<f32>(0.0), m.color.xyz * (wo.z / PI));
    }
    if (m.kind == 3u) {
        return gltf_lobes(m, wi, wo, diffuse);
    }
    // ggx_reflection: the half vector and D G / (4 cos theta_i).
    let h = normalize(wi + wo);
    let g = smith_g1(wi, h, m.alpha) * smith_g1(wo, h, m.alpha);
    let dg = ggx_d(h, m.alpha) * g / (4.0 * wi.z);
    if (m.kind == 1u) {
        return Lobes(m.color.xyz * dg, vec3<f32>(0.0));
    }
    // The plastic: the coating's specular term and the diffuse base seen through it.
    let spec = m.color.xyz * (fresnel_dielectric(dot(wi, h), m.ior) * dg);
    if (!diffuse) {
        return Lobes(spec, vec3<f32>(0.0));
    }
    let ti = transmittance(m.table, wi.z);
    let to = transmittance(m.table, wo.z);
    let diff = m.diffuse.xyz / (1.0 - m.internal_reflectance)
        * ((1.0 / PI) / (m.ior * m.ior) * wo.z * ti * to);
    return Lobes(spec, diff);
}

// gltf_pbr::lobes (glTF 2.0 Appendix B): base colour in color.xyz, metallic in color.w,
// alpha = roughness^2. Both directions above the horizon.
fn gltf_lobes(m: CutsMaterial, wi: vec3<f32>, wo: vec3<f32>, diffuse: bool) -> Lobes {
    let h = normalize(wi + wo);
    let vh = clamp(dot(wi, h), 0.0, 1.0);
    let a2 = m.alpha * m.alpha;
    // D: (N.H)^2 (a^2 - 1) + 1 as h_x^2 + h_y^2 + h_z^2 a^2 (no cancellation near N.H = 1).
    let t = (h.x * h.x + h.y * h.y) + h.z * h.z * a2;
    var d = 0.0;
    if (h.z > 0.0) {
        d = a2 / (PI * t * t);
    }
    // Height-correlated Smith visibility V_GGX.
    let vis = 0.5 / (wo.z * sqrt(a2 + (1.0 - a2) * wi.z * wi.z)
        + wi.z * sqrt(a2 + (1.0 - a2) * wo.z * wo.z));
    let spec = d * vis * wo.z;
    let x = 1.0 - vh;
    let x5 = (x * x) * (x * x) * x;
    let f_d = 0.04 + 0.96 * x5;
    let base = m.color.xyz;
    let metallic = m.color.w;
    let f_m = base + (vec3<f32>(1.0) - base) * x5;
    let glossy = (vec3<f32>((1.0 - metallic) * f_d) + f_m * metallic) * spec;
    if (!diffuse) {
        return Lobes(glossy, vec3<f32>(0.0));
    }
    return Lobes(glossy, base * ((1.0 - metallic) * (1.0 - f_d) / PI * wo.z));
}

// shade_cuts::cluster_lobes: the BRDF's lobes towards world direction w.
fn cluster_lobes(m: CutsMaterial, f: Frame, wi: vec3<f32>, w: vec3<f32>, diffuse: bool) -> Lobes {
    var wo = to_local(f, w);
    if (params.cosine_in_cuts == 0u) {
        return eval_lobes(m, wi, wo, diffuse);
    }
    if (wo.z < HORIZON) {
        wo = normalize(vec3<f32>(wo.x, wo.y, HORIZON));
    }
    let l = eval_lobes(m, wi, wo, diffuse);
    return Lobes(l.glossy / wo.z, l.diffuse / wo.z);
}

// LightCut::spread_lobes (or the cluster's direction alone): the glossy lobe averaged by the
// five-point rule, the diffuse lobe at the cluster's direction.
fn cluster_f(m: CutsMaterial, f: Frame, wi: vec3<f32>, node: u32) -> vec3<f32> {
    let d = dirs[node];
    let mu = d.xyz;
    let c = d.w;
    let centre = cluster_lobes(m, f, wi, mu, true);
    if (m.spread == 0u || c >= 1.0) {
        return centre.glossy + centre.diffuse;
    }
    let s = sqrt(max(1.0 - c * c, 0.0));
    let g = frame_from_normal(mu);
    var sum = centre.glossy;
    sum += cluster_lobes(m, f, wi, g.s * s + g.n * c, false).glossy;
    sum += cluster_lobes(m, f, wi, g.s * (-s) + g.n * c, false).glossy;
    sum += cluster_lobes(m, f, wi, g.t * s + g.n * c, false).glossy;
    sum += cluster_lobes(m, f, wi, g.t * (-s) + g.n * c, false).glossy;
    return sum * 0.2 + centre.diffuse;
}

fn vkey(e: u32) -> vec2<u32> {
    let k = params.keys_base + 2u * e;
    return vec2<u32>(cuts[k], cuts[k + 1u]);
}

fn vvalue(e: u32) -> f32 {
    let w = cuts[params.values_base + e / 2u];
    return f32((w >> (16u * (e % 2u))) & 0xffffu) * (1.0 / 65535.0);
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
    let m = materials[cuts[params.materials_base + f.tri]];
    let frame = frame_from_normal(n);
    let wi = to_local(frame, normalize(cam.origin.xyz - p));
    if (wi.z <= 0.0) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0); // one-sided materials, as the path tracer's
    }
    // The merge of sec. 3.2 over four cuts: the light cut (0) and the corners' (1-3). Each
    // cut's current position p, its end e, and its current node's (index, leftleaf).
    var p0 = 0u;
    let e0 = params.light_len;
    var p1 = cuts[ia];
    let e1 = cuts[ia + 1u];
    var p2 = cuts[ib];
    let e2 = cuts[ib + 1u];
    var p3 = cuts[ic];
    let e3 = cuts[ic + 1u];
    var k0 = vec2<u32>(light[0].index, light[0].leftleaf);
    var k1 = vkey(p1);
    var k2 = vkey(p2);
    var k3 = vkey(p3);
    var sum = vec3<f32>(0.0);
    // Each step advances at least one cut: at most the four lengths' sum of steps (a guard
    // against a hang on malformed cuts; the bundle's cuts are validated when read).
    let steps = e0 + (e1 - p1) + (e2 - p2) + (e3 - p3);
    for (var step = 0u; step < steps; step++) {
        let lo = min(min(k0.x, k1.x), min(k2.x, k3.x));
        let hi = max(max(k0.y, k1.y), max(k2.y, k3.y));
        if (hi <= lo) {
            // Every current node overlaps: the deepest one (index lo, leftmost leaf hi) is a
            // merged cluster of (lo - hi) / 2 + 1 lights.
            let v = b.x * vvalue(p1) + b.y * vvalue(p2) + b.z * vvalue(p3);
            if (v > 0.0) {
                let l = light[p0].value.xyz * f32((lo - hi) / 2u + 1u);
                sum += l * v * cluster_f(m, frame, wi, lo);
            }
        }
        // Advance every cut whose current node is the deepest; they all end together.
        var done = false;
        if (k0.x == lo) {
            p0 += 1u;
            done = done || p0 == e0;
            let q = min(p0, e0 - 1u);
            k0 = vec2<u32>(light[q].index, light[q].leftleaf);
        }
        if (k1.x == lo) {
            p1 += 1u;
            done = done || p1 == e1;
            k1 = vkey(min(p1, e1 - 1u));
        }
        if (k2.x == lo) {
            p2 += 1u;
            done = done || p2 == e2;
            k2 = vkey(min(p2, e2 - 1u));
        }
        if (k3.x == lo) {
            p3 += 1u;
            done = done || p3 == e3;
            k3 = vkey(min(p3, e3 - 1u));
        }
        if (done) {
            break;
        }
    }
    return vec4<f32>(sum, 1.0);
}
