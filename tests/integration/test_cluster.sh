#!/usr/bin/env bash
# test_cluster.sh: the render farm across "hosts" on one machine. The
# coordinator and two workers run in three network namespaces, each with its
# own address on a private test subnet, joined by veth pairs to a bridge in a
# fourth namespace; CURVE is on. Nothing here touches the host's own network:
# the four namespaces have no route out, and every packet stays on the bridge.
#
# usage: tests/integration/test_cluster.sh [photonfarm [photonfarm-worker]]
#        (defaults: build/bin/photonfarm, build/bin/photonfarm-worker)
#        PF_CLUSTER_KEEP=1 keeps the temporary directory (logs, images, keys).
#
# Needs root and `ip netns` (iproute2) with veth and bridge support; where
# either is missing it prints why, "0 passed, 0 failed, 1 skipped", and exits
# 77 (ctest shows the test as skipped). tc (also iproute2) with the tbf qdisc
# is needed for the last part only, which is skipped alone without it.
#
#  A. cornell-spheres, 128x128, CURVE on, two workers: bit-identical (cmp) to
#     the in-process render (--workers 0 without --bind); the traffic really
#     went over the veths (interface counters);
#  B. a longer render; mid-render, the bridge port of worker w2 goes down
#     (`ip link set ... down`, a pulled cable): the coordinator declares w2
#     dead within its timeout (4 heartbeats of 250 ms), re-issues its tiles,
#     and the image is still bit-identical; the time from link down to the
#     verdict and the tiles re-issued are measured and printed;
#  C. the link comes back: w2 reconnects by itself and serves the next job
#     (its tiles > 0 in that job's summary), bit-identical again;
#  D. w2 restarted (empty blob cache) behind a token-bucket link (tc tbf,
#     16 Mbit/s both ways): the photon maps take seconds to reach it, the
#     render completes bit-identical, and the summary shows w2's share.
#
# Every wait is bounded (`timeout`, poll loops with deadlines); an EXIT trap
# kills every process in the namespaces and deletes the namespaces, which
# takes their veths and the bridge with them, on success, failure or Ctrl-C.
# About 40 s on two cores.
set -u

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PF=${1:-$ROOT/build/bin/photonfarm}
PFW=${2:-$ROOT/build/bin/photonfarm-worker}
abs() { case $1 in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
PF=$(abs "$PF")
PFW=$(abs "$PFW")
cd "$ROOT" || exit 1

skip_all() {
    echo "SKIP: $*"
    echo "0 passed, 0 failed, 1 skipped"
    exit 77
}

for exe in "$PF" "$PFW"; do
    if [ ! -x "$exe" ]; then
        echo "test_cluster.sh: $exe is not an executable" >&2
        echo "0 passed, 1 failed"
        exit 1
    fi
done
if [ "$(id -u)" -ne 0 ]; then
    skip_all "the cluster test needs root (network namespaces, veth pairs, a bridge); run it as root"
fi
if ! command -v ip >/dev/null 2>&1; then
    skip_all "the cluster test needs 'ip' with netns support (Debian package iproute2)"
fi

# ---- names, addresses, settings --------------------------------------------

# Namespace names carry the pid, so two runs never share one, and the trap
# deletes exactly these.
TAG=pfcl$$
NS_BR=$TAG-br
NS_C=$TAG-c
NS_W1=$TAG-w1
NS_W2=$TAG-w2
NAMESPACES=("$NS_BR" "$NS_C" "$NS_W1" "$NS_W2")
# A private subnet that exists only inside these namespaces.
NET=10.77.0
ADDR_C=$NET.1
PORT=7878
EP=tcp://$ADDR_C:$PORT
# Bridge-side ends of the veth pairs, in $NS_BR; the host-side end is eth0
# in each host namespace.
PORT_C=to-c
PORT_W1=to-w1
PORT_W2=to-w2

HB_MS=250
DEAD_AFTER=4 # heartbeat intervals of silence (coordinator/farm.c's dead_after)
TBF_RATE_MBIT=16

SPHERES=scenes/cornell-spheres/scene.json
# (SMALL and BIG are used through namerefs, which shellcheck cannot follow.)
# shellcheck disable=SC2034
SMALL=(--size 128x128 --spp 4 --photons 50000 --caustic-photons 50000 --gather 8)
# Several seconds on two one-thread workers, so that a link can go down
# while tiles are in flight.
# shellcheck disable=SC2034
BIG=(--size 192x192 --spp 16 --photons 50000 --caustic-photons 50000 --gather 8)
FARM=(--tile 16 --heartbeat-ms "$HB_MS")

T=$(mktemp -d "${TMPDIR:-/tmp}/pf_cluster.XXXXXX") || exit 1
T0=$SECONDS

# ---- clean-up ------------------------------------------------------------------

# shellcheck source=tests/integration/netns.sh
. "$(dirname "$0")/netns.sh"
teardown() { netns_teardown; }
cleanup() {
    # (stderr off: bash reports each killed background job)
    teardown 2>/dev/null
    if [ "${PF_CLUSTER_KEEP:-0}" = 1 ]; then
        echo "logs, images and keys kept in $T"
    else
        rm -rf "$T"
    fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# ---- reporting -------------------------------------------------------------------

# shellcheck source=tests/integration/lib.sh
. "$(dirname "$0")/lib.sh"

# ---- small helpers ---------------------------------------------------------------

gt() { [ "$1" -gt "$2" ]; }
ge() { [ "$1" -ge "$2" ]; }
eq() { [ "$1" = "$2" ]; }
has() { grep -qE -- "$2" "$1" 2>/dev/null; }
# fle A B: A <= B for decimal numbers.
fle() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a <= b) }'; }
fsub() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", a - b }'; }
now() { date +%s.%N; }

