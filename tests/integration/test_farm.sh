#!/usr/bin/env bash
# test_farm.sh: integration and fault tests of the render farm, with real
# coordinator and worker processes over loopback TCP. Every image is compared
# bit for bit (cmp) with the in-process render (--workers 0) of the same
# settings, which the design promises for any number of workers and threads,
# whatever fails along the way.
#
# usage: tests/integration/test_farm.sh [photonfarm [photonfarm-worker [pf_inject]]]
#        (defaults: build/bin/photonfarm, build/bin/photonfarm-worker, build/bin/pf_inject)
#        PF_FARM_KEEP=1 keeps the temporary directory (logs, images) for a look;
#        PF_FARM_ONLY="2 5" runs only those tests (after the references).
#
#  1. local workers (--workers 2 --threads 1, --workers 1 --threads 2), both
#     Cornell scenes; no worker process left afterwards;
#  2. kill -9 one of two cluster workers mid-render, with --min-workers 1 and
#     with --min-workers 2 (the job must go on below K once it has started);
#  3. SIGSTOP one of two workers mid-render, SIGCONT it before the end (the
#     duplicates dropped are reported, not checked: the worker may abandon
#     its job after the pause rather than send late results);
#  4. a worker that joins mid-render gets tiles;
#  5. garbage, truncated, oversized, replayed and multi-frame messages from
#     tests/integration/pf_inject.c during a render; results forged for tiles never leased
#     to the sender (a known bug while the coordinator accepts them);
#  6. a worker with another protocol version (--fake-protocol 99) is refused
#     (it stays and retries, logging the refusal once; with --exit-on-bye it
#     exits 3);
#  7. CURVE: a listed key renders; an unlisted key and a plain worker never join;
#  8. SIGINT to a coordinator with local workers: exit 130, no process left;
#  9. --exit-on-bye workers leave at the end of the job; a long-lived worker
#     serves a second coordinator on the same port;
# 10. progressive passes (--passes 4): two cluster workers, one killed -9
#     in the second pass; the image is the in-process one's, bit for bit;
#     every pass's photons are spread (the log says how, pass by pass);
# 11. kill -9 of the coordinator, then --resume from its checkpoint: mid-way
#     through a one-pass render's tiles, and between progressive passes; the
#     images are the uninterrupted ones, bit for bit; a checkpoint of other
#     settings is refused (exit 3).
# 12. the photon pass spread over the workers (a tiny image, many photons):
#     two cluster workers trace photon batches, the image is the in-process
#     one's bit for bit and the log says the workers traced batches; then
#     one of them is killed -9 while it traces, and the image is still the
#     in-process one's; both times the workers compute irradiance chunks
#     too (the log's "irradiance spread" line).
#
# Every wait is bounded (poll loops with deadlines, `timeout`), every process
# the script starts is recorded and killed (kill -9) on exit, and workers carry
# an environment tag so that any photonfarm-worker left behind by this script,
# even one started by a coordinator, is found at the end. The renders are small
# (96x96, or 192x192 at 25 spp for the fault tests, so that a worker can be
# killed while tiles are in flight) and the heartbeat is 200 ms, so a silent
# worker is declared dead after 0.8 s. The whole script takes about two
# minutes on two cores.
set -u

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PF=${1:-$ROOT/build/bin/photonfarm}
PFW=${2:-$ROOT/build/bin/photonfarm-worker}
INJ=${3:-$ROOT/build/bin/pf_inject}
abs() { case $1 in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
PF=$(abs "$PF")
PFW=$(abs "$PFW")
INJ=$(abs "$INJ")
for exe in "$PF" "$PFW" "$INJ"; do
    if [ ! -x "$exe" ]; then
        echo "test_farm.sh: $exe is not an executable" >&2
        echo "0 passed, 1 failed"
        exit 1
    fi
done

T=$(mktemp -d "${TMPDIR:-/tmp}/pf_farm.XXXXXX") || exit 1
cd "$ROOT" || exit 1

# Children inherit this tag; it tells our worker processes from anyone else's.
export PF_FARM_TEST_TAG="pf_farm_test_$$_$RANDOM"

PIDS=()
cleanup() {
    local p
    for p in "${PIDS[@]}"; do
        kill -9 "$p" 2>/dev/null
    done
    for p in $(tagged_workers); do
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

# tagged_workers: pids of live photonfarm-worker processes that carry this
# script's tag (ours, whoever started them). Zombies are skipped: their
# environment cannot be read and they hold nothing.
tagged_workers() {
    local p comm
    for p in $(pgrep -f photonfarm-worker 2>/dev/null); do
        comm=$(cat "/proc/$p/comm" 2>/dev/null) || continue
        case $comm in photonfarm-work*) ;; *) continue ;; esac
        tr '\0' '\n' <"/proc/$p/environ" 2>/dev/null | grep -qx "PF_FARM_TEST_TAG=$PF_FARM_TEST_TAG" || continue
        echo "$p"
    done
}

