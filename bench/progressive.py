#!/usr/bin/env python3
"""progressive.py: anytime rendering, measured (issue: progressive passes).

Two studies, each render one process, wall time measured around it:

  deadlines   `render SCENE --time-limit L` on the Cornell scenes at 512x512
              for each limit L: the wall time against L and the relMSE
              against ../shared/references/SCENE-512.pfm; with --single-exe
              (a build from before the progressive passes) the same limits
              rendered by its one-pass planner, for the comparison.
  caustic     the water-caustic scene (scenes/water-caustic, a pool lit
              through rippled water: its floor is almost all caustic):
              relMSE after a 4x box downsample against a long progressive
              render of the same scene, the light's own reflections in the
              water masked (blocks holding a reference pixel above 1.5,
              a few specks: the lights seen directly, as the Bitterli
              references are judged) (--caustic-ref seconds; the
              progressive estimate is consistent, so its long run is the
              reference), for time limits T, 2T, 4T, 8T: the error at 8x the
              time over the error at T. With --single-exe, its one-pass
              renders at the same limits.

Prints markdown tables (and writes them with the raw rows as CSV to --out).
Standard library only. Example:

  python3 bench/progressive.py --single-exe /path/to/old/photonfarm
"""

import argparse
import csv
import json
import os
import re
import struct
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def read_pfm(path):
    with open(path, 'rb') as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = f.read()
    assert kind == b'PF', path
    endian = '<' if scale < 0 else '>'
    vals = struct.unpack(endian + '%df' % (3 * w * h), data[:12 * w * h])
    return w, h, vals


def write_pfm(path, w, h, vals):
    with open(path, 'wb') as f:
        f.write(b'PF\n%d %d\n-1.0\n' % (w, h))
        f.write(struct.pack('<%df' % len(vals), *vals))


def downsample(src, dst, k):
    w, h, v = read_pfm(src)
    ow, oh = w // k, h // k
    out = [0.0] * (3 * ow * oh)
    inv = 1.0 / (k * k)
    for y in range(oh):
        for x in range(ow):
            for c in range(3):
                s = 0.0
                for dy in range(k):
                    row = ((y * k + dy) * w + x * k) * 3 + c
                    for dx in range(k):
                        s += v[row + 3 * dx]
                out[3 * (y * ow + x) + c] = s * inv
    write_pfm(dst, ow, oh, out)


def masked_relmse(img4, ref4, ref_full, k):
    """relMSE of img4 against ref4 (both k-times downsampled), leaving out
    the blocks where the full-size reference has a pixel above 1.5."""
    w, h, a = read_pfm(img4)
    rw, rh, b = read_pfm(ref4)
    fw, fh, f = read_pfm(ref_full)
    assert (w, h) == (rw, rh) and fw == w * k
    total, n = 0.0, 0
    for y in range(h):
        for x in range(w):
            bright = False
            for dy in range(k):
                row = ((y * k + dy) * fw + x * k) * 3
                if max(f[row:row + 3 * k]) > 1.5:
                    bright = True
                    break
            if bright:
                continue
            for c in range(3):
                i = 3 * (y * w + x) + c
                total += (a[i] - b[i]) ** 2 / (b[i] ** 2 + 0.01)
            n += 3
    return total / n if n else float('nan')


def render(exe, scene, args, out, log):
    cmd = [exe, 'render', scene, '-o', out + '.png', '--hdr', out + '.pfm'] + args
    t0 = time.monotonic()
    with open(log, 'w') as lf:
        rc = subprocess.call(cmd, stdout=lf, stderr=subprocess.STDOUT)
    wall = time.monotonic() - t0
    with open(log) as lf:
        text = lf.read()
    m = re.search(r'passes: (\d+) whole(?: \+ (\d+) of (\d+) tiles of pass \d+)?, (\d+) samples per pixel', text)
    passes = m.group(1) + (('+' + m.group(2) + '/' + m.group(3) + ' tiles') if m.group(2) else '') if m else '1'
    spp = m.group(4) if m else ''
    if not m:
        m2 = re.search(r'(\d+) spp x', text)
        spp = m2.group(1) if m2 else ''
    return rc, wall, passes, spp


def compare(exe, img, ref):
    r = subprocess.run([exe, 'compare', img, ref, '--json'], capture_output=True, text=True)
    if r.returncode != 0:
        return None
    return json.loads(r.stdout)


def deadlines(args, rows):
    for scene in args.scenes:
        path = os.path.join(ROOT, 'scenes', scene, 'scene.json')
        ref = os.path.join(args.references, scene + '-512.pfm')
        for limit in args.limits:
            for label, exe in args.builds:
                out = os.path.join(args.out, '%s-%s-%g' % (scene, label, limit))
                rc, wall, passes, spp = render(exe, path, ['--time-limit', '%g' % limit] + args.extra, out,
                                               out + '.log')
                c = compare(args.exe, out + '.pfm', ref) if rc == 0 else None
                row = dict(study='deadlines', scene=scene, build=label, limit=limit, wall=round(wall, 2),
                           ratio=round(wall / limit, 3), passes=passes, spp=spp, rc=rc,
                           relmse=c['relmse'] if c else '', lum=c['lum_ratio'] if c else '')
                rows.append(row)
                print('%-16s %-12s limit %6g s: wall %7.2f s (%.3f), passes %s, spp %s, relMSE %s' %
                      (scene, label, limit, wall, wall / limit, passes, spp, row['relmse']), flush=True)


