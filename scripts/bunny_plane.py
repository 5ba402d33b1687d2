#!/usr/bin/env python3
"""Write bunny.obj with a ground plane under it (RESULTS.md section 11, the light-tree table).

The plane is a 33 x 33-vertex grid (32 x 32 quads, facing +Y) at the bunny's lowest y,
centred under its bounding box, 3 times its larger horizontal extent wide.

usage: scripts/bunny_plane.py ../shared/data/meshes/bunny.obj /tmp/bunny_plane.obj
"""
import sys


def main(src_path, out_path, divisions=32):
    src = open(src_path).read().splitlines()
    vs = [list(map(float, l.split()[1:4])) for l in src if l.startswith("v ")]
    lo = [min(v[i] for v in vs) for i in range(3)]
    hi = [max(v[i] for v in vs) for i in range(3)]
    cx, cz, y = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2, lo[1]
    ext = 3 * max(hi[0] - lo[0], hi[2] - lo[2])
    out = src[:]
    n = divisions + 1
    for i in range(n):
        for j in range(n):
            x = cx + (j / divisions - 0.5) * ext
            z = cz + (i / divisions - 0.5) * ext
            out.append("v %f %f %f" % (x, y, z))
    for i in range(divisions):
        for j in range(divisions):
            a = len(vs) + 1 + i * n + j
            # Counter-clockwise seen from +Y, as relight's ground_plane.
            out.append("f %d %d %d" % (a, a + n, a + 1))
            out.append("f %d %d %d" % (a + 1, a + n, a + n + 1))
    open(out_path, "w").write("\n".join(out) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
