#!/usr/bin/env bash
# test_hostile.sh: the coordinator against admitted but hostile workers
# (tests/integration/pf_hostile.c), with real coordinator and worker
# processes over loopback TCP. In each test an honest worker must finish the
# job, and the image must be bit-identical (cmp) to the in-process render
# (--workers 0) of the same settings.
#
# usage: tests/integration/test_hostile.sh [photonfarm [photonfarm-worker [pf_hostile]]]
#        (defaults: build/bin/...). PF_FARM_KEEP=1 keeps the temporary
#        directory; PF_HOSTILE_ONLY="a c" runs only those tests.
#
#  a. BLOB_REQ flood: a worker asks 5,000 times for the whole 30 MB map blob
#     (offset 0, credit 64) and never reads. The coordinator's peak RSS
#     (VmHWM) may exceed that of the same job without the flood (measured
#     here first) by at most 48 MiB: the transfer window lets 8 chunks of
#     1 MiB per worker into libzmq, for two workers 16 MiB even if they were
#     copies (they are not: chunks point into the framed blob), plus 32 MiB
#     for allocator and libzmq noise. Before the window, each request queued
#     30 copies of 1 MiB: 40 requests took the RSS from ~100 MB to 1.4 GB.
#  b. tile hoarding: a worker that announces 64 threads and READY with
#     credit 1024 joins first and answers no TILE while it heartbeats a
#     rising progress counter; an honest worker then finishes the 16-tile job
#     within 40 s (the lease timeout it used to wait for is 120 s), and the
#     hoarder got at most 2 tiles.
#  c. registry churn: 1,100 cycles of connect, HELLO, close (the registry has
#     1,024 slots); an honest worker then gets the job and finishes it.
#  d. forged RESULT in a reused slot: a worker leases a tile and vanishes;
#     a new connection lands in its slot and returns a RESULT for that
#     lease; it is refused (logged as a strike), and the image is intact.
#  e. a liar: a worker that speaks the protocol honestly but makes up the
#     pixels of every tile (it renders nothing), beside one honest local
#     worker (--workers 1, --min-workers 2). A result is checked on the other
#     worker (--verify), the mismatch decided by a render in the
#     coordinator; the liar is evicted, all its tiles are rendered again, the
#     summary says so, and the image is bit-identical to in-process.
#  f. a HELLO name and a BYE reason with a newline and a terminal escape
#     sequence reach the coordinator's log escaped, never raw.
#  g. a photon liar: a worker that answers every PHOTON_REQ with batches
#     that stored no photon (well-formed, inside the plan's bounds), beside
#     an honest local worker, over two progressive passes. The coordinator's
#     spot check (at least one batch of each worker a pass, re-traced here)
#     catches it: a strike naming the batch, every batch it returned is
#     traced again, and the image is bit-identical to in-process. Without
#     the checks the maps lose those batches' photons and the image differs.
#
# Every wait is bounded and every process this script starts is killed on
# exit. The heartbeat is 200 ms (a silent worker is dead after 0.8 s). The
# script takes about a minute and a half on two cores.
set -u

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PF=${1:-$ROOT/build/bin/photonfarm}
PFW=${2:-$ROOT/build/bin/photonfarm-worker}
HOS=${3:-$ROOT/build/bin/pf_hostile}
abs() { case $1 in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
PF=$(abs "$PF")
PFW=$(abs "$PFW")
HOS=$(abs "$HOS")
for exe in "$PF" "$PFW" "$HOS"; do
    if [ ! -x "$exe" ]; then
        echo "test_hostile.sh: $exe is not an executable" >&2
        echo "0 passed, 1 failed"
        exit 1
    fi
done

T=$(mktemp -d "${TMPDIR:-/tmp}/pf_hostile.XXXXXX") || exit 1
cd "$ROOT" || exit 1

PIDS=()
cleanup() {
    local p
    for p in "${PIDS[@]}"; do
        kill -9 "$p" 2>/dev/null
    done
    wait 2>/dev/null
    if [ "${PF_FARM_KEEP:-0}" = 1 ]; then
        echo "logs and images kept in $T"
    else
        rm -rf "$T"
    fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# shellcheck source=tests/integration/lib.sh
. "$(dirname "$0")/lib.sh"

# ---- processes: start, wait_exit, wait_log, stop (procs.sh) -------------------

# shellcheck source=tests/integration/procs.sh
. "$(dirname "$0")/procs.sh"

free_port() {
    python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

# rss_watch PID FILE: writes the VmHWM (kB) of PID into FILE every 0.1 s
# until it exits (run in the background; the last value is the peak).
rss_watch() {
    local v
    while kill -0 "$1" 2>/dev/null; do
        v=$(awk '/^VmHWM:/ { print $2 }' "/proc/$1/status" 2>/dev/null)
        [ -n "$v" ] && echo "$v" >"$2"
        sleep 0.1
    done
}
peak_kb() { cat "$1" 2>/dev/null || echo 0; }

# ---- images and logs ---------------------------------------------------------

same() {
    if [ ! -s "$1" ]; then
        note "$1 was not written"
        return 1
    fi
    if cmp -s "$1" "$2"; then
        return 0
    fi
    note "$(basename "$1") differs from $(basename "$2"): $(timeout 30 "$PF" compare "$1" "$2" 2>&1 | tr '\n' ' ')"
    return 1
}

# num FILE WORDS: the number in front of WORDS in the summary lines, or -1.
num() {
    local v
    v=$(grep -E 'summary' "$1" 2>/dev/null | grep -oE "[0-9]+ $2" | tail -n 1 | grep -oE '^[0-9]+')
    echo "${v:--1}"
}
tiles_of() {
    local v
    v=$(grep -E "summary: worker $2 rendered [0-9]+ tiles" "$1" 2>/dev/null | grep -oE 'rendered [0-9]+' | tail -n 1 |
        grep -oE '[0-9]+')
    echo "${v:-0}"
}
ge() { [ "$1" -ge "$2" ]; }
le() { [ "$1" -le "$2" ]; }
eq() { [ "$1" = "$2" ]; }
has() { grep -qE "$2" "$1" 2>/dev/null; }
hasnt() { ! grep -qE "$2" "$1" 2>/dev/null; }
hostile_note() { note "$1: $(grep -E 'summary: (hostile|[0-9]+ tiles)' "$2" | sed 's/.*summary: //' | tr '\n' ';')"; }

SPHERES=scenes/cornell-spheres/scene.json
# The settings are used through namerefs (coordinator, references).
# shellcheck disable=SC2034
# A 30 MB map blob: each flooded request names 30 chunks.
FLOOD=(--size 96x96 --spp 4 --photons 400000 --caustic-photons 50000 --gather 8 --tile 16)
# A grid of 16 tiles of 32 x 32, its last 4 leased in quarters: 28 tiles.
# shellcheck disable=SC2034
HOARD=(--size 128x128 --spp 16 --photons 50000 --caustic-photons 50000 --gather 8 --tile 32)
# shellcheck disable=SC2034
SMALL=(--size 96x96 --spp 4 --photons 50000 --caustic-photons 50000 --gather 8 --tile 16)
# shellcheck disable=SC2034
# 8 global batches of 65,536 photons; the photon liar connects first, so
# it is leased some of them.
PHOT=(--size 64x64 --spp 2 --photons 500000 --caustic-photons 50000 --gather 8 --tile 16 --passes 2)
# shellcheck disable=SC2034
BIG=(--size 192x192 --spp 25 --photons 50000 --caustic-photons 50000 --gather 8 --tile 16)

# coordinator NAME PORT SETTINGS_VAR [extra...]: a cluster coordinator on
# tcp://127.0.0.1:PORT writing $T/NAME.pfm; pid in $LASTPID.
coordinator() {
    local name=$1 port=$2 settings=$3
    shift 3
    local -n set_ref=$settings
    start "$name" "$PF" render "$SPHERES" -o "$T/$name.png" --hdr "$T/$name.pfm" "${set_ref[@]}" --heartbeat-ms 200 \
        --bind "tcp://127.0.0.1:$port" --workers 0 --max-wait 60 --min-workers 1 "$@"
}
worker() {
    local name=$1 port=$2
    shift 2
    start "$name" "$PFW" --connect "tcp://127.0.0.1:$port" --threads 1 --name "$name" --exit-on-bye "$@"
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

references() {
    echo "# references: in-process renders (--workers 0)"
    local r
    for r in FLOOD HOARD SMALL BIG PHOT; do
        local -n rs=$r
        if ! timeout 120 "$PF" render "$SPHERES" -o "$T/ref_$r.png" --hdr "$T/ref_$r.pfm" "${rs[@]}" --threads 2 \
            --workers 0 >"$T/ref_$r.out" 2>"$T/ref_$r.err"; then
            bad "in-process reference $r renders"
            show "$T/ref_$r.err"
            return 1
        fi
        unset -n rs
    done
    ok "in-process references rendered"
}

# ---- a. BLOB_REQ flood --------------------------------------------------------------

ta() {
    echo "# a. a BLOB_REQ flood from a worker that never reads"
    local port coord ww flood base peak budget
    port=$(free_port)
    coordinator flood_base "$port" FLOOD
    coord=$LASTPID
    rss_watch "$coord" "$T/flood_base.hwm" &
    PIDS+=("$!")
    worker flood_base_w "$port"
    ww=$LASTPID
    wait_exit "$coord" 120
    completed "a: the job without a flood renders" "$T/flood_base.err" || return
    base=$(peak_kb "$T/flood_base.hwm")
    stop "$ww"

    port=$(free_port)
    coordinator flood_coord "$port" FLOOD
    coord=$LASTPID
    rss_watch "$coord" "$T/flood_coord.hwm" &
    PIDS+=("$!")
    start flood "$HOS" "tcp://127.0.0.1:$port" blob-flood 5000 20
    flood=$LASTPID
    if ! wait_log "$T/flood.out" 'BLOB_REQ .* sent' 90; then
        bad "a: the flooding worker got the job and sent its requests"
        show "$T/flood.out"
        show "$T/flood_coord.err"
    else
        ok "a: $(sed 's/^pf_hostile //' "$T/flood.out")"
    fi
    sleep 1
    worker flood_w "$port"
    ww=$LASTPID
    wait_exit "$coord" 120
    if completed "a: an honest worker finishes the job under the flood" "$T/flood_coord.err"; then
        check "a: the image is bit-identical to in-process" same "$T/flood_coord.pfm" "$T/ref_FLOOD.pfm"
        check "a: the honest worker rendered every tile" eq "$(tiles_of "$T/flood_coord.err" flood_w)" \
            "$(num "$T/flood_coord.err" tiles,)"
        peak=$(peak_kb "$T/flood_coord.hwm")
        budget=$((base + 48 * 1024))
        check "a: peak RSS under the flood $((peak / 1024)) MiB <= $((base / 1024)) MiB without it + 48 MiB" \
            le "$peak" "$budget"
        check "a: the flooder's requests were ignored ($(num "$T/flood_coord.err" 'blob requests ignored'))" \
            ge "$(num "$T/flood_coord.err" 'blob requests ignored')" 1
        check "a: the flooder was evicted ($(num "$T/flood_coord.err" evicted) evicted)" \
            ge "$(num "$T/flood_coord.err" evicted)" 1
        check "a: the eviction is logged" has "$T/flood_coord.err" 'evicted worker hostile-flood'
        hostile_note a "$T/flood_coord.err"
    fi
    stop "$ww" "$flood"
}

# ---- b. tile hoarding ---------------------------------------------------------------

tb() {
    echo "# b. a tile hoarder joins first"
    local port coord ww hoard t0 took n
    port=$(free_port)
    coordinator hoard_coord "$port" HOARD
    coord=$LASTPID
    start hoard "$HOS" "tcp://127.0.0.1:$port" hoard 90
    hoard=$LASTPID
    if ! wait_log "$T/hoard_coord.err" 'worker hostile-hoard ready' 60; then
        bad "b: the hoarder registered and said READY"
        show "$T/hoard_coord.err"
        stop "$coord" "$hoard"
        return
    fi
    sleep 1
    t0=$SECONDS
    worker hoard_w "$port"
    ww=$LASTPID
    wait_exit "$coord" 100
    took=$((SECONDS - t0))
    if completed "b: an honest worker finishes the job the hoarder joined first" "$T/hoard_coord.err"; then
        check "b: ... within 40 s of joining (took $took s; the lease timeout is 120 s)" le "$took" 40
        check "b: the image is bit-identical to in-process" same "$T/hoard_coord.pfm" "$T/ref_HOARD.pfm"
        check "b: the hoarder rendered nothing" hasnt "$T/hoard_coord.err" 'summary: worker hostile-hoard'
        check "b: the honest worker rendered all the job's tiles ($(num "$T/hoard_coord.err" tiles,))" \
            eq "$(tiles_of "$T/hoard_coord.err" hoard_w)" "$(num "$T/hoard_coord.err" tiles,)"
        hostile_note b "$T/hoard_coord.err"
    fi
    wait_exit "$hoard" 10
    n=$(grep -oE '[0-9]+ TILEs taken' "$T/hoard.out" | grep -oE '^[0-9]+')
    note "b: $(sed 's/^pf_hostile //' "$T/hoard.out")"
    check "b: the hoarder was leased at most 2 tiles although it asked for 1024 (${n:-?})" le "${n:-99}" 2
    stop "$ww" "$hoard"
}

# ---- c. registry churn ----------------------------------------------------------------

tc() {
    echo "# c. 1,100 connect-HELLO-close cycles, then an honest worker"
    local port coord ww crc
    port=$(free_port)
    coordinator churn_coord "$port" SMALL --max-wait 120
    coord=$LASTPID
    wait_log "$T/churn_coord.err" 'listening on' 20
    timeout 180 "$HOS" "tcp://127.0.0.1:$port" churn 1100 >"$T/churn.out" 2>"$T/churn.err"
    crc=$?
    check "c: pf_hostile churn ran (exit $crc)" eq "$crc" 0 || show "$T/churn.err"
    note "c: $(sed 's/^pf_hostile //' "$T/churn.out")"
    check "c: the coordinator is alive after the churn" kill -0 "$coord"
    worker churn_w "$port"
    ww=$LASTPID
    wait_exit "$coord" 90
    if completed "c: an honest worker gets the job after the churn and finishes it" "$T/churn_coord.err"; then
        check "c: the image is bit-identical to in-process" same "$T/churn_coord.pfm" "$T/ref_SMALL.pfm"
        check "c: the honest worker rendered tiles" ge "$(tiles_of "$T/churn_coord.err" churn_w)" 1
        check "c: no worker was turned away for a full registry" hasnt "$T/churn_coord.err" 'too many workers'
        check "c: dead workers' slots were reused ($(num "$T/churn_coord.err" 'slots reused'))" \
            ge "$(num "$T/churn_coord.err" 'slots reused')" 1
        hostile_note c "$T/churn_coord.err"
    fi
    stop "$ww"
}

# ---- d. a forged RESULT in a reused slot -------------------------------------------------

td() {
    echo "# d. a RESULT forged into a reused slot"
    local port coord ww forge frc slots
    port=$(free_port)
    coordinator forge_coord "$port" BIG
    coord=$LASTPID
    start forge "$HOS" "tcp://127.0.0.1:$port" forge 2
    forge=$LASTPID
    # The honest worker joins only once the forger is done: joining earlier,
    # it could itself land in the forger's dead slot (on a slow host), and
    # the forger's second connection would then get a fresh one.
    wait_exit "$forge" 90
    frc=$rc
    worker forge_w "$port"
    ww=$LASTPID
    check "d: pf_hostile forge got a lease and sent its RESULT (exit $frc)" eq "$frc" 0 || show "$T/forge.out"
    note "d: $(sed 's/^pf_hostile //' "$T/forge.out")"
    wait_exit "$coord" 120
    if completed "d: the render completes" "$T/forge_coord.err"; then
        check "d: the image is bit-identical to in-process" same "$T/forge_coord.pfm" "$T/ref_BIG.pfm"
        slots=$(grep -oE 'worker hostile-forge joined \([^)]*\)' "$T/forge_coord.err" | grep -oE 'slot [0-9]+' |
            tr '\n' ' ')
        check "d: the second connection reused a slot" \
            grep -qE 'worker hostile-forge joined \([^)]*slot [0-9]+, reused\)' "$T/forge_coord.err"
        check "d: ... the first connection's (joined in: $slots)" \
            eq "$(echo "$slots" | awk '{ print (NF == 4 && $2 == $4) }')" 1
        local refused='hostile-forge \(id [0-9]+\): strike 1 of [0-9]+: RESULT for tile [0-9]+ attempt [0-9]+'
        check "d: the forged RESULT is refused and logged" \
            has "$T/forge_coord.err" "$refused, which was never leased to it"
        note "d: $(grep -oE 'strike 1 of .*' "$T/forge_coord.err" | head -n 1)"
        check "d: the summary counts it ($(num "$T/forge_coord.err" 'results refused') results refused)" \
            ge "$(num "$T/forge_coord.err" 'results refused')" 1
        hostile_note d "$T/forge_coord.err"
    fi
    stop "$ww" "$forge"
}

# ---- e. a liar ------------------------------------------------------------------------------

te() {
    echo "# e. a worker that returns made-up pixels, beside an honest local worker"
    local port coord liar
    port=$(free_port)
    coordinator liar_coord "$port" SMALL --workers 1 --threads 1 --min-workers 2 --verify 0.02
    coord=$LASTPID
    start liar "$HOS" "tcp://127.0.0.1:$port" liar 60
    liar=$LASTPID
    wait_exit "$coord" 120
    if completed "e: the render completes" "$T/liar_coord.err"; then
        check "e: the image is bit-identical to in-process" same "$T/liar_coord.pfm" "$T/ref_SMALL.pfm"
        check "e: the mismatch is logged" has "$T/liar_coord.err" 'verify: tile [0-9]+: .* returned different pixels'
        check "e: the liar is evicted" has "$T/liar_coord.err" 'evicted worker hostile-liar \(id [0-9]+\): returned wrong'
        check "e: the summary says so" has "$T/liar_coord.err" \
            'verify: [0-9]+ tiles? checked .*, [1-9][0-9]* mismatch(es)?, worker hostile-liar evicted, [0-9]+ tiles re-rendered'
        check "e: the liar keeps no tile" hasnt "$T/liar_coord.err" 'summary: worker hostile-liar rendered [1-9]'
        note "e: $(grep -oE 'verify: [0-9]+ tiles? checked.*' "$T/liar_coord.err" | tail -n 1)"
    fi
    wait_exit "$liar" 10
    note "e: $(sed 's/^pf_hostile //' "$T/liar.out")"
    stop "$liar"
}

# ---- f. a name and a reason with control characters ---------------------------------------

tf() {
    echo "# f. a HELLO name and a BYE reason with a newline and a terminal escape"
    local port coord ww evil
    port=$(free_port)
    coordinator evil_coord "$port" SMALL
    coord=$LASTPID
    start evil "$HOS" "tcp://127.0.0.1:$port" evil-name
    evil=$LASTPID
    wait_exit "$evil" 60
    check "f: pf_hostile evil-name got the job and said BYE (exit $rc)" eq "$rc" 0 || show "$T/evil.out"
    worker evil_w "$port"
    ww=$LASTPID
    wait_exit "$coord" 90
    if completed "f: the render completes" "$T/evil_coord.err"; then
        check "f: the name is logged escaped" has "$T/evil_coord.err" \
            'worker evil\\x0aname\\x1b\[31mred joined'
        check "f: the reason is logged escaped" has "$T/evil_coord.err" 'left: going\\x0anow\\x1b\[0m'
        check "f: no escape character reaches the log" hasnt "$T/evil_coord.err" $'\x1b'
        check "f: no line of the log starts with the name's second half" hasnt "$T/evil_coord.err" '^name'
        check "f: the image is bit-identical to in-process" same "$T/evil_coord.pfm" "$T/ref_SMALL.pfm"
        note "f: $(grep -oE 'worker evil.*joined' "$T/evil_coord.err" | head -n 1)"
    fi
    stop "$ww" "$evil"
}

# ---- g. a photon liar ----------------------------------------------------------------------

tg() {
    echo "# g. a worker that returns empty photon batches, beside an honest local worker"
    local port coord liar lies
    port=$(free_port)
    start phliar "$HOS" "tcp://127.0.0.1:$port" photon-liar 120
    liar=$LASTPID
    sleep 0.2
    coordinator phliar_coord "$port" PHOT --workers 1 --threads 1
    coord=$LASTPID
    wait_exit "$coord" 120
    if completed "g: the render completes" "$T/phliar_coord.err"; then
        check "g: the image is bit-identical to in-process" same "$T/phliar_coord.pfm" "$T/ref_PHOT.pfm"
        check "g: the lie is a strike that names the batch" has "$T/phliar_coord.err" \
            "hostile-photons \(id [0-9]+\): strike 1 of [0-9]+: photon batch [0-9]+ differs from the coordinator's trace"
        check "g: the pass's log line counts the mismatch" has "$T/phliar_coord.err" \
            'photon pass 1: .*worker batch(es)? checked here, 1 mismatch, [1-9][0-9]* discarded'
        check "g: the summary counts it" has "$T/phliar_coord.err" \
            'summary: photon spot checks: [0-9]+ worker batch(es)? traced again here, 1 mismatch'
        check "g: the liar keeps no photon batch" hasnt "$T/phliar_coord.err" \
            'summary: worker hostile-photons rendered [0-9]+ tiles, traced [1-9]'
        note "g: $(grep -oE 'photon pass 1: .*' "$T/phliar_coord.err" | tail -n 1)"
    fi
    wait_exit "$liar" 10
    lies=$(grep -oE '[0-9]+ empty batches' "$T/phliar.out" | grep -oE '^[0-9]+')
    check "g: the liar was leased batches and lied (${lies:-0} empty batches)" ge "${lies:-0}" 1
    note "g: $(sed 's/^pf_hostile //' "$T/phliar.out")"
    stop "$liar"
}

# ---- run --------------------------------------------------------------------------------

if references; then
    for n in ${PF_HOSTILE_ONLY:-a b c d e f g}; do
        "t$n"
    done
fi

for p in "${PIDS[@]}"; do
    kill -9 "$p" 2>/dev/null
done
wait 2>/dev/null
finish
