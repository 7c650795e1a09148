#!/usr/bin/env python3
"""scale.py: a scaling model of the render farm, checked against measurements.

The model predicts a one-pass farm render's wall time on W workers from the
costs of its parts, each measured on this machine (--measure writes them to
bench/results/scale-costs.json, so the inputs are visible) and from the
links' bandwidth and latency:

  coordinator   load the scene; photon pass: trace (on its cores), kd-tree
                build, irradiance points, serialize the maps blob
  distribution  every worker fetches the scene and maps blobs (1 MiB chunks,
                8 in flight per worker) from the coordinator, whose link and
                serving rate are shared by all; with fan-out (as built:
                coordinator/fanout.c) the coordinator sends each chunk once,
                to the root worker, and workers pass chunks on down a binary
                tree (depth floor(log2 W): fanout_depth(), one chunk of
                pipelining per level)
  worker build  each worker builds its Embree scene, reads the maps and
                fills its irradiance texels (in parallel on every worker)
  tiles         the tiles go to W x threads slots, one tile per core at a
                time, in queue order, each to the slot free first; the
                last quarter of the grid is split in four
                (coordinator/leases.c), so the round that is not full
                costs a quarter tile; a small tile's pixels cost more
                (tile_cost: the first-gather filter's border is a larger
                share); the coordinator handles one RESULT at a time (its
                per-message cost) and receives 12 bytes a pixel
  distributed tracing (switch): workers get the scene first, trace the
                photons in parallel and upload the photon records (32 bytes
                each) to the coordinator, which traces batches too and
                never waits (no longer than tracing them all there), and
                builds the kd-trees on its own cores; then the irradiance points are spread too
                (coordinator/farm_irr.c): the coordinator serializes the
                global map alone (32 bytes a stored photon) and every worker
                fetches it (with fan-out down its own tree, as the maps
                blob; without, W copies through the coordinator's link),
                reads it, and the points'
                core-seconds spread over W x threads, their records (32
                bytes each, both maps under a path-length limit) coming back
                through the coordinator's link; the coordinator computes
                chunks itself meanwhile and never waits, so the step takes
                no longer than computing every point there

Efficiency E(W) = T(1) / (W T(W)), the same model and configuration at one
worker. Defaults: a worker and the coordinator are each a machine like this
one (its cores, its measured costs), a 10 Gbit/s link with a 0.1 ms round
trip, tile 32. Scenes: the Bitterli dining room (a pbrt-v4 interior) at
1280x720 at 64 spp ("interior") and 256 spp ("interior-hq"), its per-pixel
cost measured at 160x90; the Cornell box at 512x512, measured at 128x128.

--check validates the model on network-namespace hosts
(tests/integration/scale_hosts.sh): a coordinator and 1..6 workers on this
machine, every link a tbf token bucket so that the link, not the 2 cores,
limits (three series, SERIES below: the coordinator's link limits, or each
worker's, both without fan-out; then the first with the farm's fan-out
tree). The farm runs with its defaults but for --verify 0 and the fan-out
degree, so its photon pass is spread over the workers and the prediction
has distributed tracing on. Before each run the small configuration's costs
and the slowdown of W threads at once are measured by separate local runs
(never fitted to the namespace runs); the model predicts the run and the
error is printed, then the mean and largest error of each series and of
all. It ends with "efficiency at 64 workers: E; model error on measured
hosts: V %" (E: the headline configuration, HEADLINE below; V: the mean
absolute error over all runs) and fails above --max-error (over all runs
or in any series). --quick: the ctest version (QUICK_SERIES: 5 runs).

Standard library only. Plots are SVG written here (no matplotlib needed).
"""

import argparse
import datetime
import heapq
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
COSTS = os.path.join(HERE, 'results', 'scale-costs.json')
VALIDATION = os.path.join(HERE, 'results', 'scale-validation.json')

CHUNK = 1 << 20           # proto/messages.h PF_PROTO_CHUNK_SIZE
WINDOW = 8 * CHUNK        # coordinator's blob window per worker
FANOUT_DEGREE = 2         # coordinator/farm.c: --fanout's default, children per serving worker
# Payload bytes per byte a link carries: TCP over Ethernet at MTU 1500 (with
# timestamps, Linux's default) puts 1448 payload bytes in a 1514-byte frame
# (Ethernet 14 + IP 20 + TCP 20 + options 12), which is what tbf counts on
# the namespace hosts' veths; a real Ethernet link also spends 24 bytes a
# frame on preamble, FCS and the gap (1538).
PAYLOAD_TBF = 1448 / 1514
PAYLOAD_ETHERNET = 1448 / 1538
PHOTON_BYTES = 32         # a photon record on the wire (docs/benchmarks.md)
RESULT_BYTES_PER_PIXEL = 12
# A tile's cost per pixel grows as it shrinks: each camera sample records
# first-gather filter samples over the tile and its border of FILTER_BORDER
# pixels, (w + 2 b)(h + 2 b) / (w h) of the tile's, at REC_OVER_RENDER the
# cost of the sample's own rendering (the time-limit probe on the dining
# room, `photonfarm render DINING --size 320x180 --time-limit 12 -v`: 0.550 s
# for 138,240 recorded samples, 0.511 s for 61,440 rendered: 3.98 / 8.32 us).
# tile_cost() gives a w x h tile's factor; the per-pixel cost measured at the
# measure size is divided by its layout's mean factor (tile 32, the farm's
# default), so a grid of 16-pixel tiles costs its 9 % more, as the split
# tail's quarters do (before, only the split quarters paid it and a tile-16
# grid was taken at the cost of 32s: 0.914 at 64 workers where 0.89 holds).
REC_OVER_RENDER = 3.98 / 8.32
FILTER_BORDER = 2
MEASURE_TILE = 32


def tile_cost(w, h):
    """A w x h tile's render cost per pixel, relative to the samples' own."""
    b = FILTER_BORDER
    return REC_OVER_RENDER * (w + 2 * b) * (h + 2 * b) / (w * h) + 1.0


