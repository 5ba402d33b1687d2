#!/usr/bin/env python3
"""Write room.obj + room.mtl: the closed 2 x 2 x 2 room of examples/cuts_room.json, six walls
facing inwards (one-sided: their winding and normals point into the room), each split into
DIV x DIV quads so the per-vertex cuts resolve the indirect light near the corners. Left wall
red, right wall green, the others white (Cornell-box-like). Run from this folder."""

DIV = 12
WALLS = [  # material, origin, u, v  (u x v is the inward normal)
    ("white", (-1, 0, -1), (0, 0, 2), (2, 0, 0)),  # floor, +Y
    ("white", (-1, 2, -1), (2, 0, 0), (0, 0, 2)),  # ceiling, -Y
    ("red", (-1, 0, -1), (0, 2, 0), (0, 0, 2)),  # left, +X
    ("green", (1, 0, -1), (0, 0, 2), (0, 2, 0)),  # right, -X
    ("white", (-1, 0, -1), (2, 0, 0), (0, 2, 0)),  # back, +Z
    ("white", (-1, 0, 1), (0, 2, 0), (2, 0, 0)),  # front, -Z
]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


with open("room.mtl", "w") as m:
    m.write("newmtl white\nKd 0.7 0.7 0.7\n\nnewmtl red\nKd 0.7 0.15 0.1\n\n")
    m.write("newmtl green\nKd 0.15 0.6 0.15\n")

lines = ["# written by make_room.py", "mtllib room.mtl"]
base = 1
for k, (mat, o, u, v) in enumerate(WALLS):
    n = cross(u, v)
    length = sum(c * c for c in n) ** 0.5
    lines.append("vn %g %g %g" % tuple(c / length for c in n))
    for i in range(DIV + 1):
        for j in range(DIV + 1):
            s, t = i / DIV, j / DIV
            lines.append("v %g %g %g" % tuple(o[c] + s * u[c] + t * v[c] for c in range(3)))
    lines.append("usemtl " + mat)
    vn = k + 1
    for i in range(DIV):
        for j in range(DIV):
            a = base + i * (DIV + 1) + j
            b, c, d = a + (DIV + 1), a + 1, a + (DIV + 1) + 1
            # (a, a + u, a + v) winds to u x v.
            lines.append("f %d//%d %d//%d %d//%d" % (a, vn, b, vn, c, vn))
            lines.append("f %d//%d %d//%d %d//%d" % (b, vn, d, vn, c, vn))
    base += (DIV + 1) ** 2
with open("room.obj", "w") as f:
    f.write("\n".join(lines) + "\n")
