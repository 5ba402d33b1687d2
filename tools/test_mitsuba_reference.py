#!/usr/bin/env python3
"""Tests of tools/mitsuba_reference.py: `python tools/test_mitsuba_reference.py`.

The dictionary tests need only Python; the others skip when `mitsuba` cannot be imported.
The render test is a furnace: a diffuse quad of albedo a facing the camera under a constant
environment L, direct lighting only, must be exactly a * L in every pixel it covers.
"""

import json
import math
import os
import struct
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_reference as ref  # noqa: E402

try:
    import mitsuba as mi  # noqa: F401

    HAVE_MITSUBA = True
except ImportError:
    HAVE_MITSUBA = False


def write_quad_ply(path, z=0.0, half=1.0):
    """A square in the plane z facing +Z, binary little-endian PLY with normals."""
    verts = [(-half, -half), (half, -half), (half, half), (-half, half)]
    header = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode())
        for x, y in verts:
            f.write(struct.pack("<6f", x, y, z, 0.0, 0.0, 1.0))
        for tri in [(0, 1, 2), (0, 2, 3)]:
            f.write(struct.pack("<B3i", 3, *tri))


def furnace_doc(albedo, radiance):
    return {
        "camera": {"origin": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 20.0, "width": 8, "height": 8},
        "env": {"file": "env.exr", "scale": 1.0, "rotate_y_deg": 0.0},
        "shapes": [{"ply": "quad.ply", "bsdf": {"type": "diffuse", "reflectance": [albedo] * 3}}],
        "spp": 256,
        "max_depth": 2,
        "hide_emitters": False,
        "_radiance": radiance,
    }


class DictTests(unittest.TestCase):
    def test_bsdf_mapping(self):
        d = ref.bsdf_dict({"type": "diffuse", "reflectance": [0.1, 0.2, 0.3]})
        self.assertEqual(d["type"], "diffuse")
        self.assertEqual(d["reflectance"]["value"], [0.1, 0.2, 0.3])
        c = ref.bsdf_dict({"type": "roughconductor", "alpha": 0.2, "specular_reflectance": [1, 1, 1]})
        self.assertEqual((c["distribution"], c["material"], c["sample_visible"]), ("ggx", "none", True))
        p = ref.bsdf_dict({"type": "roughplastic", "alpha": 0.3, "int_ior": 1.5,
                           "diffuse_reflectance": [0.5] * 3, "specular_reflectance": [1] * 3})
        self.assertEqual((p["distribution"], p["nonlinear"], p["ext_ior"], p["int_ior"]), ("ggx", False, 1.0, 1.5))
        with self.assertRaises(ValueError):
            ref.bsdf_dict({"type": "phong"})

    def test_textured_mapping(self):
        b = ref.bsdf_dict(
            {
                "type": "normalmap",
                "normalmap": {"bitmap": "n.exr"},
                "bsdf": {"type": "diffuse", "reflectance": {"bitmap": "d.exr"}},
            },
            "/base",
        )
        # Mitsuba 3.9's defaults (a shadowing factor, flipped normals) are not relight's.
        self.assertEqual((b["use_shadowing_function"], b["flip_invalid_normals"]), (False, False))
        self.assertEqual(b["normalmap"]["filename"], os.path.join("/base", "n.exr"))
        r = b["bsdf"]["reflectance"]
        self.assertEqual(
            (r["type"], r["raw"], r["filter_type"], r["wrap_mode"], r["filename"]),
            ("bitmap", True, "bilinear", "repeat", os.path.join("/base", "d.exr")),
        )