def layout_factor(w, h, tile):
    """The pixel-weighted mean tile_cost of the farm's tiles at w x h."""
    lay = tile_layout(w, h, tile)
    return sum(tw * th * tile_cost(tw, th) for tw, th in lay) / sum(tw * th for tw, th in lay)

# Scenes of the model: (name, scene, full size, render options, size at
# which the per-pixel render cost is measured).
DINING = '/work/shared/scenes/bitterli/dining-room/scene-v4.pbrt'
SCENES = {
    'interior': dict(scene=os.path.join(ROOT, '..', 'shared', 'scenes', 'bitterli', 'dining-room', 'scene-v4.pbrt'),
                     label='Bitterli dining room (pbrt-v4 interior), 1280x720, spp 64',
                     size=(1280, 720), measure_size=(160, 90),
                     opts=['--spp', '64', '--photons', '1000000', '--caustic-photons', '200000'],
                     irr_maps=2),
    'interior-hq': dict(scene=os.path.join(ROOT, '..', 'shared', 'scenes', 'bitterli', 'dining-room', 'scene-v4.pbrt'),
                        label='Bitterli dining room, 1280x720, final quality (spp 256)',
                        size=(1280, 720), measure_size=(160, 90),
                        opts=['--spp', '256', '--photons', '1000000', '--caustic-photons', '200000'],
                        irr_maps=2),
    'cornell': dict(scene=os.path.join(ROOT, 'scenes', 'cornell-box', 'scene.json'),
                    label='Cornell box (scenes/cornell-box), 512x512',
                    size=(512, 512), measure_size=(128, 128),
                    opts=['--spp', '36', '--photons', '400000'], irr_maps=1),
}
# Irradiance maps a scene's precompute makes (irr_maps above): 2 under a
# path-length limit of 3 or more (the pbrt interior: maxdepth 8; the deep
# gathers' map, photonmap.h), else 1.
IRR_RECORD_BYTES = 32     # an irradiance point on the wire (IRR_POINTS)
IRR_MIN_POINTS = 64 * 4096  # coordinator/farm_irr.c S_MIN_POINTS: fewer (both maps) stay on the coordinator
# The validation's configuration: small enough to render in seconds, with a
# maps blob (~15 MB) that takes seconds on the limited links.
VALID = dict(scene=os.path.join(ROOT, 'scenes', 'cornell-box', 'scene.json'),
             size=(128, 128), opts=['--spp', '4', '--photons', '200000'])


EXE = os.path.join(ROOT, 'build', 'bin', 'photonfarm')


def log(msg):
    sys.stderr.write('[scale] %s\n' % msg)
    sys.stderr.flush()


# ---------------------------------------------------------------- measuring

TS = re.compile(r'^(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d+)Z ')


def stamp(line):
    m = TS.match(line)
    if not m:
        return None
    return datetime.datetime.strptime(m.group(1), '%Y-%m-%dT%H:%M:%S.%f').timestamp()


def first(lines, regex):
    r = re.compile(regex)
    for ln in lines:
        m = r.search(ln)
        if m:
            return ln, m
    return None, None


def parse_farm_log(text):
    """Figures of a farm render's -v log (coordinator and, for local workers,
    their lines too): load, photon pass, blob sizes, worker fetch/build, tiles."""
    lines = text.splitlines()
    out = {}
    _, m = first(lines, r'\(([\d.]+) s to load\)')
    out['load_s'] = float(m.group(1)) if m else 0.0
    ln, m = first(lines, r'photon pass: (\d+) global \+ (\d+) caustic photons, (\d+) irradiance points; '
                         r'scene blob (\d+) bytes, map blob (\d+) bytes')
    if m:
        out['stored'] = int(m.group(1)) + int(m.group(2))
        out['irradiance_points'] = int(m.group(3))
        out['scene_bytes'] = int(m.group(4))
        out['maps_bytes'] = int(m.group(5))
        out['t_job'] = stamp(ln)
    _, m = first(lines, r'summary: photon pass ([\d.]+) s, render ([\d.]+) s, total ([\d.]+) s')
    if m:
        out['photon_s'], out['render_s'], out['total_s'] = map(float, m.groups())
    ln, m = first(lines, r'summary: (\d+) tiles')
    out['tiles'] = int(m.group(1)) if m else 0
    out['t_summary'] = stamp(ln) if ln else None
    _, m = first(lines, r'done in ([\d.]+) s')
    out['done_s'] = float(m.group(1)) if m else None
    # The first worker's maps fetch and build (local-1 or w1): the JOB's
    # build starts as its blobs are complete (the first large blob to
    # complete may be the irradiance's global map, fetched earlier).
    ln, _ = first(lines, r'job \d+: building the scene and photon maps')
    if not ln:
        ln, _ = first(lines, r'blob [0-9a-f]+ complete \((\d{6,}) bytes\)')
    t_fetched = stamp(ln) if ln else None
    ln, _ = first(lines, r'job \d+: ready \(')
    t_ready = stamp(ln) if ln else None
    ln, _ = first(lines, r'fetching the (scene|maps) blob')
    t_fetch0 = stamp(ln) if ln else None
    if t_fetched and t_ready:
        out['wbuild_s'] = t_ready - t_fetched
    if t_fetch0 and t_fetched:
        out['fetch_s'] = t_fetched - t_fetch0
    if t_ready and out.get('t_summary'):
        out['tiles_s'] = out['t_summary'] - t_ready
    return out


def parse_inprocess_log(text):
    m = re.search(r'\(trace ([\d.]+) s, kd-trees ([\d.]+) s, irradiance ([\d.]+) s\)', text)
    if not m:
        return {}
    return dict(zip(('trace_s', 'kd_s', 'irradiance_s'), map(float, m.groups())))


def run(cmd, timeout=3600):
    t0 = time.monotonic()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=timeout)
    if p.returncode != 0:
        raise RuntimeError('%s failed (%d): %s' % (' '.join(cmd), p.returncode, p.stderr[-800:]))
    return p.stderr, time.monotonic() - t0


def loadavg():
    try:
        return float(open('/proc/loadavg').read().split()[0])
    except OSError:
        return None


