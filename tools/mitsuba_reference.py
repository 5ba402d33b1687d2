#!/usr/bin/env python3
"""Render a relight scene export with Mitsuba 3 (the ground truth of relight's path tracer).

Usage: mitsuba_reference.py scene.json out.exr [--variant auto|llvm_ad_rgb|scalar_rgb]
                            [--spp N] [--seed S | --seeds S1,S2,...]

With `--seeds`, one process renders one image per seed (the JIT-compiled kernels are reused)
and writes `out_s<seed>.exr` for each; independent renders let callers estimate Mitsuba's
per-pixel noise.

`scene.json` is written by `relight_render::mitsuba::export_mitsuba` (see that module for the
format). The Mitsuba scene built from it:
  * `perspective` sensor, `look_at(origin, target, up)`, `fov` with `fov_axis = "x"`, an
    `independent` sampler with `spp` samples, an `hdrfilm` (rgb) with a `box` reconstruction
    filter (one sample per jittered point of the pixel, as relight does);
  * an `envmap` emitter: the latlong EXR, `scale`, `to_world = rotate([0, 1, 0], rotate_y_deg)`
    (left out when `env_black`);
  * a `point` emitter per light of `lights` of type `point` (`position`, rgb `intensity`), a
    `spot` emitter per `spot` (`to_world = look_at(position, position + direction)`,
    `cutoff_angle`, `beam_width`, rgb `intensity`);
  * one `ply` shape per material, `face_normals = False` (interpolated vertex normals), with
    `diffuse`, `roughconductor` (ggx, material "none", visible-normal sampling) or
    `roughplastic` (ggx, linear) BSDFs, possibly wrapped in a `normalmap` BSDF;
  * a parameter given as `{"bitmap": file}` is a `bitmap` texture of that linear EXR (`raw`;
    `wrap_mode` and `filter_type` from the entry, repeat and bilinear when absent; `to_uv`
    from the entry's 3 x 3 affine matrix rows when present); with `"channel": c` only channel
    `c` is kept (a one-channel bitmap, for a scalar such as `alpha`). The PLY's `v` and the EXR's rows are already in Mitsuba's
    placement (`relight_render::mitsuba`, "Texture and normal maps");
  * a `gltf` BSDF (`base_color`, `metallic`, `roughness`: the glTF 2.0 metallic-roughness
    BRDF, Appendix B) is, with `--gltf-as plugin` (the default), the `gltf_pbr` plugin of
    `mitsuba_gltf_bsdf.py` (beside this script): Appendix B in Dr.Jit. `--gltf-as blend` and
    `--gltf-as principled` use Mitsuba's own BSDFs instead, which differ from Appendix B (for
    comparisons): a `blendbsdf` weighted by `metallic` of `roughplastic` (diffuse = base colour,
    `int_ior = 1.5`) and `roughconductor` (`specular_reflectance` = base colour), both with
    `alpha = roughness^2`; or `principled` (`specular = 0.5`, i.e. `eta = 1.5`);
  * a `normalmap` BSDF is loaded with `use_shadowing_function = False` and
    `flip_invalid_normals = False` (both on by default in Mitsuba 3.9, neither in relight;
    Mitsuba versions without these properties refuse the scene rather than render another);
  * the `path` integrator with `max_depth` (2 = direct only, -1 = unlimited) and
    `hide_emitters`.
RGB variants only (spectral ones multiply the emitter by D65). `auto` takes `llvm_ad_rgb` when
it loads (needs libllvm; 2-3x faster) and `scalar_rgb` otherwise. Prints one line:
`variant=<v> spp=<n> seconds=<t>`.
"""

import argparse
import json
import os
import sys
import time

# How a `gltf` BSDF is rendered: "plugin" (Appendix B), "blend" or "principled" (module docs).
GLTF_AS = "plugin"


def pick_variant(requested):
    """Set and return the Mitsuba variant (`auto`: llvm_ad_rgb if it loads, else scalar_rgb)."""
    import mitsuba as mi

    candidates = ["llvm_ad_rgb", "scalar_rgb"] if requested == "auto" else [requested]
    errors = []
    for v in candidates:
        try:
            mi.set_variant(v)
            # A tiny JIT round trip: llvm variants fail here when libLLVM is missing or broken.
            mi.load_dict({"type": "diffuse"})
            return v
        except Exception as e:  # noqa: BLE001 - report every failure, try the next variant
            errors.append(f"{v}: {e}")
    raise RuntimeError("no usable Mitsuba variant: " + "; ".join(errors))