# lines FILE: its current line count (0 when absent), to look only at what a
# long-lived worker logs after that point.
lines() {
    local n
    n=$(wc -l <"$1" 2>/dev/null) || n=0
    echo "${n:-0}"
}
# after FILE N: the lines of FILE after the first N.
after() { tail -n "+$(($2 + 1))" "$1" 2>/dev/null; }

# wait_log FILE FROM REGEX SECONDS: waits (bounded) until FILE has, after its
# first FROM lines, a line matching REGEX.
wait_log() {
    local end=$((SECONDS + $4))
    while [ "$SECONDS" -lt "$end" ]; do
        after "$1" "$2" | grep -qE "$3" && return 0
        sleep 0.05
    done
    after "$1" "$2" | grep -qE "$3"
}

# stamp LINE: the log line's timestamp (ISO 8601 UTC, milliseconds; the
# log has one whenever stderr is not a terminal) in seconds since the epoch.
stamp() {
    local ts=${1%% *}
    date -u -d "$ts" +%s.%N 2>/dev/null
}

# summary_num FILE WORDS: the number before WORDS in the summary, or -1.
summary_num() {
    local v
    v=$(grep -E 'summary' "$1" 2>/dev/null | grep -oE "[0-9]+ $2" | tail -n 1 | grep -oE '^[0-9]+')
    echo "${v:--1}"
}
# total_tiles FILE: the tiles in the summary's count line, or -1.
total_tiles() {
    local v
    v=$(grep -oE 'summary: [0-9]+ tiles' "$1" 2>/dev/null | tail -n 1 | grep -oE '[0-9]+')
    echo "${v:--1}"
}
# tiles_of FILE NAME: tiles the summary says worker NAME rendered (0 if absent).
tiles_of() {
    local v
    v=$(grep -E "summary: worker $2 rendered [0-9]+ tiles" "$1" 2>/dev/null | grep -oE 'rendered [0-9]+' |
        tail -n 1 | grep -oE '[0-9]+')
    echo "${v:-0}"
}
summary_note() {
    note "$1: $(grep -E 'summary: [0-9]+ tiles' "$2" | sed 's/.*summary: //')"
    note "$1: $(grep -E 'summary: worker' "$2" | sed 's/.*summary: //' | tr '\n' ';')"
}

