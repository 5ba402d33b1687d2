"""Shared by the studies in this folder: a latlong probe as directions, solid angles and
luminance, and uniformly random rotations."""
import numpy as np
import mitsuba as mi

mi.set_variant('scalar_rgb')


def load_probe(path):
    """The probe's texel directions (y up), solid angles and luminance, flattened."""
    env = np.array(mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32))
    H, W, _ = env.shape
    lum = env @ np.array([0.2126, 0.7152, 0.0722])
    th = (np.arange(H) + 0.5) / H * np.pi
    ph = (np.arange(W) + 0.5) / W * 2 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing='ij')
    E = np.stack([np.sin(TH) * np.cos(PH), np.cos(TH), np.sin(TH) * np.sin(PH)], -1).reshape(-1, 3)
    dA = (np.sin(TH) * (np.pi / H) * (2 * np.pi / W)).reshape(-1)
    return E, dA, lum.reshape(-1)


def random_rotation(rng):
    """A uniformly random rotation matrix (from a random unit quaternion)."""
    q = rng.normal(size=4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array([[a*a+b*b-c*c-d*d, 2*(b*c-a*d), 2*(b*d+a*c)],
                     [2*(b*c+a*d), a*a-b*b+c*c-d*d, 2*(c*d-a*b)],
                     [2*(b*d-a*c), 2*(c*d+a*b), a*a-b*b-c*c+d*d]])
