#!/usr/bin/env python3
"""make_mesh.py: generates the benchmark's large mesh at run time.

The triangle-count scaling study (bench/bench.py --scaling) needs a mesh far
larger than the bunny's 69k triangles. A million-triangle file is about 19 MB,
too big to commit, so this script builds it when needed: a displaced "cube
sphere" (each face of a cube split into n x n cells, two triangles per cell,
the vertices pushed onto a sphere and then along the radius by a fixed sum of
sines), written as a binary little-endian PLY, plus a JSON scene that puts it
in the Cornell box of scenes/bunny/scene.json (same walls, light and camera)
with a diffuse material.

The output depends on n alone (the sine directions come from a seeded
generator), so a second run finds the files and does nothing. Triangles:
12 n^2; the default n = 289 gives 1,002,252.

Usage: python3 bench/make_mesh.py [--out DIR] [--n N] [--force]
Prints the path of the scene file on stdout. Standard library only.
"""

import argparse
import array
import json
import math
import os
import random
import struct
import sys

DEFAULT_N = 289  # 12 * 289^2 = 1,002,252 triangles

# The six cube faces as (normal axis, sign): each face maps (u, v) in
# [-1, 1]^2 to a point of the cube's surface.
FACES = [(0, 1), (0, -1), (1, 1), (1, -1), (2, 1), (2, -1)]


def cube_point(axis, sign, u, v):
    """The point of face (axis, sign) of the cube [-1, 1]^3 at (u, v)."""
    if axis == 0:
        return (sign, u, v)
    if axis == 1:
        return (v, sign, u)
    return (u, v, sign)


def outward(axis, sign):
    """Whether triangles (a, a+1, a+side+1) of this face, in the vertex order
    write_mesh uses, face away from the centre. Worked out from the face's
    tangents rather than by hand, so a change to cube_point cannot turn a
    face inside out unnoticed."""
    p0 = cube_point(axis, sign, 0.0, 0.0)
    pu = cube_point(axis, sign, 1.0, 0.0)
    pv = cube_point(axis, sign, 1.0, 1.0)
    e1 = [pu[k] - p0[k] for k in range(3)]
    e2 = [pv[k] - p0[k] for k in range(3)]
    nrm = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    return sum(nrm[k] * p0[k] for k in range(3)) > 0


def make_displacement(seed=1, terms=8):
    """A smooth bump function on the unit sphere: a sum of sines along random
    directions with falling amplitude. Its absolute value stays below 0.15,
    so the surface never folds through the centre."""
    rng = random.Random(seed)
    waves = []
    amp = 0.05
    freq = 3.0
    for _ in range(terms):
        d = [rng.gauss(0, 1) for _ in range(3)]
        norm = math.sqrt(sum(c * c for c in d)) or 1.0
        waves.append((d[0] / norm * freq, d[1] / norm * freq, d[2] / norm * freq,
                      rng.uniform(0, 2 * math.pi), amp))
        amp *= 0.6
        freq *= 1.7

    def disp(x, y, z):
        s = 0.0
        for ax, ay, az, ph, a in waves:
            s += a * math.sin(ax * x + ay * y + az * z + ph)
        return s
    return disp


def write_mesh(path, n):
    """Writes the displaced cube sphere with n x n cells per face to path
    (binary little-endian PLY). Seam vertices are duplicated per face; they
    are computed from the same cube coordinates, so they coincide exactly."""
    disp = make_displacement()
    side = n + 1
    coords = [-1.0 + 2.0 * i / n for i in range(side)]
    verts = array.array('f')
    for axis, sign in FACES:
        for j in range(side):
            v = coords[j]
            for i in range(side):
                x, y, z = cube_point(axis, sign, coords[i], v)
                r = math.sqrt(x * x + y * y + z * z)
                x, y, z = x / r, y / r, z / r
                k = 1.0 + disp(x, y, z)
                verts.extend((x * k, y * k, z * k))
    if sys.byteorder != 'little':
        verts.byteswap()

    nverts = 6 * side * side
    ntris = 12 * n * n
    face = struct.Struct('<BIII')
    body = bytearray(face.size * ntris)
    off = 0
    for f, (axis, sign) in enumerate(FACES):
        base = f * side * side
        flip = not outward(axis, sign)
        for j in range(n):
            row = base + j * side
            for i in range(n):
                a = row + i
                b = a + 1
                c = a + side + 1
                d = a + side
                if flip:
                    b, d = d, b
                face.pack_into(body, off, 3, a, b, c)
                face.pack_into(body, off + face.size, 3, a, c, d)
                off += 2 * face.size

    header = ("ply\nformat binary_little_endian 1.0\n"
              "comment photonfarm bench/make_mesh.py: displaced cube sphere, n = %d\n"
              "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
              "element face %d\nproperty list uchar uint vertex_indices\nend_header\n"
              % (n, nverts, ntris))
    tmp = path + '.tmp'
    with open(tmp, 'wb') as fp:
        fp.write(header.encode('ascii'))
        fp.write(verts.tobytes())
        fp.write(body)
    os.replace(tmp, path)  # a killed run leaves no half-written mesh behind
    return ntris


def scene_json(ply_name, bunny_scene):
    """The bunny's Cornell box with the mesh in place of the bunny and the
    mirror sphere. The box comes from scenes/bunny/scene.json so that the two
    stay the same scene apart from the model."""
    with open(bunny_scene) as fp:
        scene = json.load(fp)
    objects = [o for o in scene['objects'] if o.get('type') == 'quad']
    scene['materials'] = [m for m in scene['materials'] if m['name'] in ('white', 'red', 'green', 'light')]
    scene['materials'].append({'name': 'clay', 'type': 'diffuse', 'kd': [0.6, 0.55, 0.5]})
    objects.append({'type': 'ply', 'file': ply_name, 'material': 'clay',
                    'comment': 'radius about 0.45 with bumps; stands on the floor',
                    'transform': {'scale': 0.45, 'translate': [0, 0.53, 0]}})
    scene['objects'] = objects
    return scene


def main(argv=None):
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--out', default=os.path.join(root, 'build', 'bench'),
                    help='output folder (default: build/bench, which git ignores)')
    ap.add_argument('--n', type=int, default=DEFAULT_N,
                    help='cells per cube-face side; 12 n^2 triangles (default %d)' % DEFAULT_N)
    ap.add_argument('--force', action='store_true', help='rewrite the files even if they exist')
    args = ap.parse_args(argv)
    if args.n < 1 or args.n > 4000:
        ap.error('--n must be in 1..4000')

    os.makedirs(args.out, exist_ok=True)
    ply_name = 'displaced-sphere-%d.ply' % args.n
    ply_path = os.path.join(args.out, ply_name)
    scene_path = os.path.join(args.out, 'displaced-sphere-%d.json' % args.n)
    if args.force or not os.path.exists(ply_path):
        ntris = write_mesh(ply_path, args.n)
        print('make_mesh: wrote %s (%d triangles)' % (ply_path, ntris), file=sys.stderr)
    scene = scene_json(ply_name, os.path.join(root, 'scenes', 'bunny', 'scene.json'))
    with open(scene_path, 'w') as fp:
        json.dump(scene, fp, indent=1)
        fp.write('\n')
    print(scene_path)
    return 0


if __name__ == '__main__':
    sys.exit(main())