# same IMAGE REFERENCE: bit-identical PFMs.
same() {
    if [ ! -s "$1" ]; then
        note "$1 was not written"
        return 1
    fi
    cmp -s "$1" "$2" && return 0
    note "$(basename "$1") differs from $(basename "$2"): $(timeout 30 "$PF" compare "$1" "$2" 2>&1 | tr '\n' ' ')"
    return 1
}

# ---- the network ---------------------------------------------------------------------

# setup_net: four namespaces, three veth pairs, one bridge (netns.sh).
setup_net() {
    netns_setup "$NET" "$NS_BR" "$NS_C:$PORT_C" "$NS_W1:$PORT_W1" "$NS_W2:$PORT_W2"
}

# ---- processes -----------------------------------------------------------------------

# coordinator NAME SETTINGS_VAR [options...]: a cluster coordinator in $NS_C,
# bound to $EP with CURVE, writing $T/NAME.pfm; bounded by timeout(1). Its
# pid (that of timeout) is left in $LASTPID.
LASTPID=0
coordinator() {
    local name=$1
    local -n set_ref=$2
    shift 2
    ip netns exec "$NS_C" timeout 120 "$PF" render "$SPHERES" -o "$T/$name.png" --hdr "$T/$name.pfm" \
        "${set_ref[@]}" "${FARM[@]}" --threads 1 --bind "$EP" --workers 0 --max-wait 60 \
        --curve-secret "$T/keys/coordinator.key" --curve-allow "$T/keys/allowed-workers" "$@" \
        >"$T/$name.out" 2>"$T/$name.err" &
    LASTPID=$!
}

# worker NAME NS: a long-lived one-thread worker in namespace NS, logging to
# $T/NAME.err (appended: a restarted worker continues the same log).
worker() {
    ip netns exec "$2" "$PFW" --connect "$EP" --threads 1 --name "$1" \
        --curve-key "$T/keys/$1.key" --curve-server-key "$T/keys/coordinator.pub" \
        >>"$T/$1.out" 2>>"$T/$1.err" &
    LASTPID=$!
}

# wait_coord PID SECONDS: waits for a coordinator (bounded; timeout(1) inside
# bounds it too) and leaves its exit code in $rc.
rc=0
wait_coord() {
    local end=$((SECONDS + $2))
    while kill -0 "$1" 2>/dev/null && [ "$SECONDS" -lt "$end" ]; do
        sleep 0.1
    done
    if kill -0 "$1" 2>/dev/null; then
        kill -9 "$1" 2>/dev/null
        wait "$1" 2>/dev/null
        rc=124
        return 1
    fi
    wait "$1" 2>/dev/null
    rc=$?
}

completed() {
    if [ "$rc" = 0 ]; then
        ok "$1 (exit 0)"
        return 0
    fi
    bad "$1 (exit $rc; the checks that need its output are skipped)"
    show "$2" 10
    return 1
}

# ---- set-up ----------------------------------------------------------------------------

if ! setup_net 2>"$T/net.err"; then
    why=$(tail -n 1 "$T/net.err")
    teardown
    skip_all "cannot build the test network here (${why:-ip failed}): network namespaces, veth and bridge are needed"
fi
ok "four namespaces, three veth pairs and a bridge set up ($NET.0/24, no route out)"

mkdir -p "$T/keys"
for k in coordinator w1 w2; do
    (cd "$T/keys" && "$PF" keygen "$k" >/dev/null) || bad "photonfarm keygen $k"
done
cat "$T/keys/w1.pub" "$T/keys/w2.pub" >"$T/keys/allowed-workers"