def rgb(value):
    """An `rgb` texture dictionary."""
    return {"type": "rgb", "value": [float(x) for x in value]}


def bitmap(entry, base_dir):
    """A `bitmap` texture dictionary of a `{"bitmap": file[, "channel": c]}` entry (a channel
    is read with Mitsuba, whose variant must be set)."""
    path = os.path.join(base_dir, entry["bitmap"])
    d = {
        "type": "bitmap",
        "raw": True,
        "filter_type": entry.get("filter_type", "bilinear"),
        "wrap_mode": entry.get("wrap_mode", "repeat"),
    }
    if "to_uv" in entry:
        import mitsuba as mi

        m = [[float(x) for x in row] for row in entry["to_uv"]]
        d["to_uv"] = mi.ScalarTransform3f(mi.ScalarMatrix3f(m))
    if "channel" in entry:
        import mitsuba as mi
        import numpy as np

        c = int(entry["channel"])
        texels = np.array(mi.Bitmap(path), dtype=np.float32)
        d["bitmap"] = mi.Bitmap(np.ascontiguousarray(texels[:, :, c : c + 1]))
    else:
        d["filename"] = path
    return d


def colour(value, base_dir):
    """A colour parameter: an rgb triple or a bitmap entry."""
    return bitmap(value, base_dir) if isinstance(value, dict) else rgb(value)


def scalar(value, base_dir):
    """A scalar parameter: a number or a bitmap entry."""
    return bitmap(value, base_dir) if isinstance(value, dict) else float(value)


def bsdf_dict(b, base_dir="."):
    """Mitsuba BSDF dictionary of a relight `bsdf` entry (textures relative to `base_dir`)."""
    t = b["type"]
    if t == "normalmap":
        # Both switches default to on in Mitsuba 3.9 and have no counterpart in relight
        # (measured): a shadowing factor on every evaluation, and a changed normal where the
        # incident direction is below the perturbed one (relight: no contribution).
        return {
            "type": "normalmap",
            "normalmap": bitmap(b["normalmap"], base_dir),
            "bsdf": bsdf_dict(b["bsdf"], base_dir),
            "use_shadowing_function": False,
            "flip_invalid_normals": False,
        }
    if t == "diffuse":
        return {"type": "diffuse", "reflectance": colour(b["reflectance"], base_dir)}
    if t == "roughconductor":
        return {
            "type": "roughconductor",
            "distribution": "ggx",
            "alpha": scalar(b["alpha"], base_dir),
            "sample_visible": True,
            "material": "none",
            "specular_reflectance": colour(b["specular_reflectance"], base_dir),
        }
    if t == "roughplastic":
        return {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": float(b["alpha"]),
            "sample_visible": True,
            "nonlinear": False,
            "int_ior": float(b["int_ior"]),
            "ext_ior": float(b.get("ext_ior", 1.0)),
            "diffuse_reflectance": colour(b["diffuse_reflectance"], base_dir),
            "specular_reflectance": colour(b["specular_reflectance"], base_dir),
        }
    if t == "gltf":
        return gltf_dict(b, base_dir)
    raise ValueError(f"unsupported bsdf type {t!r}")


def gltf_dict(b, base_dir):
    """A `gltf` BSDF entry as `GLTF_AS` says (module docs)."""
    base = colour(b["base_color"], base_dir)
    metallic = scalar(b["metallic"], base_dir)
    roughness = b["roughness"]
    if GLTF_AS == "plugin":
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import mitsuba_gltf_bsdf  # noqa: F401 - registers `gltf_pbr`

        return {
            "type": "gltf_pbr",
            "base_color": base,
            "metallic": metallic,
            "roughness": scalar(roughness, base_dir),
        }
    if isinstance(roughness, dict):
        raise ValueError(f"--gltf-as {GLTF_AS}: a roughness texture needs the plugin")
    alpha = max(float(roughness) ** 2, 1e-3)
    if GLTF_AS == "principled":
        return {
            "type": "principled",
            "base_color": base,
            "metallic": metallic,
            "roughness": float(roughness),
            "specular": 0.5,
        }
    if GLTF_AS == "blend":
        return {
            "type": "blendbsdf",
            "weight": metallic,
            "bsdf_0": {
                "type": "roughplastic",
                "distribution": "ggx",
                "alpha": alpha,
                "sample_visible": True,
                "nonlinear": False,
                "int_ior": 1.5,
                "ext_ior": 1.0,
                "diffuse_reflectance": base,
            },
            "bsdf_1": {
                "type": "roughconductor",
                "distribution": "ggx",
                "alpha": alpha,
                "sample_visible": True,
                "material": "none",
                "specular_reflectance": colour(b["base_color"], base_dir),
            },
        }
    raise ValueError(f"unknown --gltf-as {GLTF_AS!r}")


