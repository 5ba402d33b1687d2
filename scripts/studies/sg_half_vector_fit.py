"""Study (docs/RESULTS.md section 8, session 25): one lobe fitted to a GGX lobe, in the light
direction or in the half-vector domain, and its integral against random rotations of a probe.

Usage: python sg_half_vector_fit.py PROBE.hdr ALPHA
(numpy and mitsuba, as installed by scripts/setup.sh, read the probe).

For views 0-75 degrees from the normal, the GGX conductor lobe f cos (alpha ALPHA, no Fresnel)
is tabulated on a 40,000-point Fibonacci sphere and fitted by a grid search over axis and
sharpness (amplitude by least squares, then scaled to the data's integral) with four shapes:
  sg     a Gaussian exp(-lam (1 - mu.w)) in the light direction w (the bake's default),
  mix4   the GGX-shaped kernel (four Gaussian terms) in w (--lobe-kernel ggx),
  sgh    a Gaussian in the half vector h = normalize(w + v),
  mix4h  the GGX-shaped kernel in h.
Printed per view: the fitted sharpness, the fit's relative L2 error, and the relative RMS
error of the lobe's integral against the exact one over 60 random rotations of the probe.
(The kernel terms here are written as exp(-b lam x / 2); relight's are the same shape.)
"""
import sys
import numpy as np
from probe import load_probe, random_rotation
E, dA, L = load_probe(sys.argv[1])
# local fit grid: fibonacci sphere
N = 40000; i = np.arange(N) + 0.5
z = 1 - 2*i/N; r = np.sqrt(1-z*z); a = np.pi*(1+5**0.5)*i
D = np.stack([r*np.cos(a), r*np.sin(a), z], -1); w = 4*np.pi/N
def ggx(alpha, wo, wi):
    ci = wi[:,2]; co = wo[2]
    h = wi + wo; h /= np.linalg.norm(h, axis=1, keepdims=True)
    ch = h[:,2]; a2 = alpha*alpha
    Dm = a2 / (np.pi * (ch*ch*(a2-1)+1)**2)
    def l(c): t2 = np.maximum(1-c*c,0)/np.maximum(c*c,1e-12); return (-1+np.sqrt(1+a2*t2))/2
    G = 1/(1+l(co)+l(np.maximum(ci,1e-6)))
    f = Dm*G/(4*co*np.maximum(ci,1e-6))
    return np.where(ci > 0, f*ci, 0.0)
def kern(kind, lam, c):
    x = 1 - c
    if kind == 'sg': return np.exp(-lam*x)
    if kind == 'rat': return (1 + lam*x/2)**-2
    if kind == 'mix4':
        b = np.array([2.04755,0.51189,0.12797,0.03199]); w = np.array([0.71976,0.22641,0.0181,0.00184])
    if kind == 'mix3':
        b = np.array([1.84211,0.46053,0.11513]); w = np.array([0.75132,0.17707,0.02059])
    return sum(wi*np.exp(-bi*lam*x/2) for wi,bi in zip(w,b))
def lobe(kind, lam, mu, dirs, wo):
    if kind.endswith('h'):
        h = dirs + wo; h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-9)
        return kern(kind[:-1], lam, h @ mu)
    return kern(kind, lam, dirs @ mu)
def fit(kind, T, refl):
    best = None
    # axis search in a cone around the data's peak direction
    pk = D[np.argmax(T)]
    if kind.endswith('h'): pk = pk + WO; pk /= np.linalg.norm(pk)
    basis_u = np.cross(pk, [0,0,1.0] if abs(pk[2])<0.9 else [1.0,0,0]); basis_u/=np.linalg.norm(basis_u)
    basis_v = np.cross(pk, basis_u)
    for du in np.linspace(-0.25,0.25,21):
        for dv in np.linspace(-0.1,0.1,9):
            mu = pk + du*basis_u + dv*basis_v; mu /= np.linalg.norm(mu)
            for lam in np.exp(np.linspace(np.log(2), np.log(2000), 60)):
                g = lobe(kind, lam, mu, D, WO)
                amp = (g*T).sum()/(g*g).sum()
                err = ((amp*g - T)**2).sum()
                if best is None or err < best[0]: best = (err, mu, lam, amp)
    err, mu, lam, amp = best
    g = lobe(kind, lam, mu, D, WO)
    scale = T.sum()/(amp*g).sum()
    return mu, lam, amp*scale, np.sqrt(err/(T*T).sum())
rng = np.random.default_rng(1)
alpha = float(sys.argv[2])
for tv in [0, 30, 45, 60, 75]:
    t = np.radians(tv); wo = np.array([np.sin(t), 0, np.cos(t)])
    WO = wo
    T = ggx(alpha, wo, D)
    refl = np.array([-np.sin(t), 0, np.cos(t)])
    res = {}
    fits = {k: fit(k, T, refl) for k in ['sg', 'mix4', 'sgh', 'mix4h']}
    ex, ap = [], {k: [] for k in fits}
    for _ in range(60):
        R = random_rotation(rng)   # world_from_local
        El = E @ R       # env directions in local frame
        Tl = ggx(alpha, wo, El)
        ex.append((L*Tl*dA).sum())
        for k,(mu,lam,amp,_) in fits.items():
            ap[k].append((L*amp*lobe(k, lam, mu, El, wo)*dA).sum())
    ex = np.array(ex)
    out = [f"view {tv:2d}"]
    for k,(mu,lam,amp,fe) in fits.items():
        e = np.sqrt(np.mean((np.array(ap[k])-ex)**2)/np.mean(ex**2))
        out.append(f"{k}: lam {lam:7.1f} fit-L2 {fe:.3f} img-rel-rms {e:.3f}")
    print(" | ".join(out), flush=True)