def median(xs):
    xs = sorted(x for x in xs if x is not None)
    if not xs:
        return None
    n = len(xs)
    return xs[n // 2] if n % 2 else (xs[n // 2 - 1] + xs[n // 2]) / 2


def median_dict(ds):
    """Field by field median of the numeric fields of several parses (the
    machine is shared: one run's time can be off by half)."""
    out = dict(ds[0])
    for k, v in ds[0].items():
        if isinstance(v, (int, float)):
            out[k] = median([d.get(k) for d in ds])
    return out


def measure_scene(exe, scene, size, opts, mw, mh, threads, work, reps=1):
    """One scene's costs: a local farm render (1 worker x `threads`) at the
    measure size for the coordinator's pass, blob sizes, the worker's build
    and the tiles; an in-process photon pass (tiny image) for the split of
    trace / kd-trees / irradiance. With reps > 1, the median of each."""
    out = os.path.join(work, 'm.png')
    fs, ps, walls = [], [], []
    for _ in range(reps):
        text, wall = run([exe, 'render', scene, '-o', out, '--size', '%dx%d' % (mw, mh)] + opts +
                         ['--workers', '1', '--threads', str(threads), '--verify', '0', '-v'])
        fs.append(parse_farm_log(text))
        walls.append(wall)
        text2, _ = run([exe, 'render', scene, '-o', out, '--size', '16x16'] + opts +
                       ['--spp', '1', '--threads', str(os.cpu_count()), '-v'])
        ps.append(parse_inprocess_log(text2))
    f = median_dict(fs)
    f.update(median_dict(ps))
    wall = median(walls)
    px = mw * mh
    c = dict(scene=os.path.relpath(os.path.realpath(scene), ROOT), size=list(size), opts=opts,
             measured_at='%dx%d' % (mw, mh), worker_threads=threads,
             load_s=f['load_s'], trace_s=f.get('trace_s'), kd_s=f.get('kd_s'),
             irradiance_s=f.get('irradiance_s'), coord_photon_s=f['photon_s'],
             stored_photons=f['stored'], scene_bytes=f['scene_bytes'], maps_bytes=f['maps_bytes'],
             wbuild_s=f.get('wbuild_s'), measured_tiles=f['tiles'], measured_tiles_s=f.get('tiles_s'),
             # core-seconds per pixel: the worker's tile time x its threads / pixels
             core_s_per_pixel=f['tiles_s'] * threads / px, wall_s=wall)
    log('%s: %s' % (os.path.basename(os.path.dirname(scene)) or scene, json.dumps(c)))
    return c


def measure_transfer(work):
    """bench_transfer at 1M photons: serialize rate and the loopback
    serving rate (sender and receiver on this machine)."""
    exe = os.path.join(os.path.dirname(os.path.abspath(EXE)), 'bench_transfer')
    runs = []
    for _ in range(3):
        p = subprocess.run([exe, '1000000'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=600)
        t = p.stdout
        blob = int(re.search(r'blob\s+(\d+) bytes', t).group(1))
        ser = float(re.search(r'serialize\s+([\d.]+) s', t).group(1))
        wire = float(re.search(r'transfer\s+([\d.]+) s', t).group(1))
        runs.append(dict(serialize_Bps=blob / ser, serve_Bps=blob / wire, blob_bytes=blob))
    out = median_dict(runs)
    out['source'] = 'build/bin/bench_transfer 1000000, median of 3'
    return out


def measure_message(exe, work):
    """Per-message overhead: the coordinator's time per tile of a render
    that does almost nothing per tile (emitted light only, 8x8 tiles, one
    local worker): an upper bound of the round trip TILE -> RESULT."""
    scene = os.path.join(ROOT, 'scenes', 'cornell-box', 'scene.json')
    text, _ = run([exe, 'render', scene, '-o', os.path.join(work, 'msg.png'), '--size', '256x256', '--spp', '1',
                   '--photons', '1000', '--caustic-photons', '0', '--terms', 'emitted', '--tile', '8',
                   '--workers', '1', '--threads', '1', '--verify', '0', '-v'])
    f = parse_farm_log(text)
    return dict(per_tile_s=f['tiles_s'] / f['tiles'], tiles=f['tiles'], tiles_s=f['tiles_s'],
                source='256x256 --terms emitted --tile 8, 1 local worker x 1 thread')


def measure_slowdown(exe, work, k):
    """How much slower each of k threads runs than one thread alone, now
    (the machine is shared: with a background load the answer is not
    k / cores): an in-process render's time at k threads over its time at 1,
    times k (the work is the same)."""
    scene = VALID['scene']
    ts = {}
    for th in sorted({1, k}):
        text, _ = run([exe, 'render', scene, '-o', os.path.join(work, 'c.png'), '--size', '96x96', '--spp', '8',
                       '--photons', '20000', '--threads', str(th), '-v'])
        ts[th] = float(re.search(r'render ([\d.]+) s', text.splitlines()[-1]).group(1))
    return max(1.0, ts[k] * k / ts[1])


def measure_validation(exe, work, reps=3):
    """The validation configuration's costs, by local runs (loopback, no
    namespace): what the coordinator and one 1-thread worker spend."""
    w, h = VALID['size']
    return measure_scene(exe, VALID['scene'], VALID['size'], VALID['opts'], w, h, 1, work, reps=reps)


def cmd_measure(args):
    exe = args.photonfarm
    work = tempfile.mkdtemp(prefix='pf_scale_')
    costs = dict(machine=dict(cores=os.cpu_count(), loadavg_before=loadavg(),
                              when=datetime.datetime.utcnow().strftime('%Y-%m-%d %H:%M UTC'),
                              commit=subprocess.run(['git', 'rev-parse', '--short=12', 'HEAD'], cwd=ROOT,
                                                    stdout=subprocess.PIPE, text=True).stdout.strip()))
    costs['transfer'] = measure_transfer(work)
    costs['message'] = measure_message(exe, work)
    costs['scenes'] = {}
    if args.scenes and os.path.exists(COSTS):
        costs['scenes'] = json.load(open(COSTS)).get('scenes', {})
    for name, s in SCENES.items():
        if args.scenes and name not in args.scenes:
            continue
        mw, mh = s['measure_size']
        costs['scenes'][name] = measure_scene(exe, s['scene'], s['size'], s['opts'], mw, mh, os.cpu_count(), work)
    costs['machine']['loadavg_after'] = loadavg()
    os.makedirs(os.path.dirname(COSTS), exist_ok=True)
    with open(COSTS, 'w') as fh:
        json.dump(costs, fh, indent=1, sort_keys=True)
    log('wrote %s' % COSTS)
    return costs


# ---------------------------------------------------------------- the model

def tiles_of(w, h, tile):
    return len(tile_layout(w, h, tile))


def tile_layout(w, h, tile):
    """The farm's tiles in queue order, as (width, height) pairs: the grid
    in row order, its last quarter in quarters (coordinator/leases.c,
    pf_leases_init)."""
    tx, ty = math.ceil(w / tile), math.ceil(h / tile)
    grid = tx * ty
    tail = grid // 4 if tile >= 16 else 0
    half = (tile + 1) // 2
    out = []
    for i in range(grid):
        x0, y0 = (i % tx) * tile, (i // tx) * tile
        if i < grid - tail:
            out.append((min(tile, w - x0), min(tile, h - y0)))
            continue
        for q in range(4):
            qx, qy = x0 + (q & 1) * half, y0 + (q >> 1) * half
            if qx < w and qy < h:
                sw = tile - half if q & 1 else half
                sh = tile - half if q >> 1 else half
                out.append((min(sw, w - qx), min(sh, h - qy)))
    return out


def makespan(costs, slots):
    """Tiles leased in queue order, each to the slot free first (a worker
    thread asks for the next tile when it finishes one): the time the last
    one ends."""
    if slots >= len(costs):
        return max(costs) if costs else 0.0
    free = [0.0] * slots
    heapq.heapify(free)
    for c in costs:
        heapq.heappush(free, heapq.heappop(free) + c)
    return max(free)


def irr_spread_s(c, common, W, threads, coord_cores, spread, R, r, rtt_s, irr_maps=1):
    """The irradiance precompute spread over W workers (coordinator/farm_irr.c):
    the coordinator serializes the global map (the stored photons, 32 bytes
    each, caustic ones included as an upper bound) and the workers fetch it
    (spread(): down the fan-out tree with the fanout switch, else W copies
    through the coordinator's link) and
    read it; the points' core-seconds (measured on the coordinator's cores)
    run on W x threads cores; their records (IRR_RECORD_BYTES, points of
    every map) come back into the coordinator's link. The coordinator
    computes chunks itself meanwhile (work stealing): the step never takes
    longer than computing them all there."""
    irr = c['irradiance_s']
    here = irr * common['machine']['cores'] / coord_cores
    gbytes = c['stored_photons'] * PHOTON_BYTES
    points = max(0, c['maps_bytes'] // PHOTON_BYTES - c['stored_photons']) * irr_maps
    if points < IRR_MIN_POINTS:
        return here   # farm_irr.c computes small precomputes on the coordinator alone
    ser = gbytes / common['transfer']['serialize_Bps']
    out = spread(gbytes, W)
    read = gbytes / common['transfer']['serialize_Bps']   # the worker validates and rebuilds the tree
    compute = irr * common['machine']['cores'] / (W * threads)
    back = points * IRR_RECORD_BYTES / R + rtt_s
    return min(here, ser + out + read + max(compute, back))


def fanout_depth(W, degree=FANOUT_DEGREE):
    """The depth of the deepest of W workers in the tree coordinator/fanout.c
    builds: the first worker fetches from the coordinator (depth 0), every
    later one from the shallowest serving worker with fewer than `degree`
    children, so level d holds degree^d workers (with degree 2: floor(log2 W))."""
    depth, level, placed = 0, 1, 1
    while placed < W:
        depth += 1
        level *= degree
        placed += level
    return depth


def predict(c, common, W, link_bps=10e9, coord_bps=None, rtt_s=1e-4, fanout=False, dtrace=False,
            threads=None, coord_cores=None, tile=32, shared=None, size=None, parts=False, irr_maps=None,
            payload=PAYLOAD_ETHERNET):
    """Wall time (s) of one render of scene costs `c` on W workers.

    link_bps: each worker's link (bits/s); coord_bps: the coordinator's
    (default the same); payload: the share of a link's bytes that is payload
    (PAYLOAD_ETHERNET; PAYLOAD_TBF on the namespace hosts); threads: per
    worker (default the measured worker's); shared: all hosts share this
    machine's cores (the namespace hosts on this machine), else every host
    has its own."""
    threads = threads or c['worker_threads']
    coord_cores = coord_cores or common['machine']['cores']
    r = link_bps / 8 * payload
    R = (coord_bps or link_bps) / 8 * payload
    serve = common['transfer']['serve_Bps']          # the coordinator's chunk serving rate
    R_eff = min(R, serve)
    ser_s = c['maps_bytes'] / common['transfer']['serialize_Bps']
    S_scene, S_maps = c['scene_bytes'], c['maps_bytes']
    # a flow's rate: its link, the window over the round trip
    flow = min(r, WINDOW / rtt_s) if rtt_s > 0 else r

    def spread(nbytes, n):
        """n workers fetch nbytes each from the coordinator."""
        if n <= 0 or nbytes <= 0:
            return 0.0
        if fanout:
            # The coordinator sends every chunk once (to the root worker);
            # each worker passes a chunk on, once it holds and has checked
            # it, to up to FANOUT_DEGREE children sharing its uplink: the
            # stream runs at the slowest of those rates, and each level of
            # the tree adds one chunk's relay and a round trip.
            depth = fanout_depth(n)
            relay = flow / min(FANOUT_DEGREE, n - 1) if n > 1 else flow
            rate = min(R_eff, relay)
            return nbytes / rate + depth * (min(CHUNK, nbytes) / relay + rtt_s) + rtt_s
        return max(n * nbytes / R_eff, nbytes / flow) + 2 * rtt_s

    # CPU sharing: k threads at once run `shared[k]` times slower each
    # (measured), on hosts that share one machine
    def slow(k):
        if not shared:
            return 1.0
        ks = sorted(shared)
        lo = max([x for x in ks if x <= k] or ks[:1])
        hi = min([x for x in ks if x >= k] or ks[-1:])
        if hi == lo:
            return shared[lo]
        return shared[lo] + (shared[hi] - shared[lo]) * (k - lo) / (hi - lo)

    t = {}
    t['load'] = c['load_s']
    trace, kd, irr = c['trace_s'], c['kd_s'], c['irradiance_s']
    # The coordinator's measured pass: its parts at this machine's cores.
    if dtrace:
        t['scene'] = spread(S_scene, W)
        trace_core_s = trace * common['machine']['cores']
        t_trace = trace_core_s / (W * threads) * slow(W * threads)
        up = c['stored_photons'] * PHOTON_BYTES
        t_up = max(up / R, up / W / r) + rtt_s
        # The coordinator's photon thread traces free batches itself and
        # then the oldest leased ones not yet back (coordinator/farm_photons.c):
        # it never waits on a worker, so the pass takes no longer than the
        # trace on the coordinator alone (where the photons' upload through
        # a slow coordinator link would take longer, it does the work).
        t['trace'] = min(trace * common['machine']['cores'] / coord_cores, max(t_trace, t_up))
        S = S_maps
    else:
        t['scene'] = 0.0
        t['trace'] = trace * common['machine']['cores'] / coord_cores
        S = S_maps + S_scene
    if dtrace:
        t['kd'] = kd * common['machine']['cores'] / coord_cores
        t['irradiance'] = irr_spread_s(c, common, W, threads, coord_cores, spread, R, r, rtt_s,
                                       irr_maps or c.get('irr_maps', 1))
    else:
        t['kd+irradiance'] = (kd + irr) * common['machine']['cores'] / coord_cores
    t['serialize'] = ser_s
    t['distribute'] = spread(S, W)
    t['worker build'] = c['wbuild_s'] * slow(W * threads)
    w, h = size or c['size']
    layout = tile_layout(w, h, tile)
    n = len(layout)
    # a small tile's pixels cost more: its first-gather filter's border is a
    # larger share of it (tile_cost); the measured cost is the measure
    # layout's mean
    mw, mh = (int(v) for v in c.get('measured_at', '%dx%d' % tuple(c['size'])).split('x'))
    per_px = c['core_s_per_pixel'] / layout_factor(mw, mh, MEASURE_TILE)
    slots = W * threads
    t_tiles = makespan([per_px * tw * th * tile_cost(tw, th) for tw, th in layout], slots) * slow(slots)
    t_msgs = n * common['message']['per_tile_s']
    t_res = w * h * RESULT_BYTES_PER_PIXEL / R
    t['tiles'] = max(t_tiles, t_msgs, t_res) + rtt_s
    total = sum(t.values())
    return (total, t) if parts else total


def efficiency(c, common, W, **kw):
    """T(1) / (W T(W)), T(1) on one worker at the default tile 32 (a smaller
    tile is slower on one worker too: against its own T(1) it would look
    better than it is)."""
    one = dict(kw, tile=MEASURE_TILE)
    return predict(c, common, 1, **one) / (W * predict(c, common, W, **kw))


# ---------------------------------------------------------------- validation

# The validation's series: (coordinator Mbit/s, worker Mbit/s, --fanout), each
# at 1..6 workers. 60:200: the coordinator's link limits (without fan-out
# the distribution grows with W; with the farm's fan-out tree it stays near
# flat); 400:30: each worker's own link limits. --quick (ctest scale): the
# first setting at 1, 2, 4 workers without fan-out and at 2, 4 with it.
SERIES = [(60, 200, 0), (400, 30, 0), (60, 200, FANOUT_DEGREE)]
QUICK_SERIES = [((60, 200, 0), [1, 2, 4]), ((60, 200, FANOUT_DEGREE), [2, 4])]


def series_name(coord_mbit, worker_mbit, fanout):
    return '%g:%g %s' % (coord_mbit, worker_mbit, 'fan-out %d' % fanout if fanout else 'no fan-out')


def parse_series(text):
    """--links COORD:WORKER[:FANOUT],... (FANOUT 0 when left out)."""
    out = []
    for item in text.split(','):
        f = [float(x) for x in item.split(':')]
        if len(f) not in (2, 3) or f[0] <= 0 or f[1] <= 0:
            raise SystemExit('--links: %r is not COORD_MBIT:WORKER_MBIT[:FANOUT]' % item)
        out.append((f[0], f[1], int(f[2]) if len(f) == 3 else 0))
    return out


def error_stats(rows):
    """(mean, max) absolute error in % over rows."""
    errs = [abs(r['error_pct']) for r in rows]
    return sum(errs) / len(errs), max(errs)


def cmd_check(args, costs):
    exe = args.photonfarm
    pfw = os.path.join(os.path.dirname(exe), 'photonfarm-worker')
    if os.geteuid() != 0:
        print('SKIP: the namespace hosts need root (network namespaces, veth pairs, a bridge, tc)')
        return 77
    work = tempfile.mkdtemp(prefix='pf_scale_check_')
    if args.links:
        plan = [(sr, args.workers or [1, 2, 3, 4, 5, 6]) for sr in parse_series(args.links)]
    elif args.quick:
        plan = [(sr, args.workers or ws) for sr, ws in QUICK_SERIES]
    else:
        plan = [(sr, args.workers or [1, 2, 3, 4, 5, 6]) for sr in SERIES]
    log('machine-wide costs: bench_transfer, per-message overhead')
    common = dict(machine=dict(cores=os.cpu_count()), transfer=measure_transfer(work),
                  message=measure_message(exe, work))
    rows, rtts = [], []
    load0 = loadavg()
    for (coord_mbit, worker_mbit, fanout), counts in plan:
        for W in counts:
            rc = s_validate_run(exe, pfw, work, common, W, coord_mbit, worker_mbit, fanout, rows, rtts,
                                reps=1 if args.quick else 3)
            if rc:
                return rc
    mean_err, max_err = error_stats(rows)
    series = []
    for (cm, wm, fo), _ in plan:
        sub = [r for r in rows if (r['coord_mbit'], r['worker_mbit'], r['fanout']) == (cm, wm, fo)]
        m, x = error_stats(sub)
        series.append(dict(coord_mbit=cm, worker_mbit=wm, fanout=fo, runs=len(sub), mean_abs_error_pct=m,
                           max_abs_error_pct=x))
    res = dict(when=datetime.datetime.utcnow().strftime('%Y-%m-%d %H:%M UTC'), quick=args.quick,
               links=[list(sr) for sr, _ in plan], rtt=sorted(set(rtts)), loadavg_before=load0,
               loadavg=loadavg(), config=dict(VALID, scene=os.path.relpath(VALID['scene'], ROOT)),
               common=common, runs=rows, series=series, mean_abs_error_pct=mean_err, max_abs_error_pct=max_err)
    s_efficiencies(rows)
    if not args.quick:
        with open(VALIDATION, 'w') as fh:
            json.dump(res, fh, indent=1, sort_keys=True)
        log('wrote %s' % VALIDATION)
    e64 = headline(costs)
    for sr in series:
        print('model error, %s: mean %.1f %%, max %.1f %% over %d runs' % (
            series_name(sr['coord_mbit'], sr['worker_mbit'], sr['fanout']), sr['mean_abs_error_pct'],
            sr['max_abs_error_pct'], sr['runs']))
    print('model error on measured hosts: mean %.1f %%, max %.1f %% over %d runs in %d series; load average %s '
          'before, %s after' % (mean_err, max_err, len(rows), len(series), load0, res['loadavg']))
    print('efficiency at 64 workers: %.3f; model error on measured hosts: %.1f %%' % (e64, mean_err))
    worst = max(sr['mean_abs_error_pct'] for sr in series)
    if mean_err > args.max_error or worst > args.max_error:
        print('FAIL: the model\'s mean error (%.1f %% over all runs, %.1f %% in its worst series) is above %g %%'
              % (mean_err, worst, args.max_error))
        return 1
    return 0


def s_validate_run(exe, pfw, work, common, W, coord_mbit, worker_mbit, fanout, rows, rtts, reps=3):
    """One namespace run (W workers at one link setting, --fanout `fanout`)
    against the model. Just before it, the validation configuration's costs
    are measured by local runs (loopback, no namespace: the coordinator's
    pass, one worker's build and tiles) and so is the slowdown of W threads
    at once: the machine is shared and its load moves within minutes, so the
    inputs are taken at the time of the run (never from the run itself).
    The farm runs as it does by default but for --verify 0 and the fan-out
    degree: its photon pass and irradiance precompute are spread over the
    workers, so the prediction has distributed tracing on (for this small
    pass the coordinator traces every batch itself before a worker could
    upload one: the model's trace term takes the faster of the two).
    Appends to rows; returns 0, 77 (skip) or 1."""
    vc = measure_validation(exe, work, reps)
    slowdown = {1: 1.0}
    if W > 1:
        slowdown[W] = measure_slowdown(exe, work, W)
    w, h = VALID['size']
    out = os.path.join(work, 'c%g-w%g-f%d-%d' % (coord_mbit, worker_mbit, fanout, W))
    cmd = ['bash', os.path.join(ROOT, 'tests', 'integration', 'scale_hosts.sh'), exe, pfw, out,
           '%g' % coord_mbit, '%g' % worker_mbit, '1', str(fanout), str(W), VALID['scene'],
           '--size', '%dx%d' % (w, h)] + VALID['opts']
    load = loadavg()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=1800)
    if p.returncode == 77:
        print('SKIP: namespace hosts impossible here: ' + p.stdout.strip().splitlines()[-1])
        return 77
    m = re.search(r'rtt_ms=([\d.]+)', p.stdout)
    # without ping the veths' round trip is taken as 0.1 ms: at these rates
    # it changes a prediction by far less than 1 %
    rtt = float(m.group(1)) / 1000 if m else 1e-4
    rtts.append((rtt, 'ping' if m else 'assumed: no ping here'))
    m = re.search(r'run W=(\d+) rc=(\d+) wall=([\d.]+)', p.stdout)
    if not m or int(m.group(2)) != 0:
        print('the run with %d workers failed: %s' % (W, p.stdout[-300:]))
        path = os.path.join(out, 'w%d.err' % W)
        if os.path.exists(path):
            print(open(path).read()[-1500:])
        return 1
    f = parse_farm_log(open(os.path.join(out, 'w%d.err' % W)).read())
    measured = f['done_s']
    pred, parts = predict(vc, common, W, link_bps=worker_mbit * 1e6, coord_bps=coord_mbit * 1e6, rtt_s=rtt,
                          threads=1, tile=32, shared=slowdown, parts=True, fanout=fanout > 0, dtrace=True,
                          payload=PAYLOAD_TBF)
    err = (pred - measured) / measured * 100
    rows.append(dict(W=W, coord_mbit=coord_mbit, worker_mbit=worker_mbit, fanout=fanout, measured_s=measured,
                     predicted_s=pred, error_pct=err, slowdown=slowdown[W] if W > 1 else 1.0, loadavg=load,
                     costs=vc, farm=f, parts={k: round(v, 3) for k, v in parts.items()}))
    print('%s W=%d  measured %6.2f s  predicted %6.2f s  error %+5.1f %%   (slowdown x%.2f, load %s; %s)' % (
        series_name(coord_mbit, worker_mbit, fanout), W, measured, pred, err, rows[-1]['slowdown'], load,
        ', '.join('%s %.2f' % kv for kv in parts.items() if kv[1] > 0.005)))
    sys.stdout.flush()
    return 0


def s_efficiencies(rows):
    """Measured and predicted efficiency of each run against the run with
    one worker at the same links and fan-out (or, where the series has none,
    at the same links: with one worker the fan-out tree is the coordinator
    alone, the same farm)."""
    for r in rows:
        ones = [q for q in rows if q['W'] == 1 and q['coord_mbit'] == r['coord_mbit']
                and q['worker_mbit'] == r['worker_mbit']]
        one = [q for q in ones if q.get('fanout', 0) == r.get('fanout', 0)] or ones
        if one:
            r['measured_eff'] = one[0]['measured_s'] / (r['W'] * r['measured_s'])
            r['predicted_eff'] = one[0]['predicted_s'] / (r['W'] * r['predicted_s'])


# ---------------------------------------------------------------- report

WS = [1, 2, 4, 8, 16, 32, 64, 128, 256]
VARIANTS = [('today', {}), ('fan-out', dict(fanout=True)), ('distributed tracing', dict(dtrace=True)),
            ('both', dict(fanout=True, dtrace=True))]


def table(costs, name, **kw):
    c = costs['scenes'][name]
    lines = ['| workers | ' + ' | '.join('%s: wall s / E' % v for v, _ in VARIANTS) + ' |',
             '|---|' + '---|' * len(VARIANTS)]
    for W in WS:
        cells = []
        for _, vk in VARIANTS:
            a = dict(kw, **vk)
            cells.append('%.1f / %.3f' % (predict(c, costs, W, **a), efficiency(c, costs, W, **a)))
        lines.append('| %d | %s |' % (W, ' | '.join(cells)))
    return '\n'.join(lines)


def breakdown(costs, name, W, **kw):
    total, parts = predict(costs['scenes'][name], costs, W, parts=True, **kw)
    return '%d workers: %.1f s = %s' % (W, total, ', '.join('%s %.2f' % kv for kv in parts.items() if kv[1] > 0.005))


def svg_plot(path, title, series, xmax=256, ylabel='efficiency'):
    """A small log2-x line plot, by hand. series: [(label, colour, [(x, y)], dashed)]."""
    Wd, Ht, L, R_, T, B = 640, 360, 60, 170, 30, 45
    xmin = 1
    ymin, ymax = 0.0, 1.05

    def X(x):
        return L + (math.log2(x) - math.log2(xmin)) / (math.log2(xmax) - math.log2(xmin)) * (Wd - L - R_)

    def Y(y):
        return T + (1 - (y - ymin) / (ymax - ymin)) * (Ht - T - B)
    o = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="sans-serif" '
         'font-size="11">' % (Wd, Ht), '<rect width="100%" height="100%" fill="white"/>',
         '<text x="%d" y="18" font-size="13">%s</text>' % (L, title)]
    for k in range(0, int(math.log2(xmax)) + 1):
        x = 2 ** k
        o.append('<line x1="%.1f" y1="%d" x2="%.1f" y2="%d" stroke="#ddd"/>' % (X(x), T, X(x), Ht - B))
        o.append('<text x="%.1f" y="%d" text-anchor="middle">%d</text>' % (X(x), Ht - B + 14, x))
    for k in range(0, 11, 2):
        y = k / 10
        o.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="#ddd"/>' % (L, Y(y), Wd - R_, Y(y)))
        o.append('<text x="%d" y="%.1f" text-anchor="end">%.1f</text>' % (L - 4, Y(y) + 4, y))
    o.append('<text x="%d" y="%d" text-anchor="middle">workers</text>' % ((L + Wd - R_) / 2, Ht - 8))
    o.append('<text x="14" y="%d" transform="rotate(-90 14 %d)" text-anchor="middle">%s</text>' % (
        (T + Ht - B) / 2, (T + Ht - B) / 2, ylabel))
    o.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="#888" stroke-dasharray="2,3"/>' % (
        L, Y(0.9), Wd - R_, Y(0.9)))
    for i, (label, col, pts, dashed) in enumerate(series):
        pts = [(x, y) for x, y in pts if xmin <= x <= xmax]
        d = ' '.join('%.1f,%.1f' % (X(x), Y(max(ymin, min(ymax, y)))) for x, y in pts)
        o.append('<polyline fill="none" stroke="%s" stroke-width="2" %s points="%s"/>' % (
            col, 'stroke-dasharray="6,4"' if dashed else '', d))
        for x, y in pts:
            o.append('<circle cx="%.1f" cy="%.1f" r="2.5" fill="%s"/>' % (X(x), Y(max(ymin, min(ymax, y))), col))
        ly = T + 10 + 16 * i
        o.append('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="%s" stroke-width="2" %s/>' % (
            Wd - R_ + 10, ly, Wd - R_ + 30, ly, col, 'stroke-dasharray="6,4"' if dashed else ''))
        o.append('<text x="%d" y="%d">%s</text>' % (Wd - R_ + 34, ly + 4, label))
    o.append('</svg>')
    with open(path, 'w') as fh:
        fh.write('\n'.join(o) + '\n')