def scene_dict(doc, base_dir, spp=None):
    """The Mitsuba scene dictionary of a relight `scene.json` document (variant must be set)."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    cam = doc["camera"]
    env = doc["env"]
    d = {
        "type": "scene",
        "integrator": {
            "type": "path",
            "max_depth": int(doc["max_depth"]),
            "hide_emitters": bool(doc.get("hide_emitters", False)),
        },
        "sensor": {
            "type": "perspective",
            "fov": float(cam["fov"]),
            "fov_axis": "x",
            "to_world": T().look_at(origin=cam["origin"], target=cam["target"], up=cam["up"]),
            "sampler": {"type": "independent", "sample_count": int(spp or doc["spp"])},
            "film": {
                "type": "hdrfilm",
                "width": int(cam["width"]),
                "height": int(cam["height"]),
                "pixel_format": "rgb",
                "rfilter": {"type": "box"},
            },
        },
    }
    if not doc.get("env_black", False):
        d["environment"] = {
            "type": "envmap",
            "filename": os.path.join(base_dir, env["file"]),
            "scale": float(env["scale"]),
            "to_world": T().rotate([0, 1, 0], float(env["rotate_y_deg"])),
        }
    for i, light in enumerate(doc.get("lights", [])):
        p = [float(x) for x in light["position"]]
        intensity = {"type": "rgb", "value": [float(x) for x in light["intensity"]]}
        if light["type"] == "point":
            d[f"light_{i}"] = {"type": "point", "position": p, "intensity": intensity}
        else:
            a = [float(x) for x in light["direction"]]
            up = [0, 1, 0] if abs(a[1]) < 0.9 else [1, 0, 0]
            d[f"light_{i}"] = {
                "type": "spot",
                "to_world": T().look_at(origin=p, target=[p[k] + a[k] for k in range(3)], up=up),
                "cutoff_angle": float(light["cutoff_deg"]),
                "beam_width": float(light["beam_deg"]),
                "intensity": intensity,
            }
    for i, s in enumerate(doc["shapes"]):
        d[f"shape_{i}"] = {
            "type": "ply",
            "filename": os.path.join(base_dir, s["ply"]),
            "face_normals": False,
            "bsdf": bsdf_dict(s["bsdf"], base_dir),
        }
    return d


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene_json")
    p.add_argument("out_exr")
    p.add_argument("--variant", default="auto", help="auto | llvm_ad_rgb | scalar_rgb")
    p.add_argument("--spp", type=int, default=None, help="override the file's spp")
    p.add_argument("--seed", type=int, default=0, help="sampler seed")
    p.add_argument("--seeds", default=None, help="comma-separated seeds, one image each")
    p.add_argument(
        "--gltf-as", default="plugin", help="plugin | blend | principled (module docs)"
    )
    a = p.parse_args(argv)
    global GLTF_AS
    GLTF_AS = a.gltf_as

    with open(a.scene_json) as f:
        doc = json.load(f)
    variant = pick_variant(a.variant)
    import mitsuba as mi

    base = os.path.dirname(os.path.abspath(a.scene_json))
    scene = mi.load_dict(scene_dict(doc, base, a.spp))
    if a.seeds:
        stem = a.out_exr[:-4] if a.out_exr.endswith(".exr") else a.out_exr
        jobs = [(int(x), f"{stem}_s{int(x)}.exr") for x in a.seeds.split(",")]
    else:
        jobs = [(a.seed, a.out_exr)]
    t0 = time.time()
    for seed, path in jobs:
        img = mi.render(scene, seed=seed)
        bmp = mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB)
        bmp = bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
        bmp.write(path)
    spp = a.spp or doc["spp"]
    print(f"variant={variant} spp={spp} images={len(jobs)} seconds={time.time() - t0:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