# no_workers_left [SECONDS]: true when no tagged worker is alive, waiting up to
# SECONDS (default 3) for processes that are on their way out.
no_workers_left() {
    local end=$((SECONDS + ${1:-3})) left
    while :; do
        left=$(tagged_workers)
        [ -z "$left" ] && return 0
        [ "$SECONDS" -ge "$end" ] && break
        sleep 0.1
    done
    note "worker processes left behind: $(echo $left) ($(for p in $left; do tr '\0' ' ' <"/proc/$p/cmdline"; echo ';'; done))"
    return 1
}

free_port() {
    python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

# ---- images and logs ---------------------------------------------------------

# same IMAGE REFERENCE: bit-identical PFMs; on a difference, prints what
# `photonfarm compare` says about it.
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

# num FILE WORDS: the number in front of WORDS in the last summary line that
# has it (e.g. num log "re-issued"), or -1 when there is none.
num() {
    local v
    v=$(grep -E 'summary' "$1" 2>/dev/null | grep -oE "[0-9]+ $2" | tail -n 1 | grep -oE '^[0-9]+')
    echo "${v:--1}"
}

# tiles_of FILE NAME: tiles the summary says worker NAME rendered (0 if absent).
tiles_of() {
    local v
    v=$(grep -E "summary: worker $2 rendered [0-9]+ tiles" "$1" 2>/dev/null | grep -oE 'rendered [0-9]+' | tail -n 1 |
        grep -oE '[0-9]+')
    echo "${v:-0}"
}

gt() { [ "$1" -gt "$2" ]; }
differs() { [ -s "$1" ] && [ -s "$2" ] && ! cmp -s "$1" "$2"; }
ge() { [ "$1" -ge "$2" ]; }
eq() { [ "$1" = "$2" ]; }
has() { grep -qE "$2" "$1" 2>/dev/null; }
# logged FILE REGEX: a line matches REGEX outside the summary lines.
logged() { grep -vE 'summary:' "$1" 2>/dev/null | grep -qE "$2"; }
hasnt() { ! grep -qE "$2" "$1" 2>/dev/null; }

SPHERES=scenes/cornell-spheres/scene.json
BOX=scenes/cornell-box/scene.json
SMALL=(--size 96x96 --spp 4 --photons 50000 --caustic-photons 50000 --gather 8)
# Long enough (several seconds on two one-thread workers) that a worker can
# be killed, stopped or added while tiles are in flight.
BIG=(--size 192x192 --spp 25 --photons 50000 --caustic-photons 50000 --gather 8)
# Four progressive passes of a few seconds in all.
PROG=(--size 128x128 --spp 6 --photons 30000 --caustic-photons 30000 --gather 4 --passes 4)
# The same, every pass uniform (passes after the first are adaptive by default).
PROG_UNI=("${PROG[@]}" --no-adaptive)
FARM=(--tile 16 --heartbeat-ms 200)
# A photon pass of several seconds before a tiny image (glass: caustic batches too;
# k 300: irradiance estimates long enough that workers, which fetch the global
# map first, take chunks before the coordinator has done them all).
PHOT=(--size 32x32 --spp 1 --photons 1500000 --caustic-photons 300000 --gather 4 --global-k 300)

# coordinator NAME SCENE PORT SETTINGS_VAR [extra options...]: starts a cluster
# coordinator on tcp://127.0.0.1:PORT writing $T/NAME.pfm; pid in $LASTPID.
coordinator() {
    local name=$1 scene=$2 port=$3 settings=$4
    shift 4
    local -n set_ref=$settings
    start "$name" "$PF" render "$scene" -o "$T/$name.png" --hdr "$T/$name.pfm" "${set_ref[@]}" "${FARM[@]}" \
        --bind "tcp://127.0.0.1:$port" --workers 0 --max-wait 60 "$@"
}

# worker NAME PORT [extra options...]: starts a one-thread cluster worker.
worker() {
    local name=$1 port=$2
    shift 2
    start "$name" "$PFW" --connect "tcp://127.0.0.1:$port" --threads 1 --name "$name" "$@"
}

# mid_render COORD_LOG WORKER_LOG...: waits (bounded) until the job is out and
# every given worker has built the scene and maps ("ready"), then a moment
# more, so that tiles are in flight.
mid_render() {
    local log=$1 w
    shift
    wait_log "$log" 'photon pass' 60 || return 1
    for w in "$@"; do
        wait_log "$w" 'ready' 30 || return 1
    done
    sleep 1
}

# summary_note TEST LOG: the summary's counts and tiles per worker, for the record.
summary_note() {
    note "$1: $(grep -E 'summary: [0-9]+ tiles' "$2" | sed 's/.*summary: //')"
    note "$1: $(grep -E 'summary: worker' "$2" | sed 's/.*summary: //' | tr '\n' ';')"
}

# completed MESSAGE LOG: the check that a coordinator exited 0 (in $rc); on a
# failure the caller skips the checks that need its image and summary, so
# one hang is one failure.
completed() {
    if [ "$rc" = 0 ]; then
        ok "$1 (exit 0)"
        return 0
    fi
    bad "$1 (exit $rc; the checks that need its output are skipped)"
    show "$2" 8
    return 1
}

# ---- references ----------------------------------------------------------------

references() {
    echo "# references: in-process renders (--workers 0)"
    local r rname rscene rset
    for r in spheres:$SPHERES:SMALL box:$BOX:SMALL big:$SPHERES:BIG prog:$SPHERES:PROG prog_uni:$SPHERES:PROG_UNI phot:$SPHERES:PHOT; do
        IFS=: read -r rname rscene rset <<<"$r"
        local -n rs=$rset
        if ! timeout 120 "$PF" render "$rscene" -o "$T/ref_$rname.png" --hdr "$T/ref_$rname.pfm" "${rs[@]}" \
            --threads 2 --workers 0 >"$T/ref_$rname.out" 2>"$T/ref_$rname.err"; then
            bad "in-process reference $rname renders"
            show "$T/ref_$rname.err"
            return 1
        fi
        unset -n rs
    done
    ok "in-process references rendered"
}

# ---- 1. local workers ------------------------------------------------------------

t1() {
    echo "# 1. local workers"
    local r rname rscene
    for r in spheres:$SPHERES box:$BOX; do
        IFS=: read -r rname rscene <<<"$r"
        start "local2_$rname" "$PF" render "$rscene" -o "$T/local2_$rname.png" --hdr "$T/local2_$rname.pfm" \
            "${SMALL[@]}" "${FARM[@]}" --workers 2 --threads 1
        wait_exit "$LASTPID" 120
        check "1: --workers 2 --threads 1 renders $rname (exit $rc)" eq "$rc" 0 || show "$T/local2_$rname.err"
        check "1: $rname with 2 local workers is bit-identical to in-process" \
            same "$T/local2_$rname.pfm" "$T/ref_$rname.pfm"
        check "1: no worker process left after the $rname render" no_workers_left
        summary_note 1 "$T/local2_$rname.err"
    done
    start local1 "$PF" render "$SPHERES" -o "$T/local1.png" --hdr "$T/local1.pfm" "${SMALL[@]}" "${FARM[@]}" \
        --workers 1 --threads 2
    wait_exit "$LASTPID" 120
    check "1: --workers 1 --threads 2 renders (exit $rc)" eq "$rc" 0 || show "$T/local1.err"
    check "1: 1 local worker with 2 threads is bit-identical to in-process" same "$T/local1.pfm" "$T/ref_spheres.pfm"
    check "1: no worker process left after the 1-worker render" no_workers_left
}

# ---- 2. kill -9 a worker mid-render -------------------------------------------------

# kill_test NAME MIN_WORKERS: two one-thread workers, the second killed (-9)
# while tiles are in flight.
kill_test() {
    local n=$1 min=$2 port coord wa wb
    port=$(free_port)
    coordinator "${n}_coord" "$SPHERES" "$port" BIG --min-workers "$min"
    coord=$LASTPID
    worker "${n}_a" "$port" --exit-on-bye
    wa=$LASTPID
    worker "${n}_b" "$port" --exit-on-bye
    wb=$LASTPID
    mid_render "$T/${n}_coord.err" "$T/${n}_a.err" "$T/${n}_b.err"
    if kill -0 "$coord" 2>/dev/null; then
        kill -9 "$wb"
        wait "$wb" 2>/dev/null
        ok "2: worker ${n}_b killed while the coordinator was rendering (--min-workers $min)"
    else
        bad "2: the render ended before a worker could be killed (make the render longer)"
    fi
    wait_exit "$coord" 60
    if completed "2: the render completes after kill -9 of a worker, --min-workers $min" "$T/${n}_coord.err"; then
        check "2: the image is bit-identical to in-process" same "$T/${n}_coord.pfm" "$T/ref_big.pfm"
        check "2: the log declares the killed worker dead" logged "$T/${n}_coord.err" "${n}_b.*(dead|lost|silent)"
        check "2: the summary counts a lost worker ($(num "$T/${n}_coord.err" lost) lost)" \
            ge "$(num "$T/${n}_coord.err" lost)" 1
        check "2: the summary counts re-issued tiles ($(num "$T/${n}_coord.err" re-issued) re-issued)" \
            ge "$(num "$T/${n}_coord.err" re-issued)" 1
        summary_note 2 "$T/${n}_coord.err"
        wait_exit "$wa" 10
        check "2: the surviving --exit-on-bye worker exits 0 at the end (exit $rc)" eq "$rc" 0 ||
            show "$T/${n}_a.err" 5
    fi
    stop "$wa" "$wb"
}

t2() {
    echo "# 2. kill -9 a worker mid-render"
    kill_test kill 1
    # With --min-workers 2 the job must go on once it has started, even when
    # a death leaves fewer workers than that.
    kill_test killmin 2
}

# ---- 3. SIGSTOP a worker mid-render ------------------------------------------------

t3() {
    echo "# 3. SIGSTOP a worker mid-render, SIGCONT before the end"
    local port coord wa wb was_running
    port=$(free_port)
    coordinator stop_coord "$SPHERES" "$port" BIG --min-workers 1
    coord=$LASTPID
    worker stop_a "$port" --exit-on-bye
    wa=$LASTPID
    worker stop_b "$port" --exit-on-bye
    wb=$LASTPID
    mid_render "$T/stop_coord.err" "$T/stop_a.err" "$T/stop_b.err"
    kill -STOP "$wb"
    if wait_log "$T/stop_coord.err" 'stop_b.*(dead|silent|stuck|no progress)' 10; then
        ok "3: the stopped worker is declared dead"
    else
        bad "3: the stopped worker is not declared dead within 10 s"
    fi
    sleep 1
    was_running=0
    kill -0 "$coord" 2>/dev/null && was_running=1
    kill -CONT "$wb"
    check "3: the coordinator was still rendering when the worker was resumed" eq "$was_running" 1
    wait_exit "$coord" 60
    if ! completed "3: the render completes" "$T/stop_coord.err"; then
        stop "$wa" "$wb"
        return
    fi
    check "3: the image is bit-identical to in-process" same "$T/stop_coord.pfm" "$T/ref_big.pfm"
    check "3: the summary counts re-issued tiles ($(num "$T/stop_coord.err" re-issued) re-issued)" \
        ge "$(num "$T/stop_coord.err" re-issued)" 1
    note "3: observed $(num "$T/stop_coord.err" 'duplicates') duplicates dropped"
    summary_note 3 "$T/stop_coord.err"
    note "3: $(grep -E 'stop_b' "$T/stop_coord.err" | sed 's/^[^a-z]*//' | tr '\n' ';' | cut -c1-400)"
    wait_exit "$wa" 10
    check "3: worker stop_a exits 0 at the end of the job (exit $rc)" eq "$rc" 0 || show "$T/stop_a.err" 5
    wait_exit "$wb" 10
    check "3: the resumed worker stop_b exits 0 at the end of the job (exit $rc)" eq "$rc" 0 || show "$T/stop_b.err" 5
    stop "$wa" "$wb"
}

# ---- 4. a worker joins mid-render ---------------------------------------------------

t4() {
    echo "# 4. a worker that joins mid-render"
    local port coord wa wb joined_while_running
    port=$(free_port)
    coordinator join_coord "$SPHERES" "$port" BIG --min-workers 1
    coord=$LASTPID
    worker join_a "$port" --exit-on-bye
    wa=$LASTPID
    mid_render "$T/join_coord.err" "$T/join_a.err"
    worker join_b "$port" --exit-on-bye
    wb=$LASTPID
    joined_while_running=0
    kill -0 "$coord" 2>/dev/null && joined_while_running=1
    wait_exit "$coord" 60
    if ! completed "4: the render completes" "$T/join_coord.err"; then
        stop "$wa" "$wb"
        return
    fi
    check "4: the second worker was started while the coordinator was rendering" eq "$joined_while_running" 1
    check "4: the late worker joined" has "$T/join_coord.err" 'worker join_b joined'
    check "4: the late worker rendered tiles ($(tiles_of "$T/join_coord.err" join_b))" \
        gt "$(tiles_of "$T/join_coord.err" join_b)" 0
    check "4: the image is bit-identical to in-process" same "$T/join_coord.pfm" "$T/ref_big.pfm"
    summary_note 4 "$T/join_coord.err"
    wait_exit "$wa" 10
    wait_exit "$wb" 10
    stop "$wa" "$wb"
}

# ---- 5. crafted frames --------------------------------------------------------------

t5() {
    echo "# 5. garbage, truncated, oversized, replayed and multi-frame messages"
    local port coord ww mode irc
    port=$(free_port)
    coordinator inj_coord "$SPHERES" "$port" BIG --min-workers 1
    coord=$LASTPID
    worker inj_w "$port" --exit-on-bye
    ww=$LASTPID
    mid_render "$T/inj_coord.err" "$T/inj_w.err"
    for mode in replay garbage truncated oversized multiframe; do
        timeout 60 "$INJ" "tcp://127.0.0.1:$port" "$mode" 7 >"$T/inj_$mode.out" 2>"$T/inj_$mode.err"
        irc=$?
        check "5: pf_inject $mode ran (exit $irc)" eq "$irc" 0 || show "$T/inj_$mode.err"
        note "$(tr '\n' ' ' <"$T/inj_$mode.out")"
        check "5: the coordinator is alive after $mode" kill -0 "$coord"
    done
    check "5: the replayed RESULT frames reached the running job" has "$T/inj_replay.out" 'job [0-9]+, [0-9]+ tiles'
    wait_exit "$coord" 60
    check "5: the render completes under injected frames (exit $rc)" eq "$rc" 0 || show "$T/inj_coord.err" 8
    check "5: the image is bit-identical to in-process" same "$T/inj_coord.pfm" "$T/ref_big.pfm"
    check "5: malformed messages are logged (apart from the summary)" logged "$T/inj_coord.err" 'malformed'
    check "5: the summary counts malformed messages ($(num "$T/inj_coord.err" malformed))" \
        gt "$(num "$T/inj_coord.err" malformed)" 0
    check "5: the injected peers rendered nothing" hasnt "$T/inj_coord.err" 'summary: worker inject-'
    summary_note 5 "$T/inj_coord.err"
    wait_exit "$ww" 10
    check "5: the worker was not disturbed and exits 0 at the end (exit $rc)" eq "$rc" 0 || show "$T/inj_w.err" 5
    stop "$ww"

    # Results for tiles this peer was never leased (right size, attempt 0,
    # black pixels), sent while a worker renders: a coordinator that takes a
    # result only from a worker it leased the tile to keeps the image intact.
    port=$(free_port)
    coordinator forge_coord "$SPHERES" "$port" BIG --min-workers 1
    coord=$LASTPID
    worker forge_w "$port" --exit-on-bye
    ww=$LASTPID
    mid_render "$T/forge_coord.err" "$T/forge_w.err"
    timeout 60 "$INJ" "tcp://127.0.0.1:$port" forge >"$T/inj_forge.out" 2>"$T/inj_forge.err"
    note "$(tr '\n' ' ' <"$T/inj_forge.out")"
    wait_exit "$coord" 60
    check "5: the render completes under forged results (exit $rc)" eq "$rc" 0 || show "$T/forge_coord.err" 8
    check "5: results forged for tiles never leased to the sender do not reach the image" \
        same "$T/forge_coord.pfm" "$T/ref_big.pfm"
    wait_exit "$ww" 10
    stop "$ww"
}

# ---- 6. another protocol version ------------------------------------------------------

t6() {
    echo "# 6. a worker with another protocol version"
    local proto port coord frc ww fw
    proto=$(sed -n 's/^#define PF_PROTO_VERSION \([0-9]*\).*/\1/p' "$ROOT/proto/messages.h")
    port=$(free_port)
    coordinator proto_coord "$SPHERES" "$port" SMALL --min-workers 1
    coord=$LASTPID
    # A refused worker stays and tries again (backoff 1 s, 2 s, ...), logging
    # the refusal once; SIGTERM ends it (0). A one-job --exit-on-bye worker
    # exits 3 on a refusal.
    start fake99 "$PFW" --connect "tcp://127.0.0.1:$port" --threads 1 --name fake99 --fake-protocol 99 -v
    fw=$LASTPID
    check "6: the worker with protocol 99 is refused" wait_log "$T/fake99.err" 'refused by' 15 ||
        show "$T/fake99.err" 5
    check "6: the refused worker tries again" wait_log "$T/fake99.err" 'refused again' 10 ||
        show "$T/fake99.err" 5
    check "6: it logs the refusal once ($(grep -c 'refused by' "$T/fake99.err") times)" \
        eq "$(grep -c 'refused by' "$T/fake99.err")" 1
    check "6: the refused worker is still running" kill -0 "$fw"
    kill -TERM "$fw" 2>/dev/null
    wait_exit "$fw" 10
    check "6: SIGTERM ends the refused worker with 0 (exit $rc)" eq "$rc" 0 || show "$T/fake99.err" 5
    cat "$T/fake99.out" "$T/fake99.err" >"$T/fake.all"
    check "6: the worker's message names both versions (99 and $proto)" \
        grep -qE "99.*\b$proto\b|\b$proto\b.*99" "$T/fake.all"
    note "6: worker says: $(grep -iE 'refus|version' "$T/fake.all" | head -n 2 | tr '\n' ' ')"
    timeout 30 "$PFW" --connect "tcp://127.0.0.1:$port" --threads 1 --name fake99x --fake-protocol 99 --exit-on-bye \
        >"$T/fake_x.out" 2>"$T/fake_x.err"
    frc=$?
    check "6: with --exit-on-bye the worker with protocol 99 exits 3 (refused) (exit $frc)" eq "$frc" 3 ||
        show "$T/fake_x.err" 5
    check "6: the coordinator logs the refusal" wait_log "$T/proto_coord.err" 'refused worker fake99' 5
    check "6: the refused worker never joined" hasnt "$T/proto_coord.err" 'worker fake99 joined'
    worker proto_w "$port" --exit-on-bye
    ww=$LASTPID
    wait_exit "$coord" 60
    check "6: a compatible worker then renders the job (exit $rc)" eq "$rc" 0 || show "$T/proto_coord.err" 8
    check "6: the image is bit-identical to in-process" same "$T/proto_coord.pfm" "$T/ref_spheres.pfm"
    check "6: the summary counts the refusal ($(num "$T/proto_coord.err" refused) refused)" \
        ge "$(num "$T/proto_coord.err" refused)" 1
    wait_exit "$ww" 10
    stop "$ww"
}

# ---- 7. CURVE -------------------------------------------------------------------------

t7() {
    echo "# 7. CURVE: a listed key renders, an unlisted key is refused"
    local k kg_ok port coord pb pp wa
    mkdir -p "$T/keys"
    kg_ok=1
    for k in coord wa wb; do
        if ! timeout 10 "$PF" keygen "$T/keys/$k" >"$T/keygen_$k.out" 2>&1 || [ ! -s "$T/keys/$k.key" ] ||
            [ ! -s "$T/keys/$k.pub" ]; then
            kg_ok=0
            show "$T/keygen_$k.out"
        fi
    done
    check "7: keygen writes NAME.key and NAME.pub" eq "$kg_ok" 1
    check "7: the .pub file holds no secret key" hasnt "$T/keys/wa.pub" 'secret'
    check "7: the .key file is not readable by others" eq "$(stat -c %a "$T/keys/wa.key" 2>/dev/null | cut -c3)" 0
    cp "$T/keys/wa.pub" "$T/keys/allowed.txt"
    port=$(free_port)
    coordinator curve_coord "$SPHERES" "$port" SMALL --min-workers 1 \
        --curve-secret "$T/keys/coord.key" --curve-allow "$T/keys/allowed.txt"
    coord=$LASTPID
    # The unlisted worker and a worker without CURVE try first, while the
    # coordinator waits for its first worker; a ZAP-refused client may just
    # fail to connect, so they run under timeout.
    start curve_b timeout 10 "$PFW" --connect "tcp://127.0.0.1:$port" --threads 1 --name curve_b \
        --curve-key "$T/keys/wb.key" --curve-server-key "$T/keys/coord.pub"
    pb=$LASTPID
    start curve_plain timeout 10 "$PFW" --connect "tcp://127.0.0.1:$port" --threads 1 --name curve_plain
    pp=$LASTPID
    sleep 2
    worker curve_a "$port" --exit-on-bye --curve-key "$T/keys/wa.key" --curve-server-key "$T/keys/coord.pub"
    wa=$LASTPID
    wait_exit "$coord" 60
    check "7: the listed worker renders the job (exit $rc)" eq "$rc" 0 || show "$T/curve_coord.err" 8
    check "7: the image is bit-identical to in-process" same "$T/curve_coord.pfm" "$T/ref_spheres.pfm"
    check "7: the listed worker rendered tiles" gt "$(tiles_of "$T/curve_coord.err" curve_a)" 0
    check "7: the unlisted worker never joined" hasnt "$T/curve_coord.err" 'worker curve_b joined'
    check "7: the worker without CURVE never joined" hasnt "$T/curve_coord.err" 'worker curve_plain joined'
    check "7: the coordinator logs a refusal" logged "$T/curve_coord.err" 'refused'
    check "7: the summary counts refusals ($(num "$T/curve_coord.err" refused) refused)" \
        ge "$(num "$T/curve_coord.err" refused)" 1
    wait_exit "$pb" 15
    note "7: the unlisted worker ended with exit $rc (124: still trying at its timeout, as a refused worker does):" \
        "$(grep -iE 'refus|auth|denied' "$T/curve_b.err" | head -n 1)"
    check "7: the unlisted worker did not end as if it had served (exit $rc)" test "$rc" -ne 0
    check "7: the unlisted worker kept trying until stopped (exit $rc, 124)" eq "$rc" 124
    check "7: the unlisted worker logs its refusal once ($(grep -c 'refused by' "$T/curve_b.err") times)" \
        eq "$(grep -c 'refused by' "$T/curve_b.err")" 1
    wait_exit "$pp" 15
    note "7: the worker without CURVE ended with exit $rc: $(grep -iE 'handshake|curve' "$T/curve_plain.err" | head -n 1)"
    wait_exit "$wa" 10
    check "7: the listed worker exits 0 at the end (exit $rc)" eq "$rc" 0 || show "$T/curve_a.err" 5
    stop "$pb" "$pp" "$wa"
}

# ---- 8. Ctrl-C ------------------------------------------------------------------------

t8() {
    echo "# 8. SIGINT to a coordinator with local workers"
    local coord t0
    # A background job of a script starts with SIGINT ignored; --default-signal
    # gives the coordinator the disposition it would have under a terminal.
    start sigint env --default-signal=INT "$PF" render "$SPHERES" -o "$T/sigint.png" --hdr "$T/sigint.pfm" \
        "${BIG[@]}" "${FARM[@]}" --workers 2 --threads 1
    coord=$LASTPID
    mid_render "$T/sigint.err" "$T/sigint.err"
    check "8: local workers were running before the interrupt" test -n "$(tagged_workers)"
    kill -INT "$coord"
    t0=$SECONDS
    wait_exit "$coord" 10
    check "8: the interrupted coordinator exits 130 (exit $rc, after $((SECONDS - t0)) s)" eq "$rc" 130 ||
        show "$T/sigint.err" 8
    check "8: no worker process remains after the interrupt" no_workers_left 1
}

# ---- 9. --exit-on-bye and long-lived workers ----------------------------------------------

t9() {
    echo "# 9. --exit-on-bye and a long-lived worker across two jobs"
    local port coord wbye wlong
    port=$(free_port)
    coordinator job1 "$SPHERES" "$port" SMALL --min-workers 2
    coord=$LASTPID
    worker bye_w "$port" --exit-on-bye
    wbye=$LASTPID
    worker long_w "$port"
    wlong=$LASTPID
    wait_exit "$coord" 60
    check "9: job 1 completes (exit $rc)" eq "$rc" 0 || show "$T/job1.err" 8
    check "9: job 1 is bit-identical to in-process" same "$T/job1.pfm" "$T/ref_spheres.pfm"
    wait_exit "$wbye" 10
    check "9: the --exit-on-bye worker exits 0 at the end of the job (exit $rc)" eq "$rc" 0 || show "$T/bye_w.err" 5
    sleep 1
    check "9: the long-lived worker outlives the job" kill -0 "$wlong"
    coordinator job2 "$BOX" "$port" SMALL --min-workers 1 --max-wait 45
    coord=$LASTPID
    wait_exit "$coord" 90
    check "9: job 2 on the same port completes with the long-lived worker (exit $rc)" eq "$rc" 0 ||
        show "$T/job2.err" 8
    check "9: the long-lived worker rendered tiles in job 2 ($(tiles_of "$T/job2.err" long_w))" \
        gt "$(tiles_of "$T/job2.err" long_w)" 0
    check "9: job 2 is bit-identical to in-process" same "$T/job2.pfm" "$T/ref_box.pfm"
    kill -TERM "$wlong" 2>/dev/null
    wait_exit "$wlong" 10
    check "9: the long-lived worker exits 0 on SIGTERM (exit $rc)" eq "$rc" 0 || show "$T/long_w.err" 5
    stop "$wlong"
}

# ---- 10. progressive passes -------------------------------------------------------

t10() {
    echo "# 10. progressive passes, a worker killed in the second"
    local port coord wa wb
    port=$(free_port)
    coordinator prog_coord "$SPHERES" "$port" PROG --min-workers 2
    coord=$LASTPID
    worker prog_a "$port" --exit-on-bye
    wa=$LASTPID
    worker prog_b "$port" --exit-on-bye
    wb=$LASTPID
    if wait_log "$T/prog_coord.err" 'pass 1: ' 60 && kill -0 "$coord" 2>/dev/null; then
        sleep 0.5
        kill -9 "$wb"
        wait "$wb" 2>/dev/null
        ok "10: worker prog_b killed after the first pass"
    else
        bad "10: the first pass did not end while the render ran"
    fi
    wait_exit "$coord" 90
    if completed "10: four passes complete after kill -9 of a worker" "$T/prog_coord.err"; then
        check "10: the image of four passes is bit-identical to in-process" same "$T/prog_coord.pfm" "$T/ref_prog.pfm"
        check "10: the log has the fourth pass" logged "$T/prog_coord.err" "pass 4: 6 spp"
        check "10: passes 2 to 4 put their samples by the error so far" logged "$T/prog_coord.err" \
            "pass 2: 6 spp \(adaptive, [0-9]+\.\.[0-9]+ per pixel\)"
        check "10: adaptive passes change the image (--no-adaptive in process differs)" \
            differs "$T/ref_prog.pfm" "$T/ref_prog_uni.pfm"
        check "10: each pass's photon pass says how it was spread" logged "$T/prog_coord.err" \
            "photon pass 4: [0-9]+ batches of [0-9]+ photons, [0-9]+ traced on the coordinator, [0-9]+ on the workers"
        summary_note 10 "$T/prog_coord.err"
    fi
    stop "$wa" "$wb"
}

# ---- 11. checkpoint and --resume ------------------------------------------------------

# resume_test NAME SETTINGS_VAR REF WAIT: a cluster coordinator and two
# workers; the coordinator is killed (-9) once WAIT (a shell command) says
# so, then a second one with --resume on the same checkpoint finishes.
resume_test() {
    local n=$1 set=$2 ref=$3 wait=$4 port coord wa wb
    port=$(free_port)
    coordinator "${n}_1" "$SPHERES" "$port" "$set" --checkpoint "$T/$n.ckpt"
    coord=$LASTPID
    worker "${n}_a" "$port"
    wa=$LASTPID
    worker "${n}_b" "$port"
    wb=$LASTPID
    if eval "$wait" && kill -0 "$coord" 2>/dev/null; then
        kill -9 "$coord"
        wait "$coord" 2>/dev/null
        ok "11: $n: the coordinator killed (-9) mid-render, a checkpoint on disk"
    else
        bad "11: $n: no checkpoint while the render ran"
    fi
    check "11: $n: the killed coordinator wrote no image" test ! -e "$T/${n}_1.pfm"
    local -n sref=$set
    start "${n}_2" "$PF" render "$SPHERES" -o "$T/${n}_2.png" --hdr "$T/${n}_2.pfm" "${sref[@]}" "${FARM[@]}" \
        --bind "tcp://127.0.0.1:$port" --workers 0 --max-wait 60 --checkpoint "$T/$n.ckpt" --resume
    coord=$LASTPID
    wait_exit "$coord" 120
    if completed "11: $n: --resume finishes the render" "$T/${n}_2.err"; then
        check "11: $n: the resumed image is bit-identical to the uninterrupted one" same "$T/${n}_2.pfm" "$ref"
        check "11: $n: the log says what was resumed" logged "$T/${n}_2.err" "resuming from .*$n.ckpt"
        check "11: $n: the checkpoint is removed at the end" test ! -e "$T/$n.ckpt"
        local times
        times=$(sed -nE 's/.*done in ([0-9.]+) s: photons [0-9.]+ s, render ([0-9.]+) s.*/\1 \2/p' "$T/${n}_2.err")
        check "11: $n: the summary's render time is within its run ($times)" \
            awk -v t="${times% *}" -v r="${times#* }" 'BEGIN { exit !(t != "" && r + 0 <= t + 0) }'
    fi
    unset -n sref
    stop "$wa" "$wb"
}

# ckpt_tiles FILE: the checkpoint exists (written at the first tile, then
# every 5 s), and a moment more, so that tiles are in flight.
ckpt_tiles() {
    local i
    for i in $(seq 600); do
        [ -s "$1" ] && break
        sleep 0.1
    done
    [ -s "$1" ] && sleep 0.5
}

t11() {
    echo "# 11. kill -9 of the coordinator and --resume"
    resume_test ckpt_tiles BIG "$T/ref_big.pfm" "ckpt_tiles '$T/ckpt_tiles.ckpt'"
    resume_test ckpt_pass PROG "$T/ref_prog.pfm" "wait_log '$T/ckpt_pass_1.err' 'pass 2: ' 60 && sleep 0.3"
    # A checkpoint of other settings is refused, not used.
    local port
    port=$(free_port)
    "$PF" render "$SPHERES" -o "$T/ck_x.png" "${SMALL[@]}" --bind "tcp://127.0.0.1:$port" --workers 0 --max-wait 1 \
        --checkpoint "$T/ck_bad.ckpt" >/dev/null 2>&1 </dev/null &
    local c=$!
    sleep 1
    wait "$c" 2>/dev/null
    printf 'PFCK\001\000\000\000garbage' >"$T/ck_bad.ckpt"
    timeout 60 "$PF" render "$SPHERES" -o "$T/ck_x.png" "${SMALL[@]}" --bind "tcp://127.0.0.1:$port" --workers 0 \
        --max-wait 5 --checkpoint "$T/ck_bad.ckpt" --resume >"$T/ck_bad.out" 2>"$T/ck_bad.err"
    rc=$?
    check "11: a malformed checkpoint is refused with exit 3 (exit $rc)" eq "$rc" 3
    check "11: ... naming the file" has "$T/ck_bad.err" "ck_bad.ckpt"
}

# ---- 12. the photon pass on the workers ---------------------------------------------

# photon_test NAME KILL: two one-thread workers join while the coordinator
# traces the photon pass; with KILL=1 the second is killed -9 once it traces.
photon_test() {
    local n=$1 kill=$2 port coord wa wb
    port=$(free_port)
    # one thread here: the workers, which fetch the map blob first, still
    # find irradiance chunks free (the images do not depend on threads)
    coordinator "${n}_coord" "$SPHERES" "$port" PHOT --threads 1
    coord=$LASTPID
    worker "${n}_a" "$port" --exit-on-bye
    wa=$LASTPID
    worker "${n}_b" "$port" --exit-on-bye
    wb=$LASTPID
    if [ "$kill" = 1 ]; then
        if wait_log "$T/${n}_b.err" 'tracing photon batches' 30 && sleep 0.3 && kill -0 "$coord" 2>/dev/null &&
            hasnt "$T/${n}_coord.err" 'photon pass: [0-9]+ global'; then
            kill -9 "$wb"
            wait "$wb" 2>/dev/null
            ok "12: worker ${n}_b killed while tracing photon batches"
        else
            bad "12: the photon pass ended before a worker could be killed (make it longer)"
        fi
    fi
    wait_exit "$coord" 120
    if completed "12: the render with the photon pass on the workers completes (kill $kill)" "$T/${n}_coord.err"; then
        check "12: the image is bit-identical to in-process (kill $kill)" same "$T/${n}_coord.pfm" "$T/ref_phot.pfm"
        local remote irr
        remote=$(grep -E 'summary: photon pass spread' "$T/${n}_coord.err" | grep -oE '[0-9]+ on the workers' |
            grep -oE '^[0-9]+')
        check "12: the log says the workers traced photon batches (${remote:-none})" gt "${remote:-0}" 0
        irr=$(grep -E 'summary: irradiance spread' "$T/${n}_coord.err" | grep -oE '[0-9]+ on the workers' |
            grep -oE '^[0-9]+')
        check "12: the log says the workers computed irradiance chunks (${irr:-none})" gt "${irr:-0}" 0
        # a worker's main loop held up by a 100 MB transfer (each copy of a
        # realloc'd blob buffer took up to a second under the sanitizers)
        # was declared silent, and the coordinator computed every chunk
        check "12: no worker fell silent (kill $kill)" hasnt "$T/${n}_coord.err" "${n}_a .*silent"
        if [ "$kill" = 1 ]; then
            check "12: the log declares the killed worker dead" logged "$T/${n}_coord.err" "${n}_b.*(dead|lost|silent)"
            check "12: ... and its photon batches went back" logged "$T/${n}_coord.err" "${n}_b.*photon batches"
        fi
        note "12: $(grep -E 'photon pass spread' "$T/${n}_coord.err" | sed 's/.*summary: //')"
        note "12: $(grep -E 'irradiance spread' "$T/${n}_coord.err" | sed 's/.*summary: //')"
    fi
    stop "$wa" "$wb"
}

t12() {
    echo "# 12. the photon pass spread over the workers"
    photon_test phot 0
    photon_test photkill 1
}

# ---- run ----------------------------------------------------------------------------

if references; then
    # PF_FARM_ONLY="2 5" runs only those tests (for debugging).
    for n in ${PF_FARM_ONLY:-1 2 3 4 5 6 7 8 9 10 11 12}; do
        "t$n"
    done
fi

for p in "${PIDS[@]}"; do
    kill -9 "$p" 2>/dev/null
done
wait 2>/dev/null
check "no photonfarm-worker from this script is left" no_workers_left 3

if [ "$known" -gt 0 ]; then
    echo "$known known bug(s) reported above (not counted as failures)"
fi
finish
