#!/usr/bin/env python3
"""bench.py: photonfarm's benchmark harness (run time against error, scaling).

It renders the shipped scenes over sweeps of settings with build/bin/photonfarm,
one process per point, and measures each render from the outside: wall time
with a monotonic clock around the process, peak memory from the process's own
rusage (os.wait4), and error against the references in ../shared/references
with `photonfarm compare --json`. The photon-pass and render times come from
the renderer's log. Results go to a CSV; a markdown report and gnuplot PNGs
are made from the CSV, so a report can be rebuilt without rendering again
(--report-only). With --docs the report is written into docs/benchmarks.md
between its GENERATED markers and the plots into docs/images/bench-*.png.

Two studies:

  sweep (default)  each family varies one setting from a base, at 512x512
                   (--quick: 128x128 and fewer points): photons, caustic,
                   gather, spp, workers (threads and local worker processes),
                   time-limit and quality (the last two only when
                   `photonfarm render --help` lists --time-limit / --quality).
                   Plot: relMSE against wall time, log-log, one curve per
                   family, with pbrt-v3's figures and the goal drawn in.
  --scaling        time and memory against photon count, triangle count (the
                   bunny at its four resolutions and a generated
                   million-triangle mesh, bench/make_mesh.py), resolution and
                   threads.

Reruns replace only the rows of the (scene, family) or study they measure;
other rows of the CSV are kept, so a study can be redone alone.

Robustness: a render that fails or exceeds --timeout is recorded with its
status and the tail of its log, and the sweep goes on; the exit code is then 1.
Logs of every render stay in the work folder (default build/bench).

Single-threaded; standard library only. See bench/README.md for usage.
"""

import argparse
import csv
import datetime
import json
import math
import os
import platform
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

SCENES = ['cornell-spheres', 'cornell-box']

# The peer: pbrt-v3 on this machine kind (512x512, 2 threads), relMSE against
# the same references, cornell-spheres only. The goal is the target for
# --time-limit on both scenes (about half the peer's SPPM error).
PEER_SPPM = [(10, 0.0061), (30, 0.0023), (120, 0.00086)]
PEER_PATH = [(10, 0.21), (30, 0.066), (120, 0.016)]
PEER_SCENE = 'cornell-spheres'
GOAL = [(10, 0.003), (30, 0.0011)]
BUDGETS = [10, 30, 120]

# The base each family departs from. Full: the renderer's defaults (one render
# is 15-20 s on 2 cores), so every family crosses the default point. Quick:
# 128x128 with lighter settings, a second or two per render.
BASE = {
    'full': {'size': 512, 'spp': 36, 'gather': 1, 'filter': 2, 'light': 2, 'photons': 400000, 'caustic': 400000},
    'quick': {'size': 128, 'spp': 4, 'gather': 2, 'filter': 2, 'light': 2, 'photons': 100000, 'caustic': 100000},
}

# family: the setting it varies and its values (full, quick). "workers" and
# "quality" are lists of labels; their meaning is in s_family_points.
FAMILIES = {
    'photons': ('photons', [100000, 400000, 1600000], [25000, 50000, 100000, 200000]),
    'caustic': ('caustic', [100000, 400000, 1600000], [25000, 50000, 100000, 200000]),
    'gather': ('gather', [1, 2, 4], [1, 2, 4]),
    'filter': ('filter', [0, 1, 2, 3], [0, 2]),
    'light': ('light', [1, 2, 4], [1, 2]),
    'spp': ('spp', [9, 36, 144], [1, 4, 16]),
    'workers': ('workers', None, None),
    'time-limit': ('time_limit', [10, 30, 120], [2, 5]),
    'quality': ('quality', ['draft', 'default', 'high'], ['draft', 'default']),
}
# Options a family needs from `photonfarm render --help`.
FAMILY_NEEDS = {'time-limit': '--time-limit', 'quality': '--quality', 'workers': '--workers'}

STUDIES = ['photons', 'triangles', 'resolution', 'threads']

SWEEP_COLS = ['scene', 'family', 'value', 'size', 'spp', 'gather', 'photons', 'caustic', 'workers', 'threads',
              'wall_s', 'photon_s', 'render_s', 'peak_rss_mb', 'relmse', 'rmse', 'lum_ratio', 'git', 'date',
              'time_limit', 'quality', 'cpu_s', 'load_s', 'triangles', 'global_stored', 'caustic_stored',
              'reference', 'status', 'note', 'machine', 'load_avg', 'filter', 'light']
SCALING_COLS = ['study', 'value', 'scene', 'size', 'spp', 'gather', 'photons', 'caustic', 'workers', 'threads',
                'triangles', 'wall_s', 'load_s', 'accel_other_s', 'trace_s', 'kdtree_s', 'irradiance_s',
                'photon_s', 'render_s', 'peak_rss_mb', 'global_stored', 'caustic_stored', 'bytes_per_photon',
                'relmse', 'rmse', 'lum_ratio', 'git', 'date', 'cpu_s', 'reference', 'status', 'note', 'machine',
                'load_avg']

MARK_BEGIN = '<!-- BEGIN GENERATED %s: written by bench/bench.py --docs; edits here are overwritten -->'
MARK_END = '<!-- END GENERATED %s -->'


def log(msg):
    print(msg, file=sys.stderr, flush=True)


# ---------------------------------------------------------------- the machine

def machine_info():
    """One line naming the machine: CPU model, cores, memory, kernel."""
    model = ''
    try:
        with open('/proc/cpuinfo') as fp:
            for line in fp:
                if line.startswith('model name'):
                    model = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    mem = ''
    try:
        with open('/proc/meminfo') as fp:
            for line in fp:
                if line.startswith('MemTotal:'):
                    mem = '%.1f GiB RAM' % (int(line.split()[1]) / 1048576.0)
                    break
    except OSError:
        pass
    parts = ['%d cores' % (os.cpu_count() or 1)]
    if model:
        parts.append(re.sub(r'\s+', ' ', model))
    if mem:
        parts.append(mem)
    parts.append('%s %s' % (platform.system(), platform.release()))
    return ', '.join(parts)


