#!/usr/bin/env python3
"""Writes the small assets of the Mitsuba XML test scenes in experiments/scenes/mitsuba/:
a sky environment map (EXR), a PNG texture, a binary PLY torus with normals and UVs and
an OBJ with texture coordinates. Deterministic; needs numpy and mitsuba (for EXR/PNG)."""
import math
import os
import struct
import sys

import numpy as np

out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "experiments", "scenes", "mitsuba")
os.makedirs(out, exist_ok=True)

import mitsuba as mi
mi.set_variant("scalar_rgb")

# Sky: 128x64 latitude-longitude, blue gradient, warm ground, a small bright sun.
w, h = 128, 64
sky = np.zeros((h, w, 3), np.float32)
for j in range(h):
    theta = math.pi * j / (h - 1)
    up = math.cos(theta)
    for i in range(w):
        if up > 0:
            c = np.array([0.35, 0.55, 1.0]) * (0.4 + 0.6 * up)
        else:
            c = np.array([0.30, 0.25, 0.20]) * 0.5
        sky[j, i] = c
sky[14:18, 40:44] = [40.0, 36.0, 30.0]
mi.Bitmap(sky).write(os.path.join(out, "sky.exr"))

# Texture: 64x64 sRGB PNG, coloured tiles with a diagonal stripe.
tex = np.zeros((64, 64, 3), np.uint8)
for y in range(64):
    for x in range(64):
        tex[y, x] = [40 + 3 * x, 60 + 2 * y, 200 if (x // 16 + y // 16) % 2 else 90]
        if abs(x - y) < 3:
            tex[y, x] = [250, 230, 40]
mi.Bitmap(tex, pixel_format=mi.Bitmap.PixelFormat.RGB).write(os.path.join(out, "tiles.png"))

# Torus (binary little-endian PLY with normals and UVs).
R, r, nu, nv = 0.35, 0.15, 64, 32
verts, tris = [], []
for j in range(nv + 1):
    for i in range(nu + 1):
        u, v = 2 * math.pi * i / nu, 2 * math.pi * j / nv
        c = (R + r * math.cos(v))
        p = (c * math.cos(u), r * math.sin(v), c * math.sin(u))
        n = (math.cos(v) * math.cos(u), math.sin(v), math.cos(v) * math.sin(u))
        verts.append(p + n + (i / nu, j / nv))
for j in range(nv):
    for i in range(nu):
        a, b = j * (nu + 1) + i, j * (nu + 1) + i + 1
        c, d = a + nu + 1, b + nu + 1
        tris += [(a, c, b), (b, c, d)]
with open(os.path.join(out, "torus.ply"), "wb") as f:
    f.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % len(verts)).encode())
    for p in ["x", "y", "z", "nx", "ny", "nz", "u", "v"]:
        f.write(("property float %s\n" % p).encode())
    f.write(("element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(tris)).encode())
    for v in verts:
        f.write(struct.pack("<8f", *v))
    for t in tris:
        f.write(struct.pack("<B3i", 3, *t))

# A pyramid OBJ with texture coordinates (v up, as OBJ has it).
with open(os.path.join(out, "pyramid.obj"), "w") as f:
    f.write("# square pyramid\n")
    for p in [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1), (0, 1.4, 0)]:
        f.write("v %g %g %g\n" % p)
    for t in [(0, 0), (1, 0), (1, 1), (0, 1), (0.5, 0.5)]:
        f.write("vt %g %g\n" % t)
    f.write("f 1/1 2/2 3/3 4/4\n")  # bottom faces -y (clockwise seen from above)
    for a, b in [(1, 2), (2, 3), (3, 4), (4, 1)]:
        f.write("f %d/%d 5/5 %d/%d\n" % (a, a, b, b))
print("assets written to", out)
