#!/usr/bin/env python3
"""Converts Bitterli's pbrt-v3 Cornell box (CC0) into cornell-box.obj/.mtl.

Usage: python3 make_obj.py path/to/bitterli-cornell-box/scene.pbrt

Every "trianglemesh" shape becomes one OBJ group with its NamedMaterial,
keeping the pbrt vertex order and index order exactly, so the winding (and so
the light's emitting side, facing -y) is the pbrt file's. The per-vertex
"normal N" is dropped: these are flat quads, and flat shading is exact.
"""
import re
import sys

NAMES = ["Floor", "Ceiling", "BackWall", "RightWall", "LeftWall", "ShortBox", "TallBox", "Light"]


def floats(block, key):
    m = re.search(r'"%s"\s*\[([^\]]*)\]' % key, block)
    return m.group(1).split()


def main(pbrt_path):
    text = open(pbrt_path).read()
    kd = {m.group(1): m.group(2).split()
          for m in re.finditer(r'MakeNamedMaterial "(\w+)".*?"rgb Kd" \[([^\]]*)\]', text)}
    shapes = []
    for m in re.finditer(r'NamedMaterial "(\w+)"\s*\n\s*Shape "trianglemesh"(.*)', text):
        name, rest = m.group(1), m.group(2)
        p = floats(rest, "point P")
        idx = [int(i) for i in floats(rest, "integer indices")]
        shapes.append((name, [p[i:i + 3] for i in range(0, len(p), 3)], idx))
    assert [s[0] for s in shapes] == NAMES, [s[0] for s in shapes]

    with open("cornell-box.obj", "w") as f:
        f.write("# Bitterli's Cornell box (CC0, see LICENSE.txt), converted from the pbrt-v3 scene.pbrt\n"
                "# by make_obj.py: same vertices, same triangle index order (winding), one group per shape.\n"
                "# The light quad's face normal (counter-clockwise winding) points down (-y).\n\n"
                "mtllib cornell-box.mtl\n")
        base = 1
        for name, verts, idx in shapes:
            f.write("\ng %s\nusemtl %s\n" % (name, name))
            for v in verts:
                f.write("v %s %s %s\n" % tuple(v))
            for t in range(0, len(idx), 3):
                f.write("f %d %d %d\n" % tuple(base + i for i in idx[t:t + 3]))
            base += len(verts)
    with open("cornell-box.mtl", "w") as f:
        f.write("# Materials of Bitterli's Cornell box (CC0): Lambertian albedos from scene.pbrt.\n"
                "# The light is black (non-reflecting) and emits radiance Ke on its front side only.\n")
        for name in ["LeftWall", "RightWall", "Floor", "Ceiling", "BackWall", "ShortBox", "TallBox", "Light"]:
            f.write("\nnewmtl %s\n" % name)
            if name == "Light":
                f.write("Kd 0 0 0\nKe 17 12 4\n")
            else:
                f.write("Kd %s %s %s\n" % tuple(kd[name]))


if __name__ == "__main__":
    main(sys.argv[1])