COLOURS = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b']


def cmd_report(costs, args):
    out = []
    for name in SCENES:
        if name not in costs['scenes']:
            continue
        c = costs['scenes'][name]
        out.append('### %s\n' % SCENES[name]['label'])
        out.append('10 Gbit/s links, 0.1 ms round trip, 2-thread workers, tile 32:\n')
        out.append(table(costs, name))
        out.append('')
        for W in (64, 256):
            for vn, vk in VARIANTS:
                out.append('- %s, %s' % (vn, breakdown(costs, name, W, **vk)))
        out.append('')
        series = [(vn, COLOURS[i], [(W, efficiency(c, costs, W, **vk)) for W in WS], False)
                  for i, (vn, vk) in enumerate(VARIANTS)]
        series.append(('both, tile 16', COLOURS[4], [(W, efficiency(c, costs, W, fanout=True, dtrace=True, tile=16))
                                                      for W in WS], True))
        if args.plots:
            svg_plot(os.path.join(args.plots, 'scaling-%s.svg' % name),
                     'predicted efficiency: %s' % SCENES[name]['label'], series)
    if os.path.exists(VALIDATION) and args.plots:
        v = json.load(open(VALIDATION))
        series = []
        for i, l in enumerate(v['links']):
            cm, wm, fo = (list(l) + [0])[:3]
            runs = [r for r in v['runs'] if (r['coord_mbit'], r['worker_mbit'], r.get('fanout', 0)) == (cm, wm, fo)]
            tag = '%g:%g%s' % (cm, wm, ' fan-out' if fo else '')
            series.append(('measured ' + tag, COLOURS[2 * i + 1], [(r['W'], r['measured_eff']) for r in runs], False))
            series.append(('model ' + tag, COLOURS[2 * i], [(r['W'], r['predicted_eff']) for r in runs], True))
        svg_plot(os.path.join(args.plots, 'scaling-measured.svg'),
                 'namespace hosts (coordinator:worker link, Mbit/s)', series, xmax=8)
    if os.path.exists(VALIDATION):
        v = json.load(open(VALIDATION))
        out.append('### Measured: namespace hosts\n')
        out.append('%s, %s; links (tc tbf, both ways) coordinator:worker Mbit/s %s; round trip %s, '
                   '1-thread workers, the farm\'s defaults but for `--verify 0` and the fan-out degree; '
                   'load average %s before, %s at the end; %s.\n' % (
                       v['config']['scene'], ' '.join(['--size', '%dx%d' % tuple(v['config']['size'])] +
                                                      v['config']['opts']),
                       ', '.join(series_name(*(list(l) + [0])[:3]) for l in v['links']),
                       ', '.join('%.3f ms (%s)' % (x * 1000, how) for x, how in v['rtt']),
                       v.get('loadavg_before', '?'), v['loadavg'], v['when']))
        out.append('| links Mbit/s | fan-out | workers | measured s | predicted s | error | measured E | predicted E '
                   '| predicted parts (s) |')
        out.append('|---|---|---|---|---|---|---|---|---|')
        for r in v['runs']:
            out.append('| %g:%g | %s | %d | %.2f | %.2f | %+.1f %% | %.3f | %.3f | %s |' % (
                r['coord_mbit'], r['worker_mbit'], r.get('fanout', 0) or 'off', r['W'], r['measured_s'],
                r['predicted_s'], r['error_pct'], r.get('measured_eff', float('nan')),
                r.get('predicted_eff', float('nan')),
                ', '.join('%s %.2f' % kv for kv in r['parts'].items() if kv[1] > 0.005)))
        out.append('')
        for sr in v.get('series', []):
            out.append('- %s: mean absolute error %.1f %%, largest %.1f %% (%d runs)' % (
                series_name(sr['coord_mbit'], sr['worker_mbit'], sr['fanout']), sr['mean_abs_error_pct'],
                sr['max_abs_error_pct'], sr['runs']))
        out.append('\nAll series: mean absolute error %.1f %%, largest %.1f %%.' % (
            v['mean_abs_error_pct'], v['max_abs_error_pct']))
        out.append('')
    text = '\n'.join(out)
    print(text)
    if args.docs:
        doc = os.path.join(ROOT, 'docs', 'scaling.md')
        d = open(doc).read()
        b, e = '<!-- BEGIN GENERATED scale', '<!-- END GENERATED scale -->'
        i = d.index(b)
        i = d.index('\n', i) + 1
        j = d.index(e)
        with open(doc, 'w') as fh:
            fh.write(d[:i] + '\n' + text + '\n' + d[j:])
        log('wrote %s' % doc)
    return text


