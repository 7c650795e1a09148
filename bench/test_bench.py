#!/usr/bin/env python3
"""test_bench.py: smoke test of the benchmark harness (ctest bench_smoke).

What it checks, in about ten seconds:
  - the log parser on the renderer's real lines, with fields missing, and on
    the farm's variant of the photon-pass line;
  - the choice of reference (same size, larger reference downsampled,
    render downsampled, none);
  - run_process: a child's own peak RSS (not the harness's, not an earlier
    child's) including a grandchild it reaped, exit codes, a timeout that
    kills the child's whole group;
  - the docs markers: text outside them survives, a rerun is idempotent;
  - the families that need --time-limit / --quality: skipped when the help
    lacks them, passed alone (no --spp etc.) when it has them;
  - a failing and a hanging renderer (a stand-in script) are recorded in the
    CSV and the run ends with exit code 1;
  - end to end with the real renderer: two spp points of cornell-box at
    64x64 give a CSV with finite errors that fall with more samples, a
    markdown report and a PNG plot.

Usage: python3 bench/test_bench.py [--photonfarm PATH]
Prints one line per check and a closing "N passed, M failed".
"""

import argparse
import csv
import os
import stat
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, HERE)
import bench  # noqa: E402

PASSED = 0
FAILED = 0


def check(cond, what):
    global PASSED, FAILED
    if cond:
        PASSED += 1
        print('ok   %s' % what)
    else:
        FAILED += 1
        print('FAIL %s' % what)
    return cond


LOG = '''2026-11-22T07:04:32.773Z scene scenes/cornell-box/scene.json: 36 triangles, 0 spheres, 8 materials, 0 point/spot lights (0.03 s to load)
2026-11-22T07:04:32.773Z settings: 512x512, 16 spp, 400000 global + 300000 caustic photons, 16 gather rays, seed 1
2026-11-22T07:04:34.146Z photon pass: 721258 global + 119653 caustic photons stored, 180315 irradiance points (trace 0.54 s, kd-trees 0.24 s, irradiance 1.94 s)
2026-11-22T07:04:34.488Z done in 51.59 s: photons 2.71 s, render 48.65 s -> /tmp/s.png, /tmp/s.pfm
'''


def test_parse_log():
    p = bench.parse_log(LOG)
    check(p.get('triangles') == '36' and p.get('load_s') == '0.03', 'parse_log: scene line')
    check((p.get('width'), p.get('spp'), p.get('photons'), p.get('caustic'), p.get('gather')) ==
          ('512', '16', '400000', '300000', '16'),
          'parse_log: settings line (its caustic count, not the photon pass\'s)')
    check((p.get('global_stored'), p.get('caustic_stored'), p.get('trace_s'), p.get('kdtree_s'),
           p.get('irradiance_s')) == ('721258', '119653', '0.54', '0.24', '1.94'), 'parse_log: photon pass line')
    check((p.get('done_s'), p.get('photon_s'), p.get('render_s')) == ('51.59', '2.71', '48.65'),
          'parse_log: done line')
    q = bench.parse_log('\n'.join(LOG.splitlines()[:2]) + '\n2026-11-22T07:04:34.146Z error: out of memory\n')
    check('photon_s' not in q and 'render_s' not in q and q.get('spp') == '16',
          'parse_log: a missing line leaves its fields out, the others stay')
    farm = bench.parse_log('photon pass: 10 global + 2 caustic photons, 3 irradiance points; scene blob 5 bytes\n'
                           'done in 1.5 s: photons 0.5 s, render 0.75 s -> a.png\n')
    check(farm.get('global_stored') == '10' and farm.get('caustic_stored') == '2' and 'trace_s' not in farm
          and farm.get('render_s') == '0.75', 'parse_log: the farm\'s photon pass line')


def test_pick_reference(tmp):
    refs = os.path.join(tmp, 'refs')
    os.makedirs(refs)
    for n in (128, 256, 512):
        open(os.path.join(refs, 'cornell-box-%d.pfm' % n), 'w').close()
    r, why = bench.pick_reference(refs, 'cornell-box', 256, 256)
    check(r.endswith('cornell-box-256.pfm') and why == '', 'pick_reference: same size')
    r, why = bench.pick_reference(refs, 'cornell-box', 64, 64)
    check(r.endswith('cornell-box-128.pfm') and 'downsampled' in why, 'pick_reference: larger reference downsampled')
    r, why = bench.pick_reference(refs, 'cornell-box', 1024, 1024)
    check(r.endswith('cornell-box-512.pfm') and 'render downsampled' in why, 'pick_reference: render downsampled')
    r, why = bench.pick_reference(refs, 'cornell-box', 100, 100)
    check(r is None and why, 'pick_reference: no integer factor, no reference')
    r, why = bench.pick_reference(refs, 'bunny', 128, 128)
    check(r is None and 'no reference' in why, 'pick_reference: a scene without references')


