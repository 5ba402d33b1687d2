"""The glTF 2.0 metallic-roughness BRDF (glTF specification, Appendix B) as a Mitsuba 3 BSDF
plugin, `gltf_pbr`, written in Dr.Jit from the specification (not from relight's Rust).

Parameters: `base_color` (colour texture), `metallic` and `roughness` (float or one-channel
texture; `alpha = roughness^2`, at least 1e-3). With V = wi, L = wo, H = normalize(V + L):
  D      = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2)
  V_GGX  = 1 / (2 (N.L sqrt(alpha^2 + (1 - alpha^2) (N.V)^2) + N.V sqrt(alpha^2 + (1 - alpha^2) (N.L)^2)))
  F(f0)  = f0 + (1 - f0) (1 - V.H)^5
  f      = (1 - metallic) [(1 - F(0.04)) base / pi + F(0.04) D V_GGX] + metallic F(base) D V_GGX
One-sided (zero unless N.V > 0 and N.L > 0); `eval` includes the cosine N.L, as every Mitsuba
BSDF. Sampling: Mitsuba's GGX visible-normal sampler reflected about V with probability
`(1 + metallic) / 2`, else a cosine lobe.

Import this module after `mi.set_variant(...)`; it registers the plugin on import.
"""

import drjit as dr
import mitsuba as mi

MIN_ALPHA = 1e-3


def _value1(p, si, active):
    """Evaluate a float parameter: a texture's first channel, or a number."""
    if hasattr(p, "eval_1"):
        return p.eval_1(si, active)
    return mi.Float(float(p))


def _colour(p, si, active):
    """Evaluate a colour parameter: a texture, or a constant (Mitsuba hands an `rgb` entry to
    a Python plugin as a colour)."""
    if hasattr(p, "eval"):
        return p.eval(si, active)
    return mi.Color3f(p)


class GltfBSDF(mi.BSDF):
    """Appendix B of the glTF 2.0 specification (module docs)."""

    def __init__(self, props):
        mi.BSDF.__init__(self, props)
        self.base_color = props.get("base_color")
        self.metallic = props.get("metallic")
        self.roughness = props.get("roughness")
        glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
        diffuse = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
        self.m_components = [glossy, diffuse]
        self.m_flags = glossy | diffuse

    def _params(self, si, active):
        base = _colour(self.base_color, si, active)
        metallic = _value1(self.metallic, si, active)
        r = _value1(self.roughness, si, active)
        alpha = dr.maximum(r * r, MIN_ALPHA)
        return base, metallic, alpha

    def _eval(self, si, wo, active):
        wi = si.wi
        ci = mi.Frame3f.cos_theta(wi)
        co = mi.Frame3f.cos_theta(wo)
        active = active & (ci > 0) & (co > 0)
        base, metallic, alpha = self._params(si, active)
        h = dr.normalize(wi + wo)
        vh = dr.clip(dr.dot(wi, h), 0.0, 1.0)
        a2 = alpha * alpha
        # (N.H)^2 (alpha^2 - 1) + 1 = sin^2 theta_h + cos^2 theta_h alpha^2 (no cancellation).
        nh2 = h.z * h.z
        t = (h.x * h.x + h.y * h.y) + nh2 * a2
        d = a2 / (dr.pi * t * t)
        vis = 0.5 / (co * dr.sqrt(a2 + (1 - a2) * ci * ci) + ci * dr.sqrt(a2 + (1 - a2) * co * co))
        spec = d * vis
        x = 1.0 - vh
        x5 = (x * x) * (x * x) * x
        f_d = 0.04 + 0.96 * x5
        f_m = base + (1.0 - base) * x5
        dielectric = (1.0 - f_d) * base * dr.inv_pi + f_d * spec
        metal = f_m * spec
        value = ((1.0 - metallic) * dielectric + metallic * metal) * co
        return dr.select(active, value, 0.0), active

    def _pdf(self, si, wo, active):
        wi = si.wi
        ci = mi.Frame3f.cos_theta(wi)
        co = mi.Frame3f.cos_theta(wo)
        active = active & (ci > 0) & (co > 0)
        _, metallic, alpha = self._params(si, active)
        ps = 0.5 * (1.0 + metallic)
        distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True)
        h = dr.normalize(wi + wo)
        ho = dr.dot(wo, h)
        p_spec = dr.select(ho > 0, distr.pdf(wi, h) / (4.0 * ho), 0.0)
        p = ps * p_spec + (1.0 - ps) * co * dr.inv_pi
        return dr.select(active, p, 0.0)

    def sample(self, ctx, si, sample1, sample2, active=True):
        wi = si.wi
        active = active & (mi.Frame3f.cos_theta(wi) > 0)
        _, metallic, alpha = self._params(si, active)
        ps = 0.5 * (1.0 + metallic)
        spec = sample1 < ps
        distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True)
        m, _ = distr.sample(wi, sample2)
        wo = dr.select(spec, mi.reflect(wi, m), mi.warp.square_to_cosine_hemisphere(sample2))
        bs = dr.zeros(mi.BSDFSample3f)
        bs.wo = wo
        bs.eta = 1.0
        bs.sampled_component = dr.select(spec, mi.UInt32(0), mi.UInt32(1))
        bs.sampled_type = dr.select(
            spec,
            mi.UInt32(+mi.BSDFFlags.GlossyReflection),
            mi.UInt32(+mi.BSDFFlags.DiffuseReflection),
        )
        bs.pdf = self._pdf(si, wo, active)
        value, ok = self._eval(si, wo, active)
        ok = ok & (bs.pdf > 0)
        # (Guarded division: scalar variants evaluate both branches in Python floats.)
        return bs, dr.select(ok, value / dr.maximum(bs.pdf, 1e-30), 0.0)

    def eval(self, ctx, si, wo, active=True):
        return self._eval(si, wo, active)[0]

    def pdf(self, ctx, si, wo, active=True):
        return self._pdf(si, wo, active)

    def eval_pdf(self, ctx, si, wo, active=True):
        return self._eval(si, wo, active)[0], self._pdf(si, wo, active)

    def to_string(self):
        return "GltfBSDF[glTF 2.0 Appendix B]"


mi.register_bsdf("gltf_pbr", lambda props: GltfBSDF(props))