echo "# references: in-process renders (--workers 0, no --bind)"
refs_ok=1
for r in small:SMALL big:BIG; do
    rname=${r%%:*}
    declare -n rs=${r#*:}
    if ! timeout 120 "$PF" render "$SPHERES" -o "$T/ref_$rname.png" --hdr "$T/ref_$rname.pfm" "${rs[@]}" \
        --threads 2 --workers 0 >"$T/ref_$rname.out" 2>"$T/ref_$rname.err"; then
        bad "in-process reference $rname renders"
        show "$T/ref_$rname.err"
        refs_ok=0
    fi
    unset -n rs
done
[ "$refs_ok" = 1 ] && ok "in-process references rendered"

# ---- A. CURVE across namespaces -----------------------------------------------------

part_a() {
    echo "# A. coordinator in $NS_C, workers in $NS_W1 and $NS_W2, CURVE on"
    local coord rx0 rx1
    rx0=$(netns_rx_bytes "$NS_W1")
    coordinator a SMALL --min-workers 2
    coord=$LASTPID
    worker w1 "$NS_W1"
    worker w2 "$NS_W2"
    W2=$LASTPID
    wait_coord "$coord" 90
    completed "A: the render across namespaces completes" "$T/a.err" || return 1
    check "A: CURVE is on, both worker keys allowed" has "$T/a.err" 'CURVE on: 2 worker keys allowed'
    check "A: the image is bit-identical to the in-process render" same "$T/a.pfm" "$T/ref_small.pfm"
    check "A: w1 rendered tiles ($(tiles_of "$T/a.err" w1))" gt "$(tiles_of "$T/a.err" w1)" 0
    check "A: w2 rendered tiles ($(tiles_of "$T/a.err" w2))" gt "$(tiles_of "$T/a.err" w2)" 0
    rx1=$(netns_rx_bytes "$NS_W1")
    # The photon-map blob alone is about 4 MB: it must have crossed w1's veth.
    check "A: w1's link carried the scene and the maps ($(((rx1 - rx0) / 1000)) kB received on eth0)" \
        gt $((rx1 - rx0)) 3000000
    summary_note A "$T/a.err"
}

# ---- B. a link goes down mid-render -----------------------------------------------------

DETECT=""
REISSUED=""
part_b() {
    echo "# B. w2's link goes down mid-render"
    local coord from1 from2 t_down line t_dead deadline_hi deadline_lo n
    from1=$(lines "$T/w1.err")
    from2=$(lines "$T/w2.err")
    coordinator b BIG --min-workers 2
    coord=$LASTPID
    if ! wait_log "$T/w1.err" "$from1" 'ready' 60 || ! wait_log "$T/w2.err" "$from2" 'ready' 60; then
        bad "B: both workers got the job (logs below)"
        show "$T/w1.err" 5
        show "$T/w2.err" 5
        wait_coord "$coord" 60
        return 1
    fi
    sleep 1 # tiles in flight on both workers
    if ! kill -0 "$coord" 2>/dev/null; then
        bad "B: the render ended before the link could go down (make BIG longer)"
        return 1
    fi
    t_down=$(now)
    ip -n "$NS_BR" link set "$PORT_W2" down
    ok "B: w2's bridge port is down while the coordinator is rendering"
    if wait_log "$T/b.err" 0 'worker w2 is silent: declared dead' 20; then
        line=$(grep -E 'worker w2 is silent: declared dead' "$T/b.err" | head -n 1)
        t_dead=$(stamp "$line")
        DETECT=$(fsub "$t_dead" "$t_down")
        REISSUED=$(echo "$line" | grep -oE '[0-9]+ tiles? re-issued' | grep -oE '^[0-9]+')
        # Silence is counted from w2's last message, which came at most one
        # heartbeat before the link went down; the coordinator checks at
        # least every heartbeat. Allow 1 s for scheduling on a busy machine.
        deadline_lo=$(awk -v h="$HB_MS" -v k="$DEAD_AFTER" 'BEGIN { print (k - 1) * h / 1000 }')
        deadline_hi=$(awk -v h="$HB_MS" -v k="$DEAD_AFTER" 'BEGIN { print k * h / 1000 + 1.0 }')
        check "B: w2 declared dead ${DETECT} s after its link went down (timeout $DEAD_AFTER x $HB_MS ms)" \
            fle "$deadline_lo" "$DETECT"
        check "B: ... within ${deadline_hi} s" fle "$DETECT" "$deadline_hi"
        check "B: w2's tiles were re-issued (${REISSUED:-?} at the verdict)" gt "${REISSUED:-0}" 0
    else
        bad "B: the coordinator declares w2 dead within 20 s of its link going down"
        show "$T/b.err" 8
    fi
    # The cable goes back in at once; w2 notices the coordinator's silence by
    # itself (5 of its heartbeats), drops the job and reconnects with backoff.
    T_UP=$(now)
    W2_FROM_UP=$(lines "$T/w2.err")
    ip -n "$NS_BR" link set "$PORT_W2" up
    wait_coord "$coord" 90
    completed "B: the render completes after the link loss" "$T/b.err" || return 1
    check "B: the image is bit-identical to the in-process render" same "$T/b.pfm" "$T/ref_big.pfm"
    n=$(summary_num "$T/b.err" re-issued)
    check "B: the summary counts re-issued tiles ($n)" ge "$n" "${REISSUED:-1}"
    n=$(summary_num "$T/b.err" lost)
    check "B: the summary counts w2 lost ($n lost)" ge "$n" 1
    # Heartbeats w2 queued on its abandoned connection must not revive it:
    # one lost link counts one worker lost (a fixed bug; it showed in about
    # half the runs, when the link came back while the job still ran).
    check "B: one lost link counts one worker lost ($n lost)" eq "$n" 1
    summary_note B "$T/b.err"
}

# ---- C. the link is back: w2 serves the next job ---------------------------------------

RECONNECT=""
part_c() {
    echo "# C. the link is back: w2 reconnects and serves the next job"
    local coord line t_reg n1 n2
    coordinator c SMALL --min-workers 2
    coord=$LASTPID
    # Bounded by the worker's backoff (1, 2, 4 s ... with 5 s per attempt).
    if wait_log "$T/w2.err" "$W2_FROM_UP" 'registered with' 60; then
        line=$(after "$T/w2.err" "$W2_FROM_UP" | grep -E 'registered with' | head -n 1)
        t_reg=$(stamp "$line")
        RECONNECT=$(fsub "$t_reg" "$T_UP")
        ok "C: w2 registered again ${RECONNECT} s after its link came back"
    else
        bad "C: w2 registers again within 60 s of its link coming back"
        show "$T/w2.err" 8
    fi
    wait_coord "$coord" 90
    completed "C: the next job completes" "$T/c.err" || return 1
    n2=$(tiles_of "$T/c.err" w2)
    n1=$(tiles_of "$T/c.err" w1)
    check "C: w2 rendered tiles in the next job ($n2; w1 $n1)" gt "$n2" 0
    check "C: the image is bit-identical to the in-process render" same "$T/c.pfm" "$T/ref_small.pfm"
    summary_note C "$T/c.err"
}

# ---- D. a slow link ------------------------------------------------------------------------

TRANSFER=""
part_d() {
    echo "# D. w2 behind a ${TBF_RATE_MBIT} Mbit/s token bucket (tc tbf)"
    if ! command -v tc >/dev/null 2>&1; then
        skip "D: tc is not installed (Debian package iproute2): the bandwidth-limited link is not tested"
        return 0
    fi
    if ! netns_tbf "$NS_BR" "$PORT_W2" "$TBF_RATE_MBIT" 2>"$T/tc.err" ||
        ! netns_tbf "$NS_W2" eth0 "$TBF_RATE_MBIT" 2>>"$T/tc.err"; then
        skip "D: this kernel refuses the tbf qdisc ($(tail -n 1 "$T/tc.err")): the bandwidth-limited link is not tested"
        return 0
    fi
    check "D: the tbf qdisc is on w2's bridge port" has <(ip netns exec "$NS_BR" tc qdisc show dev "$PORT_W2") 'tbf'
    # A fresh w2 has no cached blobs, so the maps cross the slow link.
    kill -TERM "$W2" 2>/dev/null
    wait_coord "$W2" 10
    local from2 coord n1 n2 t_fetch t_built blob min_s
    from2=$(lines "$T/w2.err")
    worker w2 "$NS_W2"
    W2=$LASTPID
    coordinator d SMALL --min-workers 2
    coord=$LASTPID
    wait_coord "$coord" 120
    completed "D: the render completes with w2 behind the slow link" "$T/d.err" || return 1
    check "D: the image is bit-identical to the in-process render" same "$T/d.pfm" "$T/ref_small.pfm"
    n1=$(tiles_of "$T/d.err" w1)
    n2=$(tiles_of "$T/d.err" w2)
    check "D: the summary shows w2's share (w2 $n2 tiles, w1 $n1 tiles)" has "$T/d.err" 'summary: worker w2 rendered'
    check "D: the shares add up to the tiles ($n1 + $n2 = $(total_tiles "$T/d.err"))" \
        eq $((n1 + n2)) "$(total_tiles "$T/d.err")"
    # The transfer took at least 80 % of blob bytes / rate: the link was
    # really limited (unshaped, it takes about 50 ms).
    blob=$(grep -oE 'map blob [0-9]+ bytes' "$T/d.err" | grep -oE '[0-9]+' | head -n 1)
    t_fetch=$(stamp "$(after "$T/w2.err" "$from2" | grep -E 'fetching the maps blob' | head -n 1)")
    t_built=$(stamp "$(after "$T/w2.err" "$from2" | grep -E 'building the scene and photon maps' | head -n 1)")
    if [ -n "$blob" ] && [ -n "$t_fetch" ] && [ -n "$t_built" ]; then
        TRANSFER=$(fsub "$t_built" "$t_fetch")
        min_s=$(awk -v b="$blob" -v r="$TBF_RATE_MBIT" 'BEGIN { printf "%.2f", 0.8 * b * 8 / (r * 1e6) }')
        check "D: the $((blob / 1000)) kB maps took ${TRANSFER} s to reach w2 (>= ${min_s} s at ${TBF_RATE_MBIT} Mbit/s)" \
            fle "$min_s" "$TRANSFER"
    else
        bad "D: w2's log shows the maps transfer (fetching ... building)"
        show "$T/w2.err" 6
    fi
    summary_note D "$T/d.err"
}

W2=0
W2_FROM_UP=0
T_UP=0
if [ "$refs_ok" = 1 ]; then
    if part_a; then
        part_b && part_c
        part_d
    fi
fi

echo "# measured"
note "time to detect the dead link: ${DETECT:-n/a} s (heartbeat $HB_MS ms, dead after $DEAD_AFTER)"
note "tiles re-issued at the verdict: ${REISSUED:-n/a}; in job B's summary: $(summary_num "$T/b.err" re-issued)"
note "w2 registered again after its link came back: ${RECONNECT:-n/a} s"
note "maps transfer to w2 over the ${TBF_RATE_MBIT} Mbit/s link: ${TRANSFER:-n/a} s"
note "whole test: $((SECONDS - T0)) s"

teardown 2>/dev/null
left=""
for ns in "${NAMESPACES[@]}"; do
    ns_exists "$ns" && left="$left $ns"
done
check "every namespace (and with it every veth and the bridge) is gone${left:+:$left}" eq "$left" ""

finish