# The headline configuration: the interior at final quality on 64 workers
# with both features, the default tile 32, 10 Gbit/s links (docs/scaling.md says why).
HEADLINE = dict(scene='interior-hq', fanout=True, dtrace=True, tile=32)


def headline(costs, out=sys.stdout):
    kw = dict(HEADLINE)
    c = costs['scenes'][kw.pop('scene')]
    for name in ('interior', 'interior-hq'):
        if name not in costs['scenes']:
            continue
        out.write('%s at 64 workers, 10 Gbit/s: %s\n' % (name, ', '.join(
            '%s%s E %.3f' % (vn, t16, efficiency(costs['scenes'][name], costs, 64, tile=tile, **vk))
            for vn, vk in VARIANTS for tile, t16 in ((32, ''), (16, ' tile 16')))))
    out.write('headline: %s, 64 workers, fan-out + distributed tracing, tile 32 (the default), 10 Gbit/s\n' % SCENES['interior-hq']['label'])
    return efficiency(c, costs, 64, **kw)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--measure', action='store_true', help='measure the per-part costs on this machine, '
                    'write bench/results/scale-costs.json')
    ap.add_argument('--scenes', nargs='*', help='with --measure: only these (interior, cornell)')
    ap.add_argument('--check', action='store_true', help='validate against namespace hosts')
    ap.add_argument('--quick', action='store_true', help='with --check: the short series (ctest scale)')
    ap.add_argument('--workers', type=int, nargs='*', help='with --check: these worker counts (1..6)')
    ap.add_argument('--links', help='with --check: series COORD_MBIT:WORKER_MBIT[:FANOUT],... (FANOUT: the '
                    'farm\'s --fanout, 0 when left out; default 60:200:0,400:30:0,60:200:2: the coordinator\'s '
                    'link limits, then each worker\'s, then the first with the fan-out tree; --quick: 60:200:0 at '
                    '1, 2, 4 workers and 60:200:2 at 2, 4)')
    ap.add_argument('--max-error', type=float, default=20, help='--check fails above this mean error, over all runs or in any one series (20 %%)')
    ap.add_argument('--plots', help='write SVG plots into this folder (e.g. docs/images)')
    ap.add_argument('--docs', action='store_true', help='rewrite the generated part of docs/scaling.md and '
                    'its plots docs/images/scaling-*.svg')
    ap.add_argument('--photonfarm', default=os.path.join(ROOT, 'build', 'bin', 'photonfarm'))
    args = ap.parse_args(argv)
    if args.docs and not args.plots:
        args.plots = os.path.join(ROOT, 'docs', 'images')
    global EXE
    EXE = args.photonfarm
    if args.measure:
        costs = cmd_measure(args)
    else:
        costs = json.load(open(COSTS))
    for name, sc in costs.get('scenes', {}).items():
        sc.setdefault('irr_maps', SCENES.get(name, {}).get('irr_maps', 1))
    if args.check:
        return cmd_check(args, costs)
    cmd_report(costs, args)
    print('efficiency at 64 workers: %.3f' % headline(costs))
    return 0


if __name__ == '__main__':
    sys.exit(main())