def test_run_process(tmp):
    logp = os.path.join(tmp, 'p.log')
    big = bench.run_process([sys.executable, '-c', 'b = b"x" * (200 << 20); print(len(b))'], logp, 60)
    small = bench.run_process([sys.executable, '-c', 'pass'], logp, 60)
    check(big['status'] == 'ok' and big['rss_mb'] >= 200, 'run_process: a 200 MB child reports >= 200 MB (%.0f)'
          % big['rss_mb'])
    check(small['status'] == 'ok' and small['rss_mb'] < 100,
          'run_process: the next, small child reports its own peak (%.0f MB), not the earlier one' % small['rss_mb'])
    # What the docs claim for --workers: a grandchild the child reaped counts.
    gc = bench.run_process([sys.executable, '-c', 'import subprocess, sys; subprocess.run([sys.executable, "-c", '
                            '"b = b\'x\' * (200 << 20)"])'], logp, 60)
    check(gc['status'] == 'ok' and gc['rss_mb'] >= 200,
          'run_process: a reaped grandchild\'s peak counts (%.0f MB)' % gc['rss_mb'])
    r = bench.run_process(['sh', '-c', 'echo boom >&2; exit 3'], logp, 60)
    check(r['status'] == 'failed' and r['code'] == 3 and bench.log_tail(logp) == 'boom',
          'run_process: exit code and the log\'s tail')
    t0 = time.monotonic()
    # The grandchild holds the log open; the group kill must end it too.
    r = bench.run_process(['sh', '-c', 'sleep 30 & sleep 30'], logp, 0.5)
    check(r['status'] == 'timeout' and time.monotonic() - t0 < 15, 'run_process: timeout kills the group')
    r = bench.run_process(['/nonexistent/photonfarm'], logp, 5)
    check(r['status'] == 'failed' and 'cannot start' in r['note'], 'run_process: a missing program is a failure')


def test_docs_markers(tmp):
    doc = os.path.join(tmp, 'b.md')
    with open(doc, 'w') as fp:
        fp.write('# T\n\nintro\n\n%s\nold\n%s\n\nafter\n' % (bench.MARK_BEGIN % 'sweep', bench.MARK_END % 'sweep'))
    bench.replace_section(doc, 'sweep', 'NEW TABLE\n')
    bench.replace_section(doc, 'sweep', 'NEW TABLE\n')
    text = open(doc).read()
    check('intro' in text and 'after' in text and text.count('NEW TABLE') == 1 and 'old' not in text,
          'replace_section: outside text kept, inside replaced, idempotent')
    bench.replace_section(doc, 'scaling', 'SCALING\n')
    text = open(doc).read()
    check(text.count(bench.MARK_BEGIN % 'scaling') == 1 and 'SCALING' in text and 'NEW TABLE' in text,
          'replace_section: a missing section is appended with its markers')


FAKE = '''#!/bin/sh
# A stand-in photonfarm for the harness's error paths.
case "$1" in
--version) echo "photonfarm 0.0.0 (0123456789ab)"; exit 0 ;;
compare) echo '{"relmse":0.5,"rmse":0.1,"lum_ratio":1}'; exit 0 ;;
esac
if [ "$2" = --help ]; then echo "%s"; exit 0; fi
%s
'''


def fake(tmp, name, help_text, body):
    path = os.path.join(tmp, name)
    with open(path, 'w') as fp:
        fp.write(FAKE % (help_text, body))
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)
    return path


def run_bench(args):
    return subprocess.run([sys.executable, os.path.join(HERE, 'bench.py')] + args, capture_output=True, text=True,
                          cwd=ROOT, timeout=300)


def test_families(tmp):
    old = fake(tmp, 'old', '--spp N --workers N', 'exit 0')
    p = run_bench(['--quick', '--families', 'time-limit', 'quality', '--scenes', 'cornell-box', '--photonfarm', old,
                   '--out', os.path.join(tmp, 'f1'), '--work', os.path.join(tmp, 'w1')])
    check(p.returncode == 1 and 'skipping family time-limit' in p.stderr and 'skipping family quality' in p.stderr,
          'families: time-limit and quality skipped, with a message, when the help lacks them')
    new = fake(tmp, 'new', '--spp N --workers N --time-limit S --quality Q', 'exit 0')
    p = run_bench(['--quick', '--families', 'time-limit', 'quality', '--scenes', 'cornell-box', '--photonfarm', new,
                   '--dry-run', '--work', os.path.join(tmp, 'w2')])
    lines = p.stdout.splitlines()
    check(p.returncode == 0 and any('--time-limit 2' in ln for ln in lines) and
          any('--quality draft' in ln for ln in lines) and not any('--spp' in ln for ln in lines),
          'families: --time-limit and --quality passed alone when the help has them')


