// Lobes in the half-vector domain on the GPU (relight_sphere::half_vector, issue 10 item 3):
// a Gaussian term exp(s (m . h(w) - 1)), h(w) = normalize(w + v), integrated as five
// isotropic Gaussians whose axes lie in the plane of incidence, read from the warp table
// (bilinear in ln s and theta_v, weights renormalised to the interpolated mass), one
// prefiltered fetch each; and the mass a blend keeps (relight_render::shade_sg::keep_mass).
// Appended after sg.wgsl's fetches; the grid's constants (HV_*) are prepended by
// relight_gpu::sg from relight_sphere::half_vector, and `hv` holds `table_data()`: the
// masses, then the taps (15 floats per entry).

@group(0) @binding(8) var<storage, read> hv: array<f32>;

struct HvLoc {
    i0: u32,
    j0: u32,
    ws: f32,
    wt: f32,
}

// half_vector::locate.
fn hv_locate(s: f32, c: f32) -> HvLoc {
    let theta = degrees(acos(clamp(c, -1.0, 1.0)));
    let fs = clamp((log(s) - HV_LN_S_MIN) / HV_LN_S_STEP, 0.0, f32(HV_S_COUNT - 1u));
    let ft = clamp(theta / HV_THETA_STEP, 0.0, f32(HV_THETA_COUNT - 1u));
    let i0 = min(u32(fs), HV_S_COUNT - 2u);
    let j0 = min(u32(ft), HV_THETA_COUNT - 2u);
    return HvLoc(i0, j0, fs - f32(i0), ft - f32(j0));
}

fn hv_mass(i: u32, j: u32) -> f32 {
    return hv[i * HV_THETA_COUNT + j];
}

// half_vector::term_mass: int g dw of a term of sharpness s seen at c = v . m.
fn term_mass(s0: f32, c: f32) -> f32 {
    if (c <= 0.0) {
        return 0.0;
    }
    let s = max(s0, HV_S_MIN);
    let l = hv_locate(s, c);
    let a = hv_mass(l.i0, l.j0) * (1.0 - l.wt) + hv_mass(l.i0, l.j0 + 1u) * l.wt;
    let b = hv_mass(l.i0 + 1u, l.j0) * (1.0 - l.wt) + hv_mass(l.i0 + 1u, l.j0 + 1u) * l.wt;
    return (a * (1.0 - l.ws) + b * l.ws) / s;
}

// half_vector::lobe_mass of a unit-amplitude lobe of the bake's kernel.
fn unit_lobe_mass(lambda: f32, c: f32) -> f32 {
    var m = 0.0;
    for (var j = 0u; j < 4u; j++) {
        let w = params.kernel_weight[j];
        if (w != 0.0) {
            m += w * term_mass(params.kernel_rate[j] * lambda, c);
        }
    }
    return m;
}

// Scale-free value q of tap k of entry (i, j).
fn hv_tap(i: u32, j: u32, k: u32, q: u32) -> f32 {
    return hv[HV_MASS_LEN + ((i * HV_THETA_COUNT + j) * HV_TAPS + k) * 3u + q];
}

fn hv_tap_lerp(l: HvLoc, k: u32, q: u32) -> f32 {
    let a = hv_tap(l.i0, l.j0, k, q) * (1.0 - l.wt) + hv_tap(l.i0, l.j0 + 1u, k, q) * l.wt;
    let b = hv_tap(l.i0 + 1u, l.j0, k, q) * (1.0 - l.wt) + hv_tap(l.i0 + 1u, l.j0 + 1u, k, q) * l.wt;
    return a * (1.0 - l.ws) + b * l.ws;
}

// glam's Vec3::any_orthonormal_vector (Duff et al. 2017).
fn any_orthonormal(n: vec3<f32>) -> vec3<f32> {
    var sign = 1.0;
    if (n.z < 0.0) {
        sign = -1.0;
    }
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return vec3<f32>(b, sign + n.y * n.y * a, -n.y);
}

// half_vector::integrate_term of each Gaussian term of the lobe (m, lambda, amp) seen from v
// (map frame), through the prefiltered chain: int a K(m . h(w)) L(w) dw.
fn integrate_half_vector(m: vec3<f32>, lambda: f32, amp: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let c = dot(v, m);
    if (c <= 0.0) {
        return vec3<f32>(0.0);
    }
    let t = normalize_or(v - c * m, any_orthonormal(m));
    let theta_v = acos(min(c, 1.0));
    var sum = vec3<f32>(0.0);
    for (var j = 0u; j < 4u; j++) {
        let wj = params.kernel_weight[j];
        if (wj == 0.0) {
            continue;
        }
        let s = max(params.kernel_rate[j] * lambda, HV_S_MIN);
        let l = hv_locate(s, c);
        var off: array<f32, 5>;
        var sharp: array<f32, 5>;
        var weight: array<f32, 5>;
        var model = 0.0;
        for (var k = 0u; k < HV_TAPS; k++) {
            off[k] = hv_tap_lerp(l, k, 0u) * 2.0 / sqrt(s);
            sharp[k] = hv_tap_lerp(l, k, 1u) * s;
            weight[k] = hv_tap_lerp(l, k, 2u);
            model += weight[k] * unit_integral(sharp[k]);
        }
        var norm = 1.0;
        if (model > 0.0) {
            norm = term_mass(s, max(c, 1e-6)) / model;
        }
        for (var k = 0u; k < HV_TAPS; k++) {
            let psi = off[k] - theta_v;
            let axis = m * cos(psi) + t * sin(psi);
            let a = weight[k] * norm;
            sum += (wj * amp * a) * sample_chain(axis, sharp[k]) * (params.scale * unit_integral(sharp[k]));
        }
    }
    return sum;
}
