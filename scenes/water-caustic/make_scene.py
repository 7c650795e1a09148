#!/usr/bin/env python3
"""Writes water.ply: a rippled water surface (a height field of a few
crossing sine waves, with vertex normals; binary PLY) for the water-caustic
scene.

The scene (scene.json) is a pool: a diffuse floor under the water, walls,
and a small bright light on the ceiling, so that almost everything the
camera sees of the floor is lit through the water: caustic filaments
(L S D S E). It is photonfarm's own caustic benchmark (bench/progressive.py);
regenerate with `python3 make_scene.py` (deterministic)."""
import math
import struct

N = 96            # grid cells per side
HALF = 1.0        # the surface spans [-HALF, HALF] in x and z
LEVEL = 0.45      # the water's mean height
# (amplitude, wavelength, direction in degrees, phase)
WAVES = [(0.012, 0.55, 20.0, 0.3), (0.009, 0.37, 110.0, 1.7), (0.006, 0.23, 200.0, 2.9),
         (0.004, 0.17, 300.0, 0.8)]


def height(x, z):
    h = LEVEL
    for a, lam, deg, ph in WAVES:
        k = 2.0 * math.pi / lam
        d = math.radians(deg)
        h += a * math.sin(k * (x * math.cos(d) + z * math.sin(d)) + ph)
    return h


def normal(x, z):
    # -dh/dx, 1, -dh/dz
    gx = gz = 0.0
    for a, lam, deg, ph in WAVES:
        k = 2.0 * math.pi / lam
        d = math.radians(deg)
        c = a * k * math.cos(k * (x * math.cos(d) + z * math.sin(d)) + ph)
        gx += c * math.cos(d)
        gz += c * math.sin(d)
    l = math.sqrt(gx * gx + 1.0 + gz * gz)
    return (-gx / l, 1.0 / l, -gz / l)


def main():
    verts = []
    for j in range(N + 1):
        for i in range(N + 1):
            x = -HALF + 2.0 * HALF * i / N
            z = -HALF + 2.0 * HALF * j / N
            verts.append((x, height(x, z), z) + normal(x, z))
    faces = []
    for j in range(N):
        for i in range(N):
            a = j * (N + 1) + i
            b, c, d = a + 1, a + N + 2, a + N + 1
            # counter-clockwise seen from above: the normal points up
            faces.append((a, d, c))
            faces.append((a, c, b))
    head = ("ply\nformat binary_little_endian 1.0\ncomment water.ply: written by make_scene.py\n"
            "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
            "property float nx\nproperty float ny\nproperty float nz\n"
            "element face %d\nproperty list uchar int vertex_indices\nend_header\n" % (len(verts), len(faces)))
    with open("water.ply", "wb") as f:
        f.write(head.encode("ascii"))
        for v in verts:
            f.write(struct.pack("<6f", *v))
        for t in faces:
            f.write(struct.pack("<B3i", 3, *t))


if __name__ == "__main__":
    main()