def test_failures(tmp):
    broken = fake(tmp, 'broken', '--workers', 'echo "scene.json:3: JSON syntax error" >&2; exit 3')
    out = os.path.join(tmp, 'fail')
    p = run_bench(['--quick', '--families', 'spp', '--scenes', 'cornell-box', '--points', '2', '--photonfarm', broken,
                   '--out', out, '--work', os.path.join(tmp, 'w3')])
    rows = bench.read_csv(os.path.join(out, 'sweep-quick.csv'))
    check(p.returncode == 1 and len(rows) == 2 and all(r['status'] == 'failed' for r in rows) and
          'JSON syntax error' in rows[0]['note'], 'a failing render is recorded and the sweep goes on (exit 1)')
    hang = fake(tmp, 'hang', '--workers', 'sleep 30')
    out = os.path.join(tmp, 'hang-out')
    t0 = time.monotonic()
    p = run_bench(['--quick', '--families', 'spp', '--scenes', 'cornell-box', '--points', '1', '--timeout', '0.5',
                   '--photonfarm', hang, '--out', out, '--work', os.path.join(tmp, 'w4')])
    rows = bench.read_csv(os.path.join(out, 'sweep-quick.csv'))
    check(p.returncode == 1 and len(rows) == 1 and rows[0]['status'] == 'timeout' and time.monotonic() - t0 < 30,
          'a hanging render is killed at --timeout and recorded')


def test_end_to_end(tmp, exe):
    if not os.access(exe, os.X_OK):
        check(False, 'end to end: %s is not built' % exe)
        return
    out = os.path.join(tmp, 'e2e')
    p = run_bench(['--quick', '--families', 'spp', '--scenes', 'cornell-box', '--size', '64', '--points', '2',
                   '--photonfarm', exe, '--out', out, '--work', os.path.join(tmp, 'w5'),
                   '--refs', os.path.join(ROOT, 'tests', 'data', 'references')])
    check(p.returncode == 0, 'end to end: exit 0' + ('' if p.returncode == 0 else ': ' + p.stderr[-800:]))
    path = os.path.join(out, 'sweep-quick.csv')
    with open(path, newline='') as fp:
        header = next(csv.reader(fp))
    check(header[:19] == ['scene', 'family', 'value', 'size', 'spp', 'gather', 'photons', 'caustic', 'workers',
                          'threads', 'wall_s', 'photon_s', 'render_s', 'peak_rss_mb', 'relmse', 'rmse', 'lum_ratio',
                          'git', 'date'], 'end to end: CSV columns in the agreed order')
    rows = bench.read_csv(path)
    check(len(rows) == 2 and [r['value'] for r in rows] == ['1', '4'] and all(r['status'] == 'ok' for r in rows),
          'end to end: two rows, both ok')
    if len(rows) != 2:
        return
    fin = all(0 < (bench.num(r['relmse']) or -1) < 1 and 0 < (bench.num(r['rmse']) or -1) < 1 and
              0.8 < (bench.num(r['lum_ratio']) or 0) < 1.2 for r in rows)
    check(fin, 'end to end: finite relMSE, RMSE and luminance ratio in range')
    check(all((bench.num(r['wall_s']) or 0) > 0 and (bench.num(r['peak_rss_mb']) or 0) > 1 and
              bench.num(r['photon_s']) is not None and bench.num(r['render_s']) is not None and r['size'] == '64x64'
              for r in rows), 'end to end: wall time, peak RSS, photon and render times, size recorded')
    check(fin and bench.num(rows[1]['relmse']) < bench.num(rows[0]['relmse']),
          'end to end: spp 4 has a lower relMSE than spp 1 (%s < %s)' % (rows[1]['relmse'], rows[0]['relmse']))
    md = os.path.join(out, 'sweep-quick.md')
    text = open(md).read() if os.path.exists(md) else ''
    check('### cornell-box' in text and '| spp | 4 | 64x64 |' in text and 'bench-cornell-box-quick.png' in text,
          'end to end: markdown report with the table and the plot')
    png = os.path.join(out, 'bench-cornell-box-quick.png')
    ok = os.path.exists(png) and os.path.getsize(png) > 2000 and open(png, 'rb').read(8) == b'\x89PNG\r\n\x1a\n'
    check(ok, 'end to end: PNG plot written' + ('' if ok else ' (is gnuplot installed? deploy/install-deps.sh --test)'))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--photonfarm', default=os.path.join(ROOT, 'build', 'bin', 'photonfarm'))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix='pf-bench-test.') as tmp:
        test_parse_log()
        test_pick_reference(tmp)
        test_run_process(tmp)
        test_docs_markers(tmp)
        test_families(tmp)
        test_failures(tmp)
        test_end_to_end(tmp, os.path.abspath(args.photonfarm))
    print('%d passed, %d failed' % (PASSED, FAILED))
    return 1 if FAILED else 0


if __name__ == '__main__':
    sys.exit(main())