@unittest.skipUnless(HAVE_MITSUBA, "mitsuba not importable")
class MitsubaTests(unittest.TestCase):
    def test_scene_dict_conventions(self):
        ref.pick_variant("scalar_rgb")
        doc = furnace_doc(0.5, 2.0)
        doc["env"]["rotate_y_deg"] = 90.0
        d = ref.scene_dict(doc, "/tmp")
        s = d["sensor"]
        self.assertEqual((s["fov_axis"], s["film"]["rfilter"]["type"], s["film"]["pixel_format"]), ("x", "box", "rgb"))
        self.assertEqual(d["integrator"]["max_depth"], 2)
        self.assertFalse(d["shape_0"]["face_normals"])
        # rotate([0,1,0], 90 deg) takes +Z to +X.
        m = d["environment"]["to_world"]
        p = m @ mi.ScalarPoint3f(0, 0, 1)
        self.assertAlmostEqual(p[0], 1.0, places=5)
        self.assertAlmostEqual(p[2], 0.0, places=5)

    def test_bitmap_channel_is_a_one_channel_texture(self):
        ref.pick_variant("scalar_rgb")
        with tempfile.TemporaryDirectory() as tmp:
            # 2 x 1 texels: red 0.2 then 0.6 (green and blue differ, so a mix would show).
            mi.Bitmap(mi.TensorXf([[[0.2, 0.9, 0.0], [0.6, 0.1, 1.0]]])).write(os.path.join(tmp, "r.exr"))
            c = ref.bsdf_dict(
                {"type": "roughconductor", "alpha": {"bitmap": "r.exr", "channel": 0}, "specular_reflectance": [1] * 3},
                tmp,
            )
            tex = mi.load_dict(c["alpha"])
            si = mi.SurfaceInteraction3f()
            for u, want in [(0.25, 0.2), (0.75, 0.6), (0.5, 0.4)]:
                si.uv = mi.Point2f(u, 0.5)
                self.assertAlmostEqual(tex.eval_1(si), want, places=6)
            mi.load_dict(c)  # roughconductor accepts an alpha texture

    def test_bitmap_sampling_and_to_uv(self):
        ref.pick_variant("scalar_rgb")
        with tempfile.TemporaryDirectory() as tmp:
            # 2 x 1 texels: red 0.2 then 0.6.
            mi.Bitmap(mi.TensorXf([[[0.2, 0.2, 0.2], [0.6, 0.6, 0.6]]])).write(os.path.join(tmp, "d.exr"))
            entry = {
                "bitmap": "d.exr",
                "wrap_mode": "clamp",
                "filter_type": "nearest",
                # u' = 0.5 u + 0.5: every u in [0, 1) reads the second texel, once clamped.
                "to_uv": [[0.5, 0.0, 0.5], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            }
            d = ref.bsdf_dict({"type": "diffuse", "reflectance": entry}, tmp)["reflectance"]
            self.assertEqual((d["wrap_mode"], d["filter_type"]), ("clamp", "nearest"))
            tex = mi.load_dict(d)
            si = mi.SurfaceInteraction3f()
            for u, want in [(0.1, 0.6), (0.9, 0.6), (1.8, 0.6), (-0.9, 0.2)]:
                si.uv = mi.Point2f(u, 0.5)
                self.assertAlmostEqual(tex.eval(si)[0], want, places=6)

    def test_furnace_render(self):
        a, L = 0.6, 2.0
        with tempfile.TemporaryDirectory() as tmp:
            ref.pick_variant("scalar_rgb")
            write_quad_ply(os.path.join(tmp, "quad.ply"))
            mi.Bitmap(mi.TensorXf([[[L, L, L]] * 16] * 9)).write(os.path.join(tmp, "env.exr"))
            doc = furnace_doc(a, L)
            with open(os.path.join(tmp, "scene.json"), "w") as f:
                json.dump(doc, f)
            out = os.path.join(tmp, "out.exr")
            self.assertEqual(ref.main([os.path.join(tmp, "scene.json"), out, "--variant", "scalar_rgb"]), 0)
            import numpy as np

            img = np.array(mi.Bitmap(out))
            self.assertEqual(img.shape[:2], (8, 8))
            # The quad (half-width 1 at distance 3) covers the whole 20 degree view. Mitsuba's
            # estimator is noisy even here (MIS of emitter and BSDF samples): 256 spp give
            # about 1% per pixel, so 8% per pixel and 1% on the mean of 64 pixels.
            px = img[:, :, :3].astype(float)
            self.assertLess(abs(px.mean() / (a * L) - 1.0), 0.01, px.mean())
            self.assertLess(np.abs(px / (a * L) - 1.0).max(), 0.08, px)


if __name__ == "__main__":
    unittest.main()
