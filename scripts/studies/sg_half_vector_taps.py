"""Study (docs/RESULTS.md section 8, session 25): integrating a half-vector-domain GGX-kernel
lobe with isotropic prefiltered lookups, as a frame would.

Usage: python sg_half_vector_taps.py PROBE.hdr LAMBDA N SPACING

The lobe K(m . h), h = normalize(w + v), m the normal, is integrated against random rotations
of the probe exactly (a sum over the probe's texels) and by N Gauss-Hermite taps along the
plane of incidence: each Gaussian term of sharpness s is, around the mirror direction, an
anisotropic Gaussian of sharpness s/4 in the plane and s/(4 c^2) across it (c = v.m); the taps
are placed in h and reflected exactly, each an isotropic lookup at the across-plane sharpness
capped so that taps SPACING sigma apart leave no gaps (kappa times the in-plane sharpness).
Printed per view: the relative RMS error of the tap rule over 40 rotations.
relight's budget row "half-vector fit, 5 taps" is this rule with N = 5, SPACING = 1.5, plus a
factor this script leaves out: each term weighted by its mean Jacobian 4 A(s) v.m,
A(s) = coth s - 1/s (relight_eval::sg::budget::half_vector_taps).
"""
import sys
import numpy as np
from probe import load_probe, random_rotation
E, dA, L = load_probe(sys.argv[1])
b = np.array([2.04755,0.51189,0.12797,0.03199]); wk = np.array([0.71976,0.22641,0.0181,0.00184])
lam = float(sys.argv[2]); N = int(sys.argv[3]); spacing = float(sys.argv[4])
xs, ws = np.polynomial.hermite_e.hermegauss(N); ws = ws/ws.sum()
gap = np.min(np.diff(np.sort(xs))) if N > 1 else 1.0
# iso blur width = gap*sigma/spacing; sigma^2 + blur^2 = 1/lx  ->  kappa = lambda'/lx
kappa = (1 + (gap/spacing)**2)/(gap/spacing)**2 if N > 1 else 1.0
rng = np.random.default_rng(1)
def pre(El, r, lp):
    k = np.exp(lp*(El@r - 1))*dA
    return (L*k).sum()/k.sum()
print(f"N {N} spacing {spacing} kappa {kappa:.2f}")
for tv in [0, 30, 45, 60, 75, 85]:
    t = np.radians(tv); v = np.array([np.sin(t), 0, np.cos(t)]); m = np.array([0,0,1.0])
    ax_in = np.array([1.0,0,0])
    c = v@m
    ex, app = [], []
    for _ in range(40):
        R = random_rotation(rng); El = E @ R
        h = El + v; h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-9)
        lobe = sum(wj*np.exp(-bj*lam*(1 - h@m)/2) for wj,bj in zip(wk,b))
        ex.append((L*lobe*dA).sum())
        tot = 0.0
        for wj, bj in zip(wk, b):
            s = bj*lam/2
            mass = 2*np.pi/s*(1-np.exp(-2*s))
            lx, ly = s/4, s/(4*c*c)
            lp = min(ly, kappa*lx)
            sig_w = np.sqrt(max(1/lx - 1/lp, 0))      # omega in-plane spread left to the taps
            acc = 0.0
            for x, w in zip(xs, ws):
                d = x*sig_w/2                          # h rotates half as far as omega
                hi = np.cos(d)*m + np.sin(d)*ax_in
                ci = v@hi
                if ci <= 0: continue
                wi = 2*ci*hi - v
                acc += w*4*ci*pre(El, wi, lp)
            tot += wj*mass*acc
        app.append(tot)
    ex = np.array(ex)
    e = np.sqrt(np.mean((np.array(app)-ex)**2)/np.mean(ex**2))
    print(f"view {tv:2d}: rel rms {e:.3f} ratio {np.mean(app)/np.mean(ex):.3f}", flush=True)