def binary_version(exe):
    """(version line, git hash) of the photonfarm binary; the hash is the
    commit it was built from, which is what the figures belong to."""
    try:
        out = subprocess.run([exe, '--version'], capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return '', ''
    m = re.search(r'\(([0-9a-f]{7,40}[^)]*)\)', out)
    return out, (m.group(1) if m else '')


def head_hash():
    try:
        return subprocess.run(['git', 'rev-parse', '--short=12', 'HEAD'], cwd=ROOT, capture_output=True,
                              text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ''


def render_help(exe):
    try:
        p = subprocess.run([exe, 'render', '--help'], capture_output=True, text=True, timeout=30)
        return p.stdout + p.stderr
    except (OSError, subprocess.SubprocessError):
        return ''


# ------------------------------------------------------------ running renders

def run_process(cmd, log_path, timeout):
    """Runs cmd with stdout and stderr to log_path and waits at most timeout
    seconds. Returns a dict: status ('ok', 'failed', 'timeout'), exit code,
    wall seconds, peak RSS in MiB, CPU seconds.

    The process is reaped with os.wait4, whose rusage is that of the child
    itself together with the descendants it reaped (the kernel's RUSAGE_BOTH),
    so ru_maxrss is the largest resident set of the coordinator or any worker
    process it started - the largest single process, not their sum. A thread
    blocks in wait4 so that the clock stops when the process ends, not at the
    next poll. The render runs in its own session: on a timeout the whole
    process group (local workers too) is sent SIGTERM, then SIGKILL."""
    res = {}
    with open(log_path, 'wb') as logf:
        t0 = time.monotonic()
        try:
            p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=logf, stderr=subprocess.STDOUT,
                                 cwd=ROOT, start_new_session=True)
        except OSError as e:
            return {'status': 'failed', 'code': '', 'wall_s': '', 'rss_mb': '', 'cpu_s': '',
                    'note': 'cannot start: %s' % e}

    def reap():
        _, st, ru = os.wait4(p.pid, 0)
        res['t1'] = time.monotonic()
        res['st'] = st
        res['ru'] = ru

    th = threading.Thread(target=reap, daemon=True)
    th.start()
    th.join(timeout)
    timed_out = th.is_alive()
    if timed_out:
        for sig, grace in ((signal.SIGTERM, 10), (signal.SIGKILL, 10)):
            try:
                os.killpg(p.pid, sig)
            except ProcessLookupError:
                pass
            th.join(grace)
            if not th.is_alive():
                break
    note = ''
    # Whatever the renderer left behind in its group (a local worker that
    # missed its BYE) must not run on into the next measurement.
    try:
        os.killpg(p.pid, signal.SIGKILL)
        note = 'stray processes in the render\'s group were killed'
    except (ProcessLookupError, PermissionError):
        pass
    if 'st' not in res:
        return {'status': 'timeout', 'code': '', 'wall_s': '', 'rss_mb': '', 'cpu_s': '',
                'note': 'no exit after SIGKILL'}
    code = os.waitstatus_to_exitcode(res['st'])
    p.returncode = code  # reaped here; keeps Popen from waiting on a pid that is gone
    ru = res['ru']
    out = {'status': 'timeout' if timed_out else ('ok' if code == 0 else 'failed'), 'code': code,
           'wall_s': res['t1'] - t0, 'rss_mb': ru.ru_maxrss / 1024.0, 'cpu_s': ru.ru_utime + ru.ru_stime,
           'note': note}
    if timed_out:
        out['note'] = ('timed out after %g s' % timeout) + ('; ' + note if note else '')
    return out


def log_tail(path, lines=3):
    try:
        with open(path, 'rb') as fp:
            text = fp.read()[-4000:].decode('utf-8', 'replace')
    except OSError:
        return ''
    tail = [ln.strip() for ln in text.splitlines() if ln.strip()][-lines:]
    # Drop the log's timestamps: the message is what the CSV needs.
    return ' | '.join(re.sub(r'^\d{4}-\d\d-\d\dT[\d:.]+Z\s*', '', ln) for ln in tail)


_NUM = r'([0-9]+(?:\.[0-9]*)?(?:[eE][-+]?[0-9]+)?)'
# Each field is searched for on its own in the last line that starts with
# its prefix, so a line the renderer no longer prints (or prints with fewer
# parts) leaves only that field empty.
LOG_FIELDS = [
    ('scene ', 'triangles', r': ([0-9]+) triangles'),
    ('scene ', 'load_s', r'\(' + _NUM + r' s to load\)'),
    ('settings:', 'width', r'settings: ([0-9]+)x[0-9]+'),
    ('settings:', 'height', r'settings: [0-9]+x([0-9]+)'),
    ('settings:', 'spp', r'([0-9]+) spp'),
    ('settings:', 'photons', r'([0-9]+) global'),
    ('settings:', 'caustic', r'([0-9]+) caustic'),
    ('settings:', 'gather', r'([0-9]+) gather'),
    ('settings:', 'filter', r'\(filter ([0-9]+)\)'),
    ('settings:', 'light', r'([0-9]+) light samples'),
    ('time limit ', 'spp', r'([0-9]+) spp'),
    ('time limit ', 'photons', r': ([0-9]+) global'),
    ('time limit ', 'caustic', r'([0-9]+) caustic'),
    ('photon pass:', 'global_stored', r'photon pass: ([0-9]+) global'),
    ('photon pass:', 'caustic_stored', r'([0-9]+) caustic photons'),
    ('photon pass:', 'trace_s', r'trace ' + _NUM + r' s'),
    ('photon pass:', 'kdtree_s', r'kd-trees ' + _NUM + r' s'),
    ('photon pass:', 'irradiance_s', r'irradiance ' + _NUM + r' s'),
    ('done in', 'done_s', r'done in ' + _NUM + r' s'),
    ('done in', 'photon_s', r'photons ' + _NUM + r' s'),
    ('done in', 'render_s', r'render ' + _NUM + r' s'),
]


def parse_log(text):
    """The figures photonfarm's log gives, as strings; missing ones absent."""
    last = {}
    for line in text.splitlines():
        msg = re.sub(r'^\d{4}-\d\d-\d\dT[\d:.]+Z\s*', '', line.strip())
        for prefix, _, _ in LOG_FIELDS:
            if msg.startswith(prefix):
                last[prefix] = msg
    out = {}
    for prefix, key, rx in LOG_FIELDS:
        if prefix in last:
            m = re.search(rx, last[prefix])
            if m:
                out[key] = m.group(1)
    return out


def pick_reference(refs, scene, w, h):
    """The reference for a w x h render of scene, or (None, why). compare
    box-downsamples whichever image is larger by an integer factor, so the
    same size is best, then a larger reference, then a smaller one."""
    if w != h:
        return None, 'no square reference for %dx%d' % (w, h)
    sizes = []
    for name in os.listdir(refs) if os.path.isdir(refs) else []:
        m = re.fullmatch(re.escape(scene) + r'-([0-9]+)\.pfm', name)
        if m:
            sizes.append(int(m.group(1)))
    if not sizes:
        return None, 'no reference for %s' % scene
    for r in sorted(sizes):
        if r == w:
            return os.path.join(refs, '%s-%d.pfm' % (scene, r)), ''
    for r in sorted(sizes):
        if r > w and r % w == 0:
            return os.path.join(refs, '%s-%d.pfm' % (scene, r)), 'reference %d downsampled to %d' % (r, w)
    for r in sorted(sizes, reverse=True):
        if r < w and w % r == 0:
            return os.path.join(refs, '%s-%d.pfm' % (scene, r)), 'render downsampled to the %d reference' % r
    return None, 'no reference that divides %d' % w


def compare(exe, image, ref):
    """relMSE, RMSE, luminance ratio from `photonfarm compare --json`, or an
    error string. A non-finite number (printed as null) becomes inf/nan."""
    try:
        p = subprocess.run([exe, 'compare', image, ref, '--json'], capture_output=True, text=True,
                           timeout=300, cwd=ROOT)
    except (OSError, subprocess.SubprocessError) as e:
        return None, 'compare: %s' % e
    if p.returncode != 0:
        return None, 'compare exit %d: %s' % (p.returncode, (p.stderr or p.stdout).strip()[-300:])
    try:
        j = json.loads(p.stdout)
        out = {}
        for key, bad in (('relmse', 'inf'), ('rmse', 'inf'), ('lum_ratio', 'nan')):
            v = j.get(key)
            out[key] = bad if v is None else '%.6g' % float(v)
        return out, ''
    except (ValueError, TypeError, AttributeError) as e:
        return None, 'compare: unreadable JSON (%s)' % e


class Runner:
    """Runs points: builds the command line, runs it, parses the log,
    compares against the reference, and returns one CSV row. Identical
    command lines within one invocation are rendered once (the base point
    appears in every family) unless --no-reuse."""

    def __init__(self, args, git, machine):
        self.args = args
        self.git = git
        self.machine = machine
        self.cache = {}
        self.failures = 0
        os.makedirs(args.work, exist_ok=True)

    @staticmethod
    def options(pt):
        """The render options of a point (everything but scene and outputs)."""
        opts = ['--size', '%dx%d' % (pt['size'], pt['size'])]
        for key, opt in (('spp', '--spp'), ('gather', '--gather'), ('filter', '--gather-filter'),
                         ('light', '--light-samples'), ('photons', '--photons'),
                         ('caustic', '--caustic-photons'), ('threads', '--threads'), ('workers', '--workers'),
                         ('time_limit', '--time-limit'), ('quality', '--quality')):
            if pt.get(key) not in (None, ''):
                opts += [opt, str(pt[key])]
        return opts + ['--seed', '1']

    def run(self, scene_name, scene_path, pt, label, reference=True):
        """Renders one point; returns a row dict (strings and numbers)."""
        a = self.args
        tag = re.sub(r'[^A-Za-z0-9_.=-]+', '_', '%s-%s' % (scene_name, label))
        image = os.path.join(a.work, tag + '.png')
        pfm = os.path.join(a.work, tag + '.pfm')
        logp = os.path.join(a.work, tag + '.log')
        opts = self.options(pt)
        cmd = [a.photonfarm, 'render', scene_path, '-o', image, '--hdr', pfm] + opts
        key = (scene_path,) + tuple(opts)
        row = {'git': self.git, 'machine': self.machine,
               'date': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ')}
        for k in ('spp', 'gather', 'filter', 'light', 'photons', 'caustic', 'threads', 'time_limit', 'quality'):
            row[k] = pt.get(k, '')
        row['workers'] = pt.get('workers', 0) or 0
        row['size'] = '%dx%d' % (pt['size'], pt['size'])
        if a.dry_run:
            print(' '.join(shlex.quote(c) for c in cmd))
            row['status'] = 'dry-run'
            return row
        if key in self.cache and not a.no_reuse:
            prev, prev_label = self.cache[key]
            row.update({k: v for k, v in prev.items() if k not in ('family', 'value', 'study', 'note')})
            row['note'] = 'the render of %s (same command)' % prev_label
            log('  %-34s same command as %s' % (label, prev_label))
            return row

        # The machine's one-minute load just before the render: on a shared
        # machine it says how far to trust the time.
        row['load_avg'] = '%.2f' % os.getloadavg()[0] if hasattr(os, 'getloadavg') else ''
        r = run_process(cmd, logp, a.timeout)
        try:
            with open(logp, 'rb') as fp:
                text = fp.read().decode('utf-8', 'replace')
        except OSError:
            text = ''
        lg = parse_log(text)
        row.update({'status': r['status'], 'wall_s': r['wall_s'], 'peak_rss_mb': r['rss_mb'], 'cpu_s': r['cpu_s']})
        notes = [r['note']] if r['note'] else []
        for k in ('load_s', 'triangles', 'global_stored', 'caustic_stored', 'trace_s', 'kdtree_s', 'irradiance_s',
                  'photon_s', 'render_s'):
            row[k] = lg.get(k, '')
        # The settings the renderer reports are the ones it used (a quality
        # preset or a time limit chooses them itself).
        for k in ('spp', 'gather', 'filter', 'light', 'photons', 'caustic'):
            if k in lg:
                row[k] = lg[k]
        if 'width' in lg and 'height' in lg:
            row['size'] = '%sx%s' % (lg['width'], lg['height'])
        # Accel build, light table and image writing: what the total leaves
        # when load, photon pass and render are taken out.
        try:
            row['accel_other_s'] = max(0.0, float(lg['done_s']) - float(lg['load_s']) - float(lg['photon_s'])
                                       - float(lg['render_s']))
        except (KeyError, ValueError):
            row['accel_other_s'] = ''
        # The caustic family's sweep stops at the first render that shows
        # the scene has no caustic map (run_sweep).
        row['no_caustic'] = 'caustic map skipped' in text
        if r['status'] != 'ok':
            self.failures += 1
            if r['status'] == 'failed':
                notes.append('exit %s: %s' % (r['code'], log_tail(logp)))
        elif reference:
            ref, why = pick_reference(a.refs, scene_name, pt['size'], pt['size'])
            if why:
                notes.append(why)
            if ref:
                row['reference'] = os.path.relpath(ref, ROOT)
                m, err = compare(a.photonfarm, pfm, ref)
                if m:
                    row.update(m)
                else:
                    notes.append(err)
                    self.failures += 1
                    row['status'] = 'compare-failed'
        row['note'] = '; '.join(notes)
        if r['status'] == 'ok':
            self.cache[key] = (dict(row), label)
        for f in (image, pfm):
            if not a.keep_images:
                try:
                    os.unlink(f)
                except OSError:
                    pass
        log('  %-34s %s' % (label, summary_line(row)))
        return row


def workers_label(value):
    """'t2' -> '2 threads', 'w2t1' -> '2 workers x 1 thread'."""
    m = re.fullmatch(r'(?:w([0-9]+))?t([0-9]+)', value or '')
    if not m:
        return value or ''
    t = '%s thread%s' % (m.group(2), '' if m.group(2) == '1' else 's')
    if m.group(1) is None:
        return t + ' in-process'
    return '%s worker%s × %s' % (m.group(1), '' if m.group(1) == '1' else 's', t)


def summary_line(row):
    if row.get('status') != 'ok':
        return '%s: %s' % (row.get('status', '?').upper(), row.get('note', ''))
    parts = ['%.2f s' % float(row['wall_s'])]
    if row.get('relmse') not in (None, ''):
        parts.append('relMSE %.5g' % float(row['relmse']))
    parts.append('%.0f MB' % float(row['peak_rss_mb']))
    if row.get('note'):
        parts.append('(%s)' % row['note'])
    return ', '.join(parts)


# --------------------------------------------------------------- the sweep

def family_points(family, mode, base, ncpu, limit):
    """[(value label, point dict)] for a family. A point dict holds the
    settings to pass; the quality and time-limit families pass only the
    size and threads, leaving the rest to the renderer."""
    param, full, quick = FAMILIES[family]
    pts = []
    if family == 'workers':
        # In-process threads against local worker processes of one thread.
        counts = sorted({1, 2, ncpu})
        for t in counts:
            pts.append(('t%d' % t, dict(base, threads=t)))
        for w in counts:
            pts.append(('w%dt1' % w, dict(base, workers=w, threads=1)))
    else:
        for v in (full if mode == 'full' else quick):
            if family in ('quality', 'time-limit'):
                pts.append((str(v), {'size': base['size'], 'threads': base['threads'], param: v}))
            else:
                pts.append((str(v), dict(base, **{param: v})))
    return pts[:limit] if limit else pts


def run_sweep(args, runner, mode, help_text):
    base = dict(BASE[mode])
    if args.size:
        base['size'] = args.size
    base.update(args.base)
    base['threads'] = args.threads
    ncpu = os.cpu_count() or 1
    families = []
    for f in args.families:
        need = FAMILY_NEEDS.get(f)
        if need and need not in help_text:
            log('bench: skipping family %s: `photonfarm render --help` does not mention %s '
                '(this build does not have it yet)' % (f, need))
            continue
        families.append(f)
    rows = []
    for scene in args.scenes:
        scene_path = os.path.join(ROOT, 'scenes', scene, 'scene.json')
        if not os.path.exists(scene_path):
            log('bench: no scene %s (%s); skipped' % (scene, os.path.relpath(scene_path, ROOT)))
            continue
        for fam in families:
            pts = family_points(fam, mode, base, ncpu, args.points)
            log('%s, family %s (%d points)' % (scene, fam, len(pts)))
            no_caustic = False
            for value, pt in pts:
                row = {'scene': scene, 'family': fam, 'value': value}
                if no_caustic:
                    row.update({'status': 'skipped', 'note': 'the scene has no caustic map',
                                'size': '%dx%d' % (pt['size'], pt['size']),
                                'git': runner.git, 'machine': runner.machine})
                    log('  %-34s skipped: the scene has no mirror or glass' % ('%s=%s' % (fam, value)))
                    rows.append(row)
                    continue
                row.update(runner.run(scene, scene_path, pt, '%s=%s' % (fam, value)))
                row['scene'], row['family'], row['value'] = scene, fam, value
                rows.append(row)
                # The caustic family cannot change a scene without caustics:
                # one point shows it, the rest would only cost time.
                if fam == 'caustic' and row.get('no_caustic'):
                    no_caustic = True
                    row['note'] = '; '.join(x for x in (row.get('note'), 'the scene has no caustic map') if x)
    return rows


# ------------------------------------------------------------ the scaling

def scaling_points(study, mode, args, ncpu):
    """[(value label, scene name, scene path, point dict, compare?)]."""
    quick = mode == 'quick'
    pts = []
    if study == 'photons':
        # Cornell box: no mirror or glass, so every photon goes to the global
        # map and the growth is that of one map, its kd-tree and irradiance.
        sp = os.path.join(ROOT, 'scenes', 'cornell-box', 'scene.json')
        counts = [10000, 100000, 1000000] if quick else [10000, 30000, 100000, 300000, 1000000, 3000000, 10000000]
        for n in counts:
            pts.append((str(n), 'cornell-box', sp, {'size': 16, 'spp': 1, 'gather': 1, 'photons': n, 'caustic': 0,
                                                    'threads': args.threads}, False))
    elif study == 'triangles':
        bunny = os.path.join(ROOT, 'scenes', 'bunny')
        with open(os.path.join(bunny, 'scene.json')) as fp:
            scene = json.load(fp)
        size = 64
        base = {'size': size, 'spp': 4, 'gather': 1, 'photons': 100000, 'caustic': 100000, 'threads': args.threads}
        for res in ('_res4', '_res3', '_res2', ''):
            for o in scene['objects']:
                if o.get('type') == 'ply':
                    o['file'] = os.path.join(bunny, 'bun_zipper%s.ply' % res)
            path = os.path.join(args.work, 'bunny%s.json' % res)
            with open(path, 'w') as fp:
                json.dump(scene, fp, indent=1)
            pts.append(('bunny' + res, 'bunny', path, dict(base), False))
        mesh_dir = os.path.join(args.work, 'mesh')
        p = subprocess.run([sys.executable, os.path.join(HERE, 'make_mesh.py'), '--out', mesh_dir],
                           capture_output=True, text=True)
        if p.returncode == 0 and p.stdout.strip():
            pts.append(('mesh-1M', 'displaced-sphere', p.stdout.strip().splitlines()[-1], dict(base), False))
        else:
            log('bench: make_mesh.py failed (%s); the million-triangle point is skipped' % p.stderr.strip()[-300:])
    elif study == 'resolution':
        sp = os.path.join(ROOT, 'scenes', 'cornell-spheres', 'scene.json')
        sizes = [64, 128, 256] if quick else [128, 256, 512, 1024]
        base = ({'spp': 4, 'gather': 1, 'photons': 100000, 'caustic': 100000} if quick else
                {'spp': 16, 'gather': 1, 'photons': 400000, 'caustic': 400000})
        for s in sizes:
            pts.append((str(s), 'cornell-spheres', sp, dict(base, size=s, threads=args.threads), True))
    elif study == 'threads':
        sp = os.path.join(ROOT, 'scenes', 'cornell-spheres', 'scene.json')
        base = ({'size': 128, 'spp': 4, 'gather': 1, 'photons': 100000, 'caustic': 100000} if quick else
                {'size': 256, 'spp': 36, 'gather': 1, 'photons': 400000, 'caustic': 400000})
        t = 1
        counts = []
        while t < ncpu:
            counts.append(t)
            t *= 2
        counts.append(ncpu)
        for t in counts:
            pts.append((str(t), 'cornell-spheres', sp, dict(base, threads=t), True))
    if args.size and study != 'resolution':
        for _, _, _, pt, _ in pts:
            pt['size'] = args.size
    return pts[:args.points] if args.points else pts


def run_scaling(args, runner, mode):
    ncpu = os.cpu_count() or 1
    rows = []
    for study in args.studies:
        pts = scaling_points(study, mode, args, ncpu)
        log('scaling, %s (%d points)' % (study, len(pts)))
        for value, scene, path, pt, ref in pts:
            row = runner.run(scene, path, pt, '%s=%s' % (study, value), reference=ref)
            row.update({'study': study, 'value': value, 'scene': scene})
            rows.append(row)
    set_bytes_per_photon(rows)
    return rows


def _stored(r):
    return float(r.get('global_stored') or 0) + float(r.get('caustic_stored') or 0)


def set_bytes_per_photon(rows):
    """Bytes per photon for the photons study: the growth of peak RSS over
    the smallest run, divided by the growth in stored photons. Rough: it
    includes the allocator's slack, arrays grown by doubling, the kd-tree's
    and the irradiance records. Left empty while the growth is under 16 MB,
    where the program's own size and page granularity swamp it."""
    ok = [r for r in rows if r.get('study') == 'photons' and r.get('status') == 'ok'
          and num(r.get('global_stored')) is not None and num(r.get('peak_rss_mb')) is not None]
    ok.sort(key=_stored)
    for r in ok:
        r['bytes_per_photon'] = ''
    if len(ok) < 2:
        return
    r0 = ok[0]
    for r in ok[1:]:
        dn = _stored(r) - _stored(r0)
        dm = num(r['peak_rss_mb']) - num(r0['peak_rss_mb'])
        if dn > 0 and dm >= 16:
            r['bytes_per_photon'] = dm * 1048576.0 / dn


# ------------------------------------------------------------- CSV files

def fmt_cell(v):
    if isinstance(v, float):
        return '%.6g' % v if math.isfinite(v) else repr(v)
    return '' if v is None else str(v)


def merge_csv(path, cols, new_rows, key):
    """Writes path: the rows already there whose key is not among the new
    rows' keys, then the new rows. Returns all rows."""
    old = read_csv(path)
    replaced = {key(r) for r in new_rows}
    rows = [r for r in old if key(r) not in replaced] + new_rows
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + '.tmp'
    with open(tmp, 'w', newline='') as fp:
        w = csv.DictWriter(fp, fieldnames=cols, extrasaction='ignore', restval='')
        w.writeheader()
        for r in rows:
            w.writerow({k: fmt_cell(r.get(k)) for k in cols})
    os.replace(tmp, path)
    return read_csv(path)


def read_csv(path):
    if not os.path.exists(path):
        return []
    with open(path, newline='') as fp:
        return list(csv.DictReader(fp))


def num(v):
    """float(v), or None for empty or unparsable cells."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f


def fmt_num(v, digits=3):
    f = num(v)
    if f is None:
        return ''
    if not math.isfinite(f):
        return 'inf' if f > 0 else str(f)
    if f == 0:
        return '0'
    if abs(f) >= 10 ** digits:
        return '%.0f' % f
    return '%.*g' % (digits, f)


def fmt_time(v):
    """Seconds with two decimals below 10 s, one below 100 s, none above."""
    f = num(v)
    if f is None or not math.isfinite(f):
        return fmt_num(v)
    return '%.2f' % f if f < 10 else '%.1f' % f if f < 100 else '%.0f' % f


def fmt_mb(v):
    f = num(v)
    if f is None or not math.isfinite(f):
        return fmt_num(v)
    return '%.1f' % f if f < 100 else '%.0f' % f


def fmt_count(v):
    """A setting's count, short: 400000 -> 400k, 2000000 -> 2M, 25000 -> 25k."""
    f = num(v)
    if f is None:
        return str(v or '')
    for div, suf in ((1e6, 'M'), (1e3, 'k')):
        if abs(f) >= div:
            return ('%.3g' % (f / div)) + suf
    return '%d' % f


def fmt_int(v):
    """A measured count in full: 1002264 -> 1,002,264."""
    f = num(v)
    return '{:,}'.format(int(f)) if f is not None and math.isfinite(f) else str(v or '')


# ------------------------------------------------------------------- plots

def gp_str(s):
    return '"' + str(s).replace('\\', '\\\\').replace('"', '\\"') + '"'


def gp_block(name, rows):
    """A gnuplot data block; rows are tuples of numbers and strings."""
    out = ['$%s << EOD' % name]
    for r in rows:
        out.append(' '.join(gp_str(c) if isinstance(c, str) else repr(float(c)) for c in r))
    out.append('EOD')
    return '\n'.join(out)


def run_gnuplot(script, png, keep_script_dir):
    """Writes the script beside the logs and runs gnuplot on it. Returns True
    when the PNG was written."""
    gp = os.path.join(keep_script_dir, os.path.basename(png)[:-4] + '.gp')
    with open(gp, 'w') as fp:
        fp.write(script)
    exe = shutil.which('gnuplot')
    if not exe:
        log('bench: gnuplot not found (install gnuplot-nox, e.g. deploy/install-deps.sh --bench); '
            'no plot %s (script left in %s)' % (os.path.relpath(png, ROOT), gp))
        return False
    p = subprocess.run([exe, gp], capture_output=True, text=True, timeout=120)
    if p.returncode != 0 or not os.path.exists(png):
        log('bench: gnuplot failed on %s: %s' % (gp, p.stderr.strip()[-500:]))
        return False
    return True


# One colour per curve, fixed (gnuplot's default yellow is hard to see).
COLOURS = ['#1f77b4', '#ff7f0e', '#2ca02c', '#9467bd', '#8c564b', '#e377c2', '#17becf', '#7f7f7f']


def colour(i):
    return 'lc rgb "%s"' % COLOURS[i % len(COLOURS)]


PLOT_HEAD = '''set terminal pngcairo size 960,680 enhanced font "Sans,10"
set output %s
set encoding utf8
set grid xtics ytics mxtics mytics lc rgb "#dddddd"
set key outside right top
'''


def plot_sweep(scene, rows, png, mode, script_dir):
    """relMSE against wall time, log-log, one curve per family (in sweep
    order), each point labelled with its value; the peer's figures and the
    goal as labelled points."""
    blocks, plots = [], []
    for i, fam in enumerate(FAMILIES):
        pts = []
        for r in rows:
            if r['family'] != fam or r.get('status') != 'ok':
                continue
            x, y = num(r.get('wall_s')), num(r.get('relmse'))
            if x and y and x > 0 and y > 0 and math.isfinite(y):
                lab = fmt_count(r['value']) if fam in ('photons', 'caustic') else r['value']
                pts.append((x, y, lab))
        if not pts:
            continue
        name = 'f%d' % i
        blocks.append(gp_block(name, pts))
        # A family keeps its colour in every plot (its place in FAMILIES).
        if fam == 'workers':
            # The images are bit-identical, so the points share one relMSE:
            # a point type per configuration instead of overlapping labels.
            for j, (x, y, lab) in enumerate(pts):
                plots.append('$%s every ::%d::%d using 1:2 with points pt %d ps 1.4 lw 1.5 %s title %s'
                             % (name, j, j, (4, 6, 8, 10, 12, 14)[j % 6], colour(i),
                                gp_str('workers: ' + workers_label(lab))))
        else:
            plots.append('$%s using 1:2 with linespoints pt 7 ps 0.9 lw 1.5 %s title %s'
                         % (name, colour(i), gp_str(fam)))
            plots.append('$%s using 1:2:3 with labels offset char 0.6,0.6 font ",7" tc rgb "%s" notitle'
                         % (name, COLOURS[i % len(COLOURS)]))
    if not plots:
        return False
    if scene == PEER_SCENE:
        blocks.append(gp_block('sppm', [(t, e, '%g s' % t) for t, e in PEER_SPPM]))
        blocks.append(gp_block('path', [(t, e, '%g s' % t) for t, e in PEER_PATH]))
        plots.append('$sppm using 1:2 with linespoints dt 2 pt 5 ps 1.1 lc rgb "black" '
                     'title "pbrt-v3 SPPM (peer)"')
        plots.append('$path using 1:2 with linespoints dt 3 pt 4 ps 1.1 lc rgb "gray40" '
                     'title "pbrt-v3 path tracer"')
    blocks.append(gp_block('goal', [(t, e, 'goal %g s' % t) for t, e in GOAL]))
    plots.append('$goal using 1:2 with points pt 3 ps 2.2 lw 2 lc rgb "red" title "goal (--time-limit)"')
    plots.append('$goal using 1:2:3 with labels offset char 0,-1.2 font ",8" tc rgb "red" notitle')
    sizes = sorted({r.get('size', '') for r in rows if r.get('status') == 'ok'})
    title = '%s: relMSE against wall time (%s%s)' % (scene, ', '.join(sizes),
                                                       ', quick run: not comparable with the 512x512 peer'
                                                       if mode == 'quick' else '')
    script = (PLOT_HEAD % gp_str(png) + 'set logscale xy\nset format y "10^{%L}"\n'
              'set xlabel "wall time (s)"\nset ylabel "relMSE against the reference"\n'
              'set title ' + gp_str(title) + '\n' + '\n'.join(blocks) + '\nplot ' + ', \\\n     '.join(plots) + '\n')
    return run_gnuplot(script, png, script_dir)


def plot_scaling(study, rows, png, script_dir):
    rows = [r for r in rows if r.get('study') == study and r.get('status') == 'ok']
    if not rows:
        return False
    blocks, plots = [], []
    if study == 'photons':
        xs = [(num(r['photons']), r) for r in rows if num(r.get('photons'))]
        series = [('trace_s', 'photon tracing'), ('kdtree_s', 'kd-tree build'), ('irradiance_s', 'irradiance'),
                  ('photon_s', 'photon pass (sum)'), ('wall_s', 'wall (whole run)')]
        xlabel, logx = 'photons emitted (global map; cornell-box, 16x16, spp 1, gather 1)', True
    elif study == 'triangles':
        xs = [(num(r['triangles']), r) for r in rows if num(r.get('triangles'))]
        series = [('load_s', 'scene load'), ('accel_other_s', 'accel build + other'),
                  ('photon_s', 'photon pass'), ('render_s', 'render'), ('wall_s', 'wall')]
        xlabel, logx = 'triangles (bunny res4 .. res1, generated 1M mesh; 64x64)', True
    elif study == 'resolution':
        xs = [(num(r['size'].split('x')[0]) ** 2, r) for r in rows if num(r.get('size', '').split('x')[0])]
        series = [('photon_s', 'photon pass'), ('render_s', 'render'), ('wall_s', 'wall')]
        xlabel, logx = 'pixels (cornell-spheres)', True
    else:
        xs = [(num(r['threads']), r) for r in rows if num(r.get('threads'))]
        series = [('photon_s', 'photon pass'), ('render_s', 'render'), ('wall_s', 'wall')]
        xlabel, logx = 'threads (cornell-spheres)', False
    xs.sort(key=lambda p: p[0])
    for i, (key, title) in enumerate(series):
        pts = [(x, num(r.get(key))) for x, r in xs if num(r.get(key)) and num(r.get(key)) > 0]
        if pts:
            blocks.append(gp_block('s%d' % i, pts))
            plots.append('$s%d using 1:2 with linespoints pt 7 lw 1.5 %s title %s' % (i, colour(i), gp_str(title)))
    if study == 'threads':
        base = [(x, num(r.get('render_s'))) for x, r in xs if num(r.get('render_s'))]
        if base:
            t1 = base[0][1] * base[0][0]
            blocks.append(gp_block('ideal', [(x, t1 / x) for x, _ in base]))
            plots.append('$ideal using 1:2 with lines dt 2 lc rgb "gray50" title "render, ideal 1/threads"')
    mem = [(x, num(r.get('peak_rss_mb'))) for x, r in xs if num(r.get('peak_rss_mb'))]
    if mem:
        blocks.append(gp_block('mem', mem))
        plots.append('$mem using 1:2 axes x1y2 with linespoints dt 4 pt 6 lw 2 lc rgb "black" '
                     'title "peak RSS (MB, right axis)"')
    if not plots:
        return False
    script = (PLOT_HEAD % gp_str(png) + ('set logscale x\n' if logx else 'set xtics 1\n') +
              'set logscale y\nset logscale y2\nset ytics nomirror\nset y2tics\n'
              'set xlabel ' + gp_str(xlabel) + '\nset ylabel "seconds"\nset y2label "peak RSS (MB)"\n'
              'set title ' + gp_str('time and memory against %s' % study) + '\n' +
              '\n'.join(blocks) + '\nplot ' + ', \\\n     '.join(plots) + '\n')
    return run_gnuplot(script, png, script_dir)


# ------------------------------------------------------------ markdown

def md_table(header, rows):
    out = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    for r in rows:
        out.append('| ' + ' | '.join(str(c) for c in r) + ' |')
    return '\n'.join(out)


def md_status(r):
    """The error columns of a row, or its status when it has none."""
    if r.get('status') != 'ok':
        return [r.get('status', ''), '', '']
    return [fmt_num(r.get('relmse'), 3), fmt_num(r.get('rmse'), 3), fmt_num(r.get('lum_ratio'), 4)]


def header_lines(rows, mode, command):
    dates = sorted(r['date'] for r in rows if r.get('date'))
    gits = sorted({r['git'] for r in rows if r.get('git')})
    machines = sorted({r['machine'] for r in rows if r.get('machine')})
    loads = sorted(num(r.get('load_avg')) for r in rows if num(r.get('load_avg')) is not None)
    m = re.match(r'([0-9]+) cores', machines[0] if machines else '')
    cores = int(m.group(1)) if m else (os.cpu_count() or 1)
    out = ['- machine: %s' % ('; '.join(machines) or 'unknown'),
           '- measured: %s%s, photonfarm built from %s' % (dates[0][:16].replace('T', ' ') if dates else '?',
                                                           (' to ' + dates[-1][:16].replace('T', ' ')) if dates
                                                           and dates[-1][:16] != dates[0][:16] else '',
                                                           ', '.join(gits) or '?'),
           '- load average (1 min) before the renders: %s' % (
               ('%.2f to %.2f' % (loads[0], loads[-1]) if loads else 'not recorded') +
               ('; **the machine was busy: times are pessimistic**' if loads and
                loads[len(loads) // 2] > 0.5 * cores else '')),
           '- command: `%s`%s' % (command, ' (**quick run**: small images, few points; for development, not '
                                  'the published figures)' if mode == 'quick' else '')]
    return out


def infer_base(rows, mode):
    """The base settings as the rows show them: for each setting, its most
    common value in the families that do not vary it (so --size and --base
    overrides, and a report rebuilt from the CSV, say what was run)."""
    base = {}
    for key, fams in (('size', ()), ('spp', ('spp',)), ('gather', ('gather',)), ('filter', ('filter',)),
                      ('light', ('light',)), ('photons', ('photons',)), ('caustic', ('caustic',))):
        vals = [r.get(key) for r in rows if r.get('status') == 'ok' and r.get('family') not in fams
                and r.get('family') not in ('quality', 'time-limit') and r.get(key)]
        if vals:
            v = max(sorted(set(vals)), key=vals.count)
            base[key] = int(v.split('x')[0]) if key == 'size' else v
        elif key in BASE[mode]:
            base[key] = BASE[mode][key]
    return base


def sweep_markdown(rows, mode, image_rel, command):
    """The sweep's report: header, base settings, per scene a plot, the
    comparison with the peer at the time budgets and the full table."""
    base = infer_base(rows, mode)
    out = header_lines(rows, mode, command)
    out.append('- base of every family: %s; each family changes one setting; `--seed 1`; `--threads %s`' % (
        ', '.join('%dx%d' % (v, v) if k == 'size' else
                  '%s %s' % (k, fmt_count(v) if k in ('photons', 'caustic') else v) for k, v in base.items()),
        ', '.join(sorted({r.get('threads', '') for r in rows if r.get('family') != 'workers'} - {''})) or '?'))
    out.append('- wall time: the whole process (scene load, photon pass, render, writing the images), by the '
               'harness; peak RSS: the largest single process (with `--workers`, the coordinator or one worker, '
               'not their sum)')
    out.append('')
    scenes = [s for s in SCENES if any(r['scene'] == s for r in rows)]
    scenes += sorted({r['scene'] for r in rows} - set(scenes))
    for scene in scenes:
        srows = [r for r in rows if r['scene'] == scene]
        out.append('### %s' % scene)
        out.append('')
        if image_rel.get(scene):
            out.append('![relMSE against wall time, %s](%s)' % (scene, image_rel[scene]))
            out.append('')
        ok = [r for r in srows if r.get('status') == 'ok' and num(r.get('relmse')) is not None
              and num(r.get('wall_s')) is not None]
        peer = dict(PEER_SPPM) if scene == PEER_SCENE else {}
        path = dict(PEER_PATH) if scene == PEER_SCENE else {}
        goal = dict(GOAL)
        brows = []
        for b in BUDGETS:
            within = [r for r in ok if num(r['wall_s']) <= b]
            best = min(within, key=lambda r: num(r['relmse'])) if within else None
            brows.append(['%d s' % b, fmt_num(peer.get(b), 3) or '-', fmt_num(path.get(b), 3) or '-',
                          ('≤ ' + fmt_num(goal[b], 3)) if b in goal else '-',
                          fmt_num(best['relmse'], 3) if best else 'none this fast',
                          '%s=%s, %.1f s' % (best['family'], best['value'], num(best['wall_s'])) if best else ''])
        out.append('Best relMSE within each time budget, against pbrt-v3 (512×512, 2 threads%s):' % (
            '' if scene == PEER_SCENE else '; the peer was measured on cornell-spheres only'))
        out.append('')
        out.append(md_table(['budget', 'pbrt-v3 SPPM', 'pbrt-v3 path', 'goal', 'photonfarm', 'by'], brows))
        out.append('')
        trows = []
        order = list(FAMILIES)
        srows.sort(key=lambda r: order.index(r['family']) if r['family'] in order else len(order))
        for r in srows:
            if not r.get('threads'):
                wt = ''
            elif str(r.get('workers') or 0) != '0':
                wt = workers_label('w%st%s' % (r['workers'], r['threads']))
            else:
                wt = workers_label('t%s' % r['threads'])
            value = fmt_count(r['value']) if r['family'] in ('photons', 'caustic') else r['value']
            trows.append([r['family'], value, r.get('size', ''), r.get('spp', ''), r.get('gather', ''),
                          r.get('filter', ''), r.get('light', ''), fmt_count(r.get('photons')), fmt_count(r.get('caustic')), wt,
                          fmt_time(r.get('wall_s')), fmt_time(r.get('photon_s')), fmt_time(r.get('render_s')),
                          fmt_mb(r.get('peak_rss_mb'))] + md_status(r))
        out.append(md_table(['family', 'value', 'size', 'spp', 'gather', 'filter', 'light', 'photons', 'caustic',
                             'workers×threads',
                             'wall s', 'photons s', 'render s', 'peak RSS MB', 'relMSE', 'RMSE', 'lum. ratio'],
                            trows))
        notes = ['- %s=%s: %s' % (r['family'], r['value'], r['note']) for r in srows if r.get('note')]
        if notes:
            out.append('')
            out.append('Notes:')
            out.append('')
            out.extend(notes)
        out.append('')
    return '\n'.join(out).rstrip() + '\n'


def scaling_markdown(rows, mode, image_rel, command):
    out = header_lines(rows, mode, command)
    out.append('')
    titles = {'photons': 'Photon count', 'triangles': 'Triangle count', 'resolution': 'Resolution',
              'threads': 'Threads'}
    for study in STUDIES:
        srows = [r for r in rows if r.get('study') == study]
        out.append('### %s' % titles[study])
        out.append('')
        if not srows:
            out.append('Not measured yet: `python3 bench/bench.py --scaling --studies %s --docs`.' % study)
            out.append('')
            continue
        if image_rel.get(study):
            out.append('![time and memory against %s](%s)' % (study, image_rel[study]))
            out.append('')
        if study == 'photons':
            out.append('cornell-box (no mirror or glass, so one global map), 16×16, spp 1, gather 1: the run is '
                       'the photon pass. Bytes per photon = growth of peak RSS over the smallest run / growth of '
                       'stored photons; rough (allocator slack, arrays grown by doubling, kd-tree and irradiance '
                       'records all count).')
            out.append('')
            out.append(md_table(['photons emitted', 'stored', 'trace s', 'kd-trees s', 'irradiance s',
                                 'photon pass s', 'wall s', 'peak RSS MB', 'bytes/photon (rough)'],
                                [[fmt_count(r.get('photons')), fmt_int(r.get('global_stored')),
                                  fmt_time(r.get('trace_s')), fmt_time(r.get('kdtree_s')),
                                  fmt_time(r.get('irradiance_s')), fmt_time(r.get('photon_s')),
                                  fmt_time(r.get('wall_s')), fmt_mb(r.get('peak_rss_mb')),
                                  fmt_num(r.get('bytes_per_photon'))] if r.get('status') == 'ok' else
                                 [fmt_count(r.get('photons')), r.get('status', '')] + [''] * 7 for r in srows]))
        elif study == 'triangles':
            out.append('The bunny scene (glass bunny, mirror sphere) with each of the four bunny meshes, and the '
                       'same box around a generated displaced sphere (`bench/make_mesh.py`, diffuse, so no caustic '
                       'photons); 64×64, spp 1, gather 4, 100k + 100k photons. "accel + other" is the run\'s '
                       'total less load, photon pass and render: mostly the Embree build.')
            out.append('')
            out.append(md_table(['model', 'triangles', 'load s', 'accel + other s', 'photon pass s', 'render s',
                                 'wall s', 'peak RSS MB'],
                                [[r['value'], fmt_int(r.get('triangles')), fmt_time(r.get('load_s')),
                                  fmt_time(r.get('accel_other_s')), fmt_time(r.get('photon_s')),
                                  fmt_time(r.get('render_s')), fmt_time(r.get('wall_s')),
                                  fmt_mb(r.get('peak_rss_mb'))] if r.get('status') == 'ok' else
                                 [r['value'], r.get('status', '')] + [''] * 6 for r in srows]))
        elif study == 'resolution':
            s0 = srows[0]
            out.append('cornell-spheres, spp %s, gather %s, %s + %s photons; the error is against the nearest '
                       'reference (a larger one box-downsampled, or the render downsampled to 512).' % (
                           s0.get('spp'), s0.get('gather'), fmt_count(s0.get('photons')),
                           fmt_count(s0.get('caustic'))))
            out.append('')
            trows = []
            for r in srows:
                if r.get('status') != 'ok':
                    trows.append([r.get('size', ''), r.get('status', '')] + [''] * 6)
                    continue
                px = (num(r['size'].split('x')[0]) or 0) ** 2
                per = num(r.get('render_s'))
                trows.append([r.get('size', ''), fmt_time(r.get('photon_s')), fmt_time(r.get('render_s')),
                              fmt_num(per / px * 1e6) if per and px else '', fmt_time(r.get('wall_s')),
                              fmt_mb(r.get('peak_rss_mb')), fmt_num(r.get('relmse'))])
            out.append(md_table(['size', 'photon pass s', 'render s', 'render s per Mpixel', 'wall s',
                                 'peak RSS MB', 'relMSE'], trows))
        else:
            s0 = srows[0]
            out.append('cornell-spheres, %s, spp %s, gather %s, %s + %s photons, in-process threads (the photon '
                       'pass and the render both use them).' % (s0.get('size'), s0.get('spp'), s0.get('gather'),
                                                                fmt_count(s0.get('photons')),
                                                                fmt_count(s0.get('caustic'))))
            out.append('')
            t1 = next((r for r in srows if r.get('status') == 'ok'), None)
            trows = []
            for r in srows:
                if r.get('status') != 'ok':
                    trows.append([r.get('threads', ''), r.get('status', '')] + [''] * 5)
                    continue
                sp_r = num(t1.get('render_s')) / num(r['render_s']) if num(r.get('render_s')) and \
                    num(t1.get('render_s')) else None
                sp_p = num(t1.get('photon_s')) / num(r['photon_s']) if num(r.get('photon_s')) and \
                    num(t1.get('photon_s')) else None
                trows.append([r.get('threads', ''), fmt_time(r.get('photon_s')), fmt_time(r.get('render_s')),
                              fmt_time(r.get('wall_s')), fmt_num(sp_p), fmt_num(sp_r), fmt_mb(r.get('peak_rss_mb'))])
            out.append(md_table(['threads', 'photon pass s', 'render s', 'wall s', 'photon pass speed-up',
                                 'render speed-up', 'peak RSS MB'], trows))
        notes = ['- %s: %s' % (r['value'], r['note']) for r in srows if r.get('note')]
        if notes:
            out += ['', 'Notes:', ''] + notes
        out.append('')
    return '\n'.join(out).rstrip() + '\n'


def replace_section(doc_path, name, body):
    """Puts body between the GENERATED markers of section name in doc_path;
    appends the section (with markers) when they are missing."""
    begin, end = MARK_BEGIN % name, MARK_END % name
    try:
        with open(doc_path) as fp:
            text = fp.read()
    except FileNotFoundError:
        text = '# Benchmarks\n\n'
    i = text.find(begin)
    j = text.find(end, i + 1) if i >= 0 else -1
    block = begin + '\n\n' + body.rstrip() + '\n\n' + end
    if i >= 0 and j >= 0:
        text = text[:i] + block + text[j + len(end):]
    else:
        log('bench: %s has no markers for section %s; appended at the end' % (doc_path, name))
        text = text.rstrip() + '\n\n' + block + '\n'
    tmp = doc_path + '.tmp'
    with open(tmp, 'w') as fp:
        fp.write(text)
    os.replace(tmp, doc_path)


# ---------------------------------------------------------------- reports

def sweep_key(r):
    return (r.get('scene'), r.get('family'))


def scaling_key(r):
    return r.get('study')


def report(args, mode, sweep_rows, scaling_rows, command):
    """Markdown and plots from the CSV rows: into --out, or with --docs into
    docs/benchmarks.md and docs/images. Returns the files written."""
    written = []
    if args.docs:
        img_dir = os.path.join(ROOT, 'docs', 'images')
        md_dir = os.path.join(ROOT, 'docs')
    else:
        img_dir = md_dir = args.out
    os.makedirs(img_dir, exist_ok=True)
    suffix = '-quick' if mode == 'quick' and not args.docs else ''
    if sweep_rows is not None:
        rel = {}
        for scene in sorted({r['scene'] for r in sweep_rows}):
            png = os.path.join(img_dir, 'bench-%s%s.png' % (scene, suffix))
            if plot_sweep(scene, [r for r in sweep_rows if r['scene'] == scene], png, mode, args.work):
                rel[scene] = os.path.relpath(png, md_dir)
                written.append(png)
        md = sweep_markdown(sweep_rows, mode, rel, command)
        if args.docs:
            replace_section(os.path.join(md_dir, 'benchmarks.md'), 'sweep', md)
            written.append(os.path.join(md_dir, 'benchmarks.md'))
        else:
            p = os.path.join(md_dir, 'sweep%s.md' % suffix)
            with open(p, 'w') as fp:
                fp.write('# photonfarm: run time against error\n\n' + md)
            written.append(p)
    if scaling_rows is not None:
        set_bytes_per_photon(scaling_rows)
        rel = {}
        for study in STUDIES:
            png = os.path.join(img_dir, 'bench-scaling-%s%s.png' % (study, suffix))
            if plot_scaling(study, scaling_rows, png, args.work):
                rel[study] = os.path.relpath(png, md_dir)
                written.append(png)
        md = scaling_markdown(scaling_rows, mode, rel, command)
        if args.docs:
            replace_section(os.path.join(md_dir, 'benchmarks.md'), 'scaling', md)
            written.append(os.path.join(md_dir, 'benchmarks.md'))
        else:
            p = os.path.join(md_dir, 'scaling%s.md' % suffix)
            with open(p, 'w') as fp:
                fp.write('# photonfarm: scaling\n\n' + md)
            written.append(p)
    return sorted(set(written))


# -------------------------------------------------------------------- main

def parse_size(s):
    m = re.fullmatch(r'([0-9]+)(?:x([0-9]+))?', s)
    if not m or (m.group(2) and m.group(2) != m.group(1)) or not 1 <= int(m.group(1)) <= 16384:
        raise argparse.ArgumentTypeError('expected N or NxN (square, 1..16384), got %r' % s)
    return int(m.group(1))


def parse_base(s):
    out = {}
    for part in s.split(','):
        k, _, v = part.partition('=')
        k = k.strip()
        if k not in ('spp', 'gather', 'filter', 'light', 'photons', 'caustic') or not v.strip().isdigit():
            raise argparse.ArgumentTypeError('expected KEY=N[,KEY=N] with KEY in spp, gather, filter, light, '
                                             'photons, caustic')
        out[k] = int(v)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog='bench.py', description='photonfarm benchmarks: run time against error (the sweep) and scaling.',
        epilog='Full sweep: python3 bench/bench.py --docs (about an hour on 2 cores). '
               'Scaling: python3 bench/bench.py --scaling --docs. Development: add --quick.')
    ap.add_argument('--quick', action='store_true', help='128x128 against the 128 references, few points')
    ap.add_argument('--scaling', action='store_true', help='the scaling studies instead of the sweep')
    ap.add_argument('--scenes', nargs='+', default=SCENES, metavar='SCENE',
                    help='scenes/<SCENE>/scene.json to sweep (default: %s)' % ' '.join(SCENES))
    ap.add_argument('--families', nargs='+', default=list(FAMILIES), choices=list(FAMILIES), metavar='FAMILY',
                    help='sweep families (default: all: %s)' % ' '.join(FAMILIES))
    ap.add_argument('--studies', nargs='+', default=STUDIES, choices=STUDIES, metavar='STUDY',
                    help='scaling studies (default: all: %s)' % ' '.join(STUDIES))
    ap.add_argument('--out', default=os.path.join(ROOT, 'bench', 'results'),
                    help='folder for the CSV files (default bench/results); also the reports without --docs')
    ap.add_argument('--docs', action='store_true',
                    help='write the report into docs/benchmarks.md and the plots into docs/images')
    ap.add_argument('--report-only', action='store_true', help='no renders: rebuild reports from the CSV')
    ap.add_argument('--size', type=parse_size, help='override the image size (N or NxN)')
    ap.add_argument('--points', type=int, default=0, help='at most this many points per family or study')
    ap.add_argument('--base', type=parse_base, default={}, metavar='KEY=N,...',
                    help='override the base settings (spp, gather, photons, caustic)')
    ap.add_argument('--threads', type=int, default=os.cpu_count() or 1,
                    help='--threads for every render outside the workers and threads studies (default: all cores)')
    ap.add_argument('--timeout', type=float, default=None,
                    help='seconds before a render is killed (default 600; --quick 120)')
    ap.add_argument('--photonfarm', default=os.path.join(ROOT, 'build', 'bin', 'photonfarm'),
                    help='the renderer (default build/bin/photonfarm)')
    shared_refs = os.path.join(os.path.dirname(ROOT), 'shared', 'references')
    ap.add_argument('--refs', default=shared_refs if os.path.isdir(shared_refs) else
                    os.path.join(ROOT, 'tests', 'data', 'references'),
                    help='reference images (default ../shared/references, else the 128-pixel copies in '
                    'tests/data/references)')
    ap.add_argument('--work', default=os.path.join(ROOT, 'build', 'bench'),
                    help='logs, plot scripts and the generated mesh (default build/bench)')
    ap.add_argument('--keep-images', action='store_true', help='keep the rendered PNG and PFM files in --work')
    ap.add_argument('--no-reuse', action='store_true', help='render a repeated command again instead of reusing it')
    ap.add_argument('--dry-run', action='store_true', help='print the render commands, run nothing')
    args = ap.parse_args(argv)

    mode = 'quick' if args.quick else 'full'
    if args.timeout is None:
        args.timeout = 120.0 if args.quick else 600.0
    for attr in ('out', 'work', 'refs', 'photonfarm'):
        setattr(args, attr, os.path.abspath(getattr(args, attr)))
    if args.points < 0 or args.threads < 1 or args.timeout <= 0:
        ap.error('--points must be >= 0, --threads >= 1 and --timeout > 0')
    os.makedirs(args.work, exist_ok=True)
    name = ('scaling' if args.scaling else 'sweep') + ('-quick' if args.quick else '')
    csv_path = os.path.join(args.out, name + '.csv')
    cols = SCALING_COLS if args.scaling else SWEEP_COLS
    key = scaling_key if args.scaling else sweep_key
    command = 'python3 bench/bench.py ' + ' '.join(shlex.quote(a) for a in (argv if argv is not None
                                                                            else sys.argv[1:]))

    if args.report_only:
        # The command that would measure these rows again.
        command = 'python3 bench/bench.py' + (' --quick' if args.quick else '') + \
            (' --scaling' if args.scaling else '') + (' --docs' if args.docs else '')
    failures = 0
    if args.report_only:
        rows = read_csv(csv_path)
        if not rows:
            log('bench: %s is empty or missing: nothing to report' % csv_path)
            return 1
    else:
        if not os.access(args.photonfarm, os.X_OK):
            log('bench: %s is not an executable: build first (cmake -S . -B build && cmake --build build -j2)'
                % args.photonfarm)
            return 2
        version, git = binary_version(args.photonfarm)
        head = head_hash()
        if git and head and not head.startswith(git[:7]) and not git.startswith(head[:7]):
            log('bench: note: %s was built from %s, the checkout is at %s' % (args.photonfarm, git, head))
        machine = machine_info()
        load = os.getloadavg()[0] if hasattr(os, 'getloadavg') else 0.0
        log('bench: %s, %s; %s; load average %.2f%s' % (name, version or args.photonfarm, machine, load,
                                                        ' (the machine is busy: times will be slow)'
                                                        if load > 0.5 * (os.cpu_count() or 1) else ''))
        runner = Runner(args, git, machine)
        if args.scaling:
            new = run_scaling(args, runner, mode)
        else:
            new = run_sweep(args, runner, mode, render_help(args.photonfarm))
        failures = runner.failures
        if args.dry_run:
            return 0
        if not new:
            log('bench: nothing was run')
            return 1
        rows = merge_csv(csv_path, cols, new, key)
        log('bench: %d rows in %s' % (len(rows), os.path.relpath(csv_path, ROOT)))
    if args.scaling:
        written = report(args, mode, None, rows, command)
    else:
        written = report(args, mode, rows, None, command)
    for w in written:
        log('bench: wrote %s' % os.path.relpath(w, ROOT))
    if failures:
        log('bench: %d render(s) failed or timed out; see the status and note columns' % failures)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
