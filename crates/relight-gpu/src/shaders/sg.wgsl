// The `sg` frame's shading pass (Green 2005, thesis 2.3 and 3.2; relight_render::shade_sg).
// The per-vertex pass (view location on the icosahedron, blend of the three nearest views'
// lobes, axes rotated to the map frame, diffuse SH) runs on the CPU
// (relight_render::shade_sg::SgRenderer::prepare) and is uploaded each frame; per pixel:
// * the three corners' lobes, matched to the reference corner's once per triangle and frame
//   (sg_match.wgsl), are blended with the fragment's perspective-correct weights (the
//   per-pixel interpolation of the paper's figure 2-2): by energy (blend3_energy, the
//   default) or linearly (blend3, the thesis');
// * each lobe is integrated against the lighting with one trilinear fetch of the
//   Gaussian-prefiltered cube chain (eq. 2.7, figure 3-2's shader):
//   L_o = sum_k a_k unit_integral(lambda_k) P(mu_k, lambda_k) scale,
//   plus the Gouraud-interpolated diffuse radiance;
// * half-vector lobes (params.half_vector) are rescaled to keep the corners' integrals
//   (keep_mass) and integrated for the fragment's view with the warp table (sg_half.wgsl).
// The chain is a 6-layer texture with one mip level per chain level; fetches are manual
// bilinear textureLoads with the CPU's rules (texel centres at (i + 0.5) / n, clamped at each
// face's edges, no filtering across faces), linear in ln lambda between the two levels that
// bracket it (SgLighting::sample).

@group(0) @binding(0) var<uniform> cam: Camera;
@group(0) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read> lobes: array<Lobe>;
@group(0) @binding(4) var<storage, read> diffuse: array<vec4<f32>>;
@group(0) @binding(5) var chain: texture_2d_array<f32>;
@group(0) @binding(6) var<uniform> params: SgParams;
// Per triangle, component and corner, the permutation of that corner's lobes (4 bits per
// slot, 8 slots per word; sg_match.wgsl).
@group(0) @binding(7) var<storage, read> perms: array<u32>;

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

@fragment
fn fs(f: VOut) -> @location(0) vec4<f32> {
    let b = f.bary / (f.bary.x + f.bary.y + f.bary.z);
    let id = vec3<u32>(indices[3u * f.tri], indices[3u * f.tri + 1u], indices[3u * f.tri + 2u]);
    var sum = diffuse[id.x].xyz * b.x + diffuse[id.y].xyz * b.y + diffuse[id.z].xyz * b.z;
    // Half-vector lobes (sg_half.wgsl): the fragment's own view in the map frame.
    var v = vec3<f32>(0.0);
    if (params.half_vector != 0u) {
        let p = positions[id.x].xyz * b.x + positions[id.y].xyz * b.y + positions[id.z].xyz * b.z;
        let d = normalize_or(cam.origin.xyz - p, cam.forward.xyz);
        let r = params.env_from_world;
        v = vec3<f32>(dot(r[0].xyz, d), dot(r[1].xyz, d), dot(r[2].xyz, d));
    }
    var start = 0u;
    for (var comp = 0u; comp < 2u; comp++) {
        var count = params.direct_count;
        if (comp == 1u) {
            count = params.indirect_count;
        }
        let base = (f.tri * 2u + comp) * 6u;
        for (var k = 0u; k < count; k++) {
            let w = k / 8u;
            let shift = (k % 8u) * 4u;
            let l0 = get_lobe(id.x, start + ((perms[base + w] >> shift) & 15u));
            let l1 = get_lobe(id.y, start + ((perms[base + 2u + w] >> shift) & 15u));
            let l2 = get_lobe(id.z, start + ((perms[base + 4u + w] >> shift) & 15u));
            var lobe: Lobe;
            if (params.energy_blend != 0u) {
                lobe = blend_energy(l0, l1, l2, b);
            } else {
                lobe = blend_linear(l0, l1, l2, b);
            }
            var amp = lobe.amplitude.xyz;
            let lambda = lobe.axis_sharpness.w;
            if (params.half_vector != 0u) {
                // keep_mass: the corners' integrals, each seen from its vertex's view (its
                // unit-amplitude mass in amplitude.w, relight_render's vertex_masses).
                let unit = unit_lobe_mass(lambda, dot(v, lobe.axis_sharpness.xyz));
                if (unit > 0.0) {
                    let want = l0.amplitude.xyz * (l0.amplitude.w * b.x)
                        + l1.amplitude.xyz * (l1.amplitude.w * b.y)
                        + l2.amplitude.xyz * (l2.amplitude.w * b.z);
                    amp = clamp(want / unit, amp * 0.25, amp * 4.0);
                }
                if (any(amp != vec3<f32>(0.0)) && lambda > 0.0) {
                    sum += integrate_half_vector(lobe.axis_sharpness.xyz, lambda, amp, v);
                }
            } else if (any(amp != vec3<f32>(0.0)) && lambda > 0.0) {
                // One prefiltered fetch per term of the lobe kernel (relight_sphere::sg_kernel).
                for (var j = 0u; j < 4u; j++) {
                    let w = params.kernel_weight[j];
                    if (w != 0.0) {
                        let lj = params.kernel_rate[j] * lambda;
                        sum += (w * amp) * sample_chain(lobe.axis_sharpness.xyz, lj) * (params.scale * unit_integral(lj));
                    }
                }
            }
        }
        start += count;
    }
    return vec4<f32>(sum, 1.0);
}
