#!/usr/bin/env bash
# test_fanout.sh: map fan-out measured (issue 21). A coordinator and six
# workers on network-namespace "hosts" (tests/integration/netns.sh), every
# link a token bucket (tc tbf); the coordinator's link is the limited one.
#
#  A. six fresh workers (empty blob caches) render a cornell-box whose photon
#     map blob is several chunks (> 4 MiB). The coordinator's summary line
#     "blobs from the coordinator: maps S bytes sent for M bytes" must show
#     S <= 2 x M (without fan-out it is 6 x M), workers must have fetched
#     the maps from peers (and the scene, which the workers fetch first to
#     trace the photons, or with the maps, likewise: "scene S for M",
#     S <= 2 x M, and plans naming peers), and the image must be bit-identical (cmp) to the
#     in-process render. Meanwhile a hostile peer (pf_inject garbage and
#     truncated frames) hits worker w6's peer socket: the worker drops and
#     strikes what it sends, and serves on.
#  B. the same with the coordinator's link slower still, and the worker that
#     serves the others killed (kill -9) as the maps go out: its children
#     fetch the rest from the coordinator (told by the coordinator when it
#     declares the worker dead, or by their own 4 s stall timer), the render
#     completes, bit-identical again.
#
# usage: tests/integration/test_fanout.sh [photonfarm [photonfarm-worker [pf_inject]]]
#        PF_FANOUT_KEEP=1 keeps the temporary directory (logs, images).
# Needs root, `ip netns` and tc with tbf; without them it exits 77 (ctest:
# skipped). About 30 s on two cores.
set -u

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PF=${1:-$ROOT/build/bin/photonfarm}
PFW=${2:-$ROOT/build/bin/photonfarm-worker}
INJ=${3:-$ROOT/build/bin/pf_inject}
abs() { case $1 in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
PF=$(abs "$PF")
PFW=$(abs "$PFW")
INJ=$(abs "$INJ")
cd "$ROOT" || exit 1

skip_all() {
    echo "SKIP: $*"
    echo "0 passed, 0 failed, 1 skipped"
    exit 77
}
[ "$(id -u)" -eq 0 ] || skip_all "the fan-out test needs root (network namespaces, veth pairs, a bridge, tc)"
command -v ip >/dev/null 2>&1 || skip_all "no 'ip' (Debian package iproute2)"
command -v tc >/dev/null 2>&1 || skip_all "no 'tc' (Debian package iproute2)"

NW=6
TAG=pffo$$
NS_BR=$TAG-br
NS_C=$TAG-c
NAMESPACES=("$NS_BR" "$NS_C")
PAIRS=("$NS_C:to-c")
for k in $(seq 1 "$NW"); do
    NAMESPACES+=("$TAG-w$k")
    PAIRS+=("$TAG-w$k:to-w$k")
done
NET=10.79.0
EP=tcp://$NET.1:7880
COORD_MBIT=80
WORKER_MBIT=200
SCENE=scenes/cornell-box/scene.json
# About 7 MB of maps (7 chunks) and a quick render.
RENDER=(--size 96x96 --spp 1 --photons 100000 --caustic-photons 1000 --gather 4)
FARM=(--tile 16 --heartbeat-ms 250 --verify 0 --max-wait 60 --threads 1)

T=$(mktemp -d "${TMPDIR:-/tmp}/pf_fanout.XXXXXX") || exit 1
# shellcheck source=tests/integration/netns.sh
. "$(dirname "$0")/netns.sh"
cleanup() {
    netns_teardown 2>/dev/null
    if [ "${PF_FANOUT_KEEP:-0}" = 1 ]; then echo "logs kept in $T"; else rm -rf "$T"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM
# shellcheck source=tests/integration/lib.sh
. "$(dirname "$0")/lib.sh"
fanout_finish() {
    finish
    exit $?
}
# within SENT SIZE: SIZE <= SENT <= 2 x SIZE (and both known).
within() { [ -n "$1" ] && [ -n "$2" ] && [ "$1" -ge "$2" ] && [ "$1" -le $((2 * $2)) ]; }

if ! netns_setup "$NET" "$NS_BR" "${PAIRS[@]}" 2>"$T/net.err"; then
    skip_all "cannot build the namespace network here ($(tail -n 1 "$T/net.err"))"
fi
if ! netns_tbf "$NS_C" eth0 "$COORD_MBIT" 2>"$T/tc.err" || ! netns_tbf "$NS_BR" to-c "$COORD_MBIT" 2>>"$T/tc.err"; then
    skip_all "this kernel refuses the tbf qdisc ($(tail -n 1 "$T/tc.err"))"
fi
for k in $(seq 1 "$NW"); do
    netns_tbf "$TAG-w$k" eth0 "$WORKER_MBIT" 2>>"$T/tc.err" && netns_tbf "$NS_BR" "to-w$k" "$WORKER_MBIT" 2>>"$T/tc.err" ||
        skip_all "this kernel refuses the tbf qdisc ($(tail -n 1 "$T/tc.err"))"
done

# The in-process reference.
if ! timeout 120 "$PF" render "$SCENE" -o "$T/ref.png" --hdr "$T/ref.pfm" "${RENDER[@]}" --workers 0 -q 2>"$T/ref.err"; then
    bad "the in-process reference render"
    show "$T/ref.err"
    fanout_finish
fi

# start_workers RUN: six fresh workers, one a namespace; pids in WPIDS.
start_workers() {
    WPIDS=()
    for k in $(seq 1 "$NW"); do
        ip netns exec "$TAG-w$k" timeout 120 "$PFW" --connect "$EP" --threads 1 --name "w$k" --exit-on-bye -v \
            >"$T/$1-w$k.out" 2>"$T/$1-w$k.err" &
        WPIDS+=($!)
    done
}
stop_workers() {
    local p end=$((SECONDS + 5))
    for p in "${WPIDS[@]}"; do
        while kill -0 "$p" 2>/dev/null && [ "$SECONDS" -lt "$end" ]; do sleep 0.1; done
        kill -9 "$p" 2>/dev/null
        wait "$p" 2>/dev/null
    done
}
# figures LOG: "SENT SIZE PEERS BACK" from the coordinator's summary line.
figures() {
    sed -nE 's/.*maps ([0-9]+) bytes sent for ([0-9]+) bytes of maps.*fan-out: ([0-9]+) workers? fetched the maps from a peer, ([0-9]+) sent back.*/\1 \2 \3 \4/p' "$1" | tail -n 1
}

# scene_figures LOG: "SENT SIZE PEERS" of the scene blob from the same line.
scene_figures() {
    sed -nE 's/.*, scene ([0-9]+) for ([0-9]+) .* ([0-9]+) scene plans named a peer.*/\1 \2 \3/p' "$1" | tail -n 1
}

# ---- A: six workers, the coordinator's bytes per map ------------------------------
start_workers a
# The hostile peer, from w1's host, at w6's peer port (once w6 has bound it).
ipid=""
end=$((SECONDS + 10))
pport=""
while [ -z "$pport" ] && [ "$SECONDS" -lt "$end" ]; do
    pport=$(sed -nE 's/.*serving blob chunks to other workers at tcp:\/\/[^:]*:([0-9]+).*/\1/p' "$T/a-w6.err" | head -n 1)
    [ -z "$pport" ] && sleep 0.05
done
if [ -n "$pport" ] && [ -x "$INJ" ]; then
    (ip netns exec "$TAG-w1" timeout 60 "$INJ" "tcp://$NET.7:$pport" garbage 7 &&
        ip netns exec "$TAG-w1" timeout 60 "$INJ" "tcp://$NET.7:$pport" truncated) >"$T/inject.out" 2>&1 &
    ipid=$!
fi
t0=$SECONDS
ip netns exec "$NS_C" timeout 120 "$PF" render "$SCENE" -o "$T/a.png" --hdr "$T/a.pfm" "${RENDER[@]}" "${FARM[@]}" \
    --bind "$EP" --workers 0 --min-workers "$NW" -v >"$T/a.out" 2>"$T/a.err"
rc=$?
wait "$ipid" 2>/dev/null
stop_workers
read -r sent size peers back <<<"$(figures "$T/a.err")"
note "A: $NW workers, coordinator link $COORD_MBIT Mbit/s: the coordinator sent ${sent:-?} bytes of maps for a" \
    "${size:-?}-byte map blob ($(awk -v s="${sent:-0}" -v m="${size:-1}" 'BEGIN { printf "%.2f", s / m }') x);" \
    "${peers:-?} workers fetched from a peer; $((SECONDS - t0)) s"
check "A: the farm render succeeds" [ "$rc" -eq 0 ]
check "A: the map blob is more than 4 chunks (${size:-?} bytes)" [ "${size:-0}" -gt $((4 * 1048576)) ]
check "A: the coordinator sent <= 2 x the map size (${sent:-?} for ${size:-?})" \
    within "${sent:-}" "${size:-}"
check "A: at least 4 of the $NW workers fetched the maps from a peer (${peers:-?})" [ "${peers:-0}" -ge 4 ]
read -r ssent ssize speers <<<"$(scene_figures "$T/a.err")"
check "A: the coordinator sent <= 2 x the scene size (${ssent:-?} for ${ssize:-?})" within "${ssent:-}" "${ssize:-}"
check "A: at least 4 of the $NW workers were sent to a peer for the scene (${speers:-?})" [ "${speers:-0}" -ge 4 ]
check "A: a worker took scene chunks from a peer" grep -qE "fetching blob [0-9a-f]+ from peer" "$T"/a-w*.err
check "A: no chunk from a peer failed its hash" bash -c "! grep -h 'does not match its chunk hash' $T/a-w*.err"
check "A: the image is bit-identical to the in-process render" cmp -s "$T/a.pfm" "$T/ref.pfm"
if [ -n "$ipid" ]; then
    check "A: w6 dropped and struck the hostile peer's frames" grep -q "dropped a message from a peer" "$T/a-w6.err"
else
    skip "A: the hostile peer (no peer port seen in w6's log, or no pf_inject)"
fi
[ "$rc" -eq 0 ] || show "$T/a.err"

# ---- B: the serving worker killed as the maps go out -------------------------------
# A slower coordinator link (the maps take seconds), so the kill lands mid-transfer.
ip netns exec "$NS_C" tc qdisc change dev eth0 root tbf rate 16mbit burst 32768 latency 400ms 2>/dev/null
ip netns exec "$NS_BR" tc qdisc change dev to-c root tbf rate 16mbit burst 32768 latency 400ms 2>/dev/null
start_workers b
t0=$SECONDS
# Heartbeats of 1 s here: at 16 Mbit/s, workers falling back together get a
# 1 MiB chunk each every few seconds, and with 250 ms they would give the
# coordinator up for silent (5 intervals) between two chunks.
ip netns exec "$NS_C" timeout 120 "$PF" render "$SCENE" -o "$T/b.png" --hdr "$T/b.pfm" "${RENDER[@]}" "${FARM[@]}" \
    --heartbeat-ms 1000 --bind "$EP" --workers 0 --min-workers 5 -v >"$T/b.out" 2>"$T/b.err" &
cpid=$!
# The first "fetches the maps from worker wK" line names a serving worker.
victim=""
end=$((SECONDS + 60))
while [ -z "$victim" ] && [ "$SECONDS" -lt "$end" ] && kill -0 "$cpid" 2>/dev/null; do
    victim=$(sed -nE 's/.*fetches the maps from worker (w[0-9]+) .*/\1/p' "$T/b.err" | head -n 1)
    [ -z "$victim" ] && sleep 0.05
done
if [ -n "$victim" ]; then
    sleep 0.3
    # WPIDS holds timeout's pid (ip netns exec execs it): the worker is its child.
    tpid=${WPIDS[$((${victim#w} - 1))]}
    # shellcheck disable=SC2046
    kill -9 $(pgrep -P "$tpid") "$tpid" 2>/dev/null
    note "B: killed $victim, a serving worker, $((SECONDS - t0)) s in"
fi
wait "$cpid"
rc=$?
stop_workers
read -r sent size peers back <<<"$(figures "$T/b.err")"
falls=$(grep -l "from the coordinator" "$T"/b-w*.err 2>/dev/null | wc -l)
note "B: the coordinator sent ${sent:-?} bytes of maps for ${size:-?} ($(awk -v s="${sent:-0}" -v m="${size:-1}" \
    'BEGIN { printf "%.2f", s / m }') x); $falls workers fetched the rest from the coordinator; $((SECONDS - t0)) s"
check "B: a serving worker was found and killed" [ -n "$victim" ]
check "B: the render completes without the killed worker" [ "$rc" -eq 0 ]
check "B: its children fell back to the coordinator ($falls)" [ "$falls" -ge 1 ]
check "B: the image is bit-identical to the in-process render" cmp -s "$T/b.pfm" "$T/ref.pfm"
[ "$rc" -eq 0 ] || show "$T/b.err"

fanout_finish
