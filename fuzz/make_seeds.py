#!/usr/bin/env python3
"""Write the binary seed inputs of the fuzz targets (fuzz/README.md) into fuzz/seeds/:
a triangle in OBJ+MTL, PLY (ASCII and both binary byte orders), glTF (external buffer and
data URI) and GLB, and a textured glTF triangle (PNG base colour, metallic-roughness and normal
textures with a sampler and KHR_texture_transform, and a camera) with its image in a GLB
buffer view, a data URI and an external file; flat, RLE and cross-shaped Radiance HDR files and a float OpenEXR,
each image behind the layout byte the env targets read first. Generated, not committed:
fuzz/run.sh runs this first. Standard library only."""
import base64
import json
import math
import os
import struct
import sys
import zlib

root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "seeds")


def put(target, name, data):
    d = os.path.join(root, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def meshes():
    put("obj", "tri.obj", b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n"
        b"usemtl a\nf 1/1/1 2/1/1 3/1/1\n\0newmtl a\nKd 0.5 0.5 0.5\nKs 0.1 0.1 0.1\nNs 10\n")
    head = (b"ply\nformat %s 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n")
    put("ply", "tri_ascii.ply", head % b"ascii" + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    for order, fmt in ((b"binary_little_endian", "<"), (b"binary_big_endian", ">")):
        body = struct.pack(fmt + "9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack(fmt + "B3i", 3, 0, 1, 2)
        put("ply", "tri_%s.ply" % order.decode()[7:], head % order + body)
    buf = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<3H", 0, 1, 2) + b"\0\0"

    def doc(uri):
        d = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
             "nodes": [{"mesh": 0, "translation": [0, 1, 0]}],
             "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
             "buffers": [{"byteLength": len(buf)}],
             "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                             {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
             "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                            "min": [0, 0, 0], "max": [1, 1, 0]},
                           {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]}
        if uri:
            d["buffers"][0]["uri"] = uri
        return json.dumps(d).encode()

    put("gltf", "tri.gltf", doc("b.bin") + b"\0" + buf)
    put("gltf", "tri_datauri.gltf",
        doc("data:application/octet-stream;base64," + base64.b64encode(buf).decode()))
    j = doc(None)
    j += b" " * (-len(j) % 4)
    put("gltf", "tri.glb", b"glTF" + struct.pack("<II", 2, 28 + len(j) + len(buf))
        + struct.pack("<I", len(j)) + b"JSON" + j + struct.pack("<I", len(buf)) + b"BIN\0" + buf)
    textured(buf)


def png_2x2():
    """A 2 x 2 8-bit RGB PNG: red, green / blue, white."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    rows = b"\0" + bytes([255, 0, 0, 0, 255, 0]) + b"\0" + bytes([0, 0, 255, 255, 255, 255])
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def textured(tri):
    """The triangle with UVs and a textured material, its image in three places."""
    uv = struct.pack("<6f", 0, 0, 1, 0, 0, 1)
    geo = tri + uv  # positions 0..36, indices 36..42 (+2 padding), UVs 44..68
    png = png_2x2()

    def doc(buffer_uri, image, buffer_len, views):
        tex = {"index": 0, "extensions": {"KHR_texture_transform": {
            "offset": [0.25, 0], "rotation": 0.5, "scale": [2, 1]}}}
        d = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
             "extensionsUsed": ["KHR_texture_transform"],
             "nodes": [{"mesh": 0, "name": "tri"},
                       {"camera": 0, "translation": [0, 0, 3]}],
             "cameras": [{"type": "perspective",
                          "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}}],
             "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 2},
                                         "indices": 1, "material": 0}]}],
             "materials": [{"name": "painted", "pbrMetallicRoughness": {
                 "baseColorFactor": [1, 0.8, 0.6, 1], "metallicFactor": 0.2,
                 "roughnessFactor": 0.7, "baseColorTexture": tex,
                 "metallicRoughnessTexture": {"index": 0}},
                 "normalTexture": {"index": 0, "scale": 0.5}}],
             "textures": [{"source": 0, "sampler": 0}],
             "samplers": [{"wrapS": 33071, "wrapT": 33648, "magFilter": 9728}],
             "images": [image],
             "buffers": [{"byteLength": buffer_len}],
             "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                             {"buffer": 0, "byteOffset": 36, "byteLength": 6},
                             {"buffer": 0, "byteOffset": 44, "byteLength": 24}] + views,
             "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                            "min": [0, 0, 0], "max": [1, 1, 0]},
                           {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
                           {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"}]}
        if buffer_uri:
            d["buffers"][0]["uri"] = buffer_uri
        return json.dumps(d).encode()

    geo_uri = "data:application/octet-stream;base64," + base64.b64encode(geo).decode()
    put("gltf", "tex_datauri.gltf", doc(geo_uri, {
        "uri": "data:image/png;base64," + base64.b64encode(png).decode()}, len(geo), []))
    # The fuzz target's external file `b.bin` holds the PNG.
    put("gltf", "tex_external.gltf", doc(geo_uri, {"uri": "b.bin"}, len(geo), []) + b"\0" + png)
    bin_ = geo + png
    bin_ += b"\0" * (-len(bin_) % 4)
    j = doc(None, {"bufferView": 3, "mimeType": "image/png"}, len(bin_),
            [{"buffer": 0, "byteOffset": len(geo), "byteLength": len(png)}])
    j += b" " * (-len(j) % 4)
    put("gltf", "tex.glb", b"glTF" + struct.pack("<II", 2, 28 + len(j) + len(bin_))
        + struct.pack("<I", len(j)) + b"JSON" + j + struct.pack("<I", len(bin_)) + b"BIN\0" + bin_)


def rgbe(r, g, b):
    m = max(r, g, b)
    if m < 1e-32:
        return bytes(4)
    e = math.frexp(m)[1]
    s = 256.0 / 2 ** e
    return bytes([int(r * s), int(g * s), int(b * s), e + 128])


def hdr_head(w, h):
    return b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w)


def images():
    # Layout byte first (0 latlong, 1 cross, 2 probe, 3 detected), then the file.
    put("hdr", "flat.hdr", b"\0" + hdr_head(4, 2) + rgbe(0.5, 0.25, 1.0) * 8)
    rows = b""
    for y in range(4):
        px = [rgbe(0.1 * x + 0.1, 0.2, 0.3 * y + 0.1) for x in range(8)]
        rows += bytes([2, 2, 0, 8])
        for c in range(4):
            vals = bytes(p[c] for p in px)
            rows += bytes([128 + 8, vals[0]]) if len(set(vals)) == 1 else bytes([8]) + vals
    put("hdr", "rle.hdr", b"\0" + hdr_head(8, 4) + rows)
    put("hdr", "cross.hdr", b"\1" + hdr_head(6, 8) + rgbe(1, 1, 1) * 48)
    put("exr", "float.exr", b"\0" + exr(8, 4))


def exr(w, h):
    """A scanline OpenEXR, no compression, 32-bit float B, G, R channels."""
    def attr(name, kind, value):
        return name + b"\0" + kind + b"\0" + struct.pack("<i", len(value)) + value

    ch = b"".join(c + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in (b"B", b"G", b"R")) + b"\0"
    box = struct.pack("<4i", 0, 0, w - 1, h - 1)
    head = (b"\x76\x2f\x31\x01" + struct.pack("<i", 2)
            + attr(b"channels", b"chlist", ch)
            + attr(b"compression", b"compression", b"\0")
            + attr(b"dataWindow", b"box2i", box)
            + attr(b"displayWindow", b"box2i", box)
            + attr(b"lineOrder", b"lineOrder", b"\0")
            + attr(b"pixelAspectRatio", b"float", struct.pack("<f", 1))
            + attr(b"screenWindowCenter", b"v2f", struct.pack("<2f", 0, 0))
            + attr(b"screenWindowWidth", b"float", struct.pack("<f", 1))
            + b"\0")
    blocks = []
    for y in range(h):
        data = b"".join(struct.pack("<%df" % w, *[(x + 1) * k / w for x in range(w)]) for k in (0.3, 0.6, 0.9))
        blocks.append(struct.pack("<ii", y, len(data)) + data)
    offsets, at = [], len(head) + 8 * h
    for b in blocks:
        offsets.append(at)
        at += len(b)
    return head + struct.pack("<%dQ" % h, *offsets) + b"".join(blocks)


if __name__ == "__main__":
    meshes()
    images()
    print("make_seeds: wrote", root, file=sys.stderr)