def caustic(args, rows):
    scene = os.path.join(ROOT, 'scenes', 'water-caustic', 'scene.json')
    ref = os.path.join(args.out, 'water-ref')
    if not os.path.exists(ref + '.pfm') or args.fresh_ref:
        print('reference: progressive, %g s ...' % args.caustic_ref, flush=True)
        rc, wall, passes, spp = render(args.exe, scene, ['--time-limit', '%g' % args.caustic_ref] + args.extra, ref,
                                       ref + '.log')
        if rc != 0:
            sys.exit('the reference render failed: see %s.log' % ref)
        print('reference: %.1f s, passes %s, %s spp' % (wall, passes, spp), flush=True)
    downsample(ref + '.pfm', ref + '-4x.pfm', 4)
    base = args.caustic_time
    for label, exe in args.builds:
        errs = []
        for k in (1, 2, 4, 8):
            t = base * k
            out = os.path.join(args.out, 'water-%s-%g' % (label, t))
            rc, wall, passes, spp = render(exe, scene, ['--time-limit', '%g' % t] + args.extra, out, out + '.log')
            c = c4 = None
            if rc == 0:
                c = compare(args.exe, out + '.pfm', ref + '.pfm')
                downsample(out + '.pfm', out + '-4x.pfm', 4)
                c4 = masked_relmse(out + '-4x.pfm', ref + '-4x.pfm', ref + '.pfm', 4)
            e4 = c4 if c4 is not None else float('nan')
            errs.append(e4)
            row = dict(study='caustic', scene='water-caustic', build=label, limit=t, wall=round(wall, 2),
                       ratio=round(wall / t, 3), passes=passes, spp=spp, rc=rc, relmse=c['relmse'] if c else '',
                       relmse4=e4, lum=c['lum_ratio'] if c else '')
            rows.append(row)
            print('water-caustic    %-12s limit %6g s: wall %7.2f s, passes %s, relMSE %s, after 4x downsample %.3g' %
                  (label, t, wall, passes, row['relmse'], e4), flush=True)
        if errs[0] > 0:
            print('%s: error at 8x the time / error at 1x = %.3f' % (label, errs[-1] / errs[0]), flush=True)


def table(rows):
    lines = ['| study | scene | build | limit (s) | wall (s) | wall / limit | passes | spp | relMSE | relMSE 4x |',
             '|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        def f(v):
            return ('%.3g' % v) if isinstance(v, float) else str(v)
        lines.append('| %s | %s | %s | %g | %.2f | %.3f | %s | %s | %s | %s |' %
                     (r['study'], r['scene'], r['build'], r['limit'], r['wall'], r['ratio'], r['passes'], r['spp'],
                      f(r['relmse']), f(r.get('relmse4', ''))))
    return '\n'.join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--exe', default=os.path.join(ROOT, 'build', 'bin', 'photonfarm'))
    ap.add_argument('--single-exe', help='a photonfarm from before the progressive passes (one-pass --time-limit)')
    ap.add_argument('--references', default=os.path.join(ROOT, '..', 'shared', 'references'))
    ap.add_argument('--scenes', default='cornell-spheres,cornell-box')
    ap.add_argument('--limits', default='10,30,120')
    ap.add_argument('--caustic-time', type=float, default=5.0, help='T: the caustic study renders T, 2T, 4T, 8T')
    ap.add_argument('--caustic-ref', type=float, default=300.0, help='seconds of the caustic reference render')
    ap.add_argument('--fresh-ref', action='store_true', help='render the caustic reference again')
    ap.add_argument('--only', choices=['deadlines', 'caustic'])
    ap.add_argument('--extra', default='', help='more render options, e.g. "--workers 2 --threads 1"')
    ap.add_argument('--out', default=os.path.join(ROOT, 'build', 'bench-progressive'))
    args = ap.parse_args()
    args.scenes = [s for s in args.scenes.split(',') if s]
    args.limits = [float(x) for x in args.limits.split(',') if x]
    args.extra = args.extra.split()
    args.builds = [('progressive', args.exe)] + ([('one-pass', args.single_exe)] if args.single_exe else [])
    os.makedirs(args.out, exist_ok=True)
    rows = []
    if args.only in (None, 'deadlines'):
        deadlines(args, rows)
    if args.only in (None, 'caustic'):
        caustic(args, rows)
    md = table(rows)
    print()
    print(md)
    with open(os.path.join(args.out, 'progressive.md'), 'w') as f:
        f.write(md + '\n')
    with open(os.path.join(args.out, 'progressive.csv'), 'w', newline='') as f:
        keys = ['study', 'scene', 'build', 'limit', 'wall', 'ratio', 'passes', 'spp', 'rc', 'relmse', 'relmse4', 'lum']
        w = csv.DictWriter(f, fieldnames=keys, extrasaction='ignore')
        w.writeheader()
        for r in rows:
            w.writerow(r)
    return 0


if __name__ == '__main__':
    sys.exit(main())
