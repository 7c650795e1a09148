#!/usr/bin/env bash
# scale_hosts.sh: farm renders across network-namespace "hosts" with
# bandwidth-limited links, for the scaling model's validation
# (bench/scale.py --check, ctest scale). One coordinator namespace and up to
# 6 worker namespaces on a bridge (tests/integration/netns.sh, as in
# test_cluster.sh); every link is a token bucket (tc tbf) both ways: the
# coordinator's at --coord-mbit, each worker's at --worker-mbit. netem is not
# used (this kernel has no sch_netem; the latency is the veths' own).
#
# usage: scale_hosts.sh PHOTONFARM PHOTONFARM-WORKER OUTDIR COORD_MBIT WORKER_MBIT
#                       WORKER_THREADS FANOUT "W1 W2 ..." SCENE [render options...]
#
# For each worker count W it starts W fresh workers (empty blob caches, one
# per namespace, --exit-on-bye) and a coordinator (--min-workers W, --verify 0,
# --threads = the machine's cores, --fanout FANOUT: 0 for the farm where the
# coordinator serves every worker, 2 for the farm's default tree; the photon
# pass and the irradiance precompute are spread over the workers as the farm
# does by default) rendering SCENE with the given options, and
# writes the coordinator's log to OUTDIR/wW.err and the workers' to
# OUTDIR/wW-k.err; it prints one line per run, "run W=W rc=RC wall=SECONDS".
# Exits 77 (skipped) with a SKIP line where namespaces, veths, a bridge or
# tbf cannot be made (not root, no iproute2, a container that refuses them),
# 1 when a render fails.
set -u

PF=$1 PFW=$2 OUT=$3 COORD_MBIT=$4 WORKER_MBIT=$5 WTHREADS=$6 FANOUT=$7 COUNTS=$8 SCENE=$9
shift 9
mkdir -p "$OUT" || exit 1

skip_all() {
    echo "SKIP: $*"
    exit 77
}
[ "$(id -u)" -eq 0 ] || skip_all "the namespace hosts need root (network namespaces, veth pairs, a bridge, tc)"
command -v ip >/dev/null 2>&1 || skip_all "no 'ip' (Debian package iproute2)"
command -v tc >/dev/null 2>&1 || skip_all "no 'tc' (Debian package iproute2)"

MAXW=0
for w in $COUNTS; do [ "$w" -gt "$MAXW" ] && MAXW=$w; done
TAG=pfsc$$
NS_BR=$TAG-br
NS_C=$TAG-c
NAMESPACES=("$NS_BR" "$NS_C")
PAIRS=("$NS_C:to-c")
for k in $(seq 1 "$MAXW"); do
    NAMESPACES+=("$TAG-w$k")
    PAIRS+=("$TAG-w$k:to-w$k")
done
NET=10.78.0
EP=tcp://$NET.1:7879

# shellcheck source=tests/integration/netns.sh
. "$(dirname "$0")/netns.sh"
trap 'netns_teardown 2>/dev/null' EXIT
trap 'exit 130' INT TERM

if ! netns_setup "$NET" "$NS_BR" "${PAIRS[@]}" 2>"$OUT/net.err"; then
    skip_all "cannot build the namespace network here ($(tail -n 1 "$OUT/net.err"))"
fi
if ! netns_tbf "$NS_C" eth0 "$COORD_MBIT" 2>"$OUT/tc.err" ||
    ! netns_tbf "$NS_BR" to-c "$COORD_MBIT" 2>>"$OUT/tc.err"; then
    skip_all "this kernel refuses the tbf qdisc ($(tail -n 1 "$OUT/tc.err"))"
fi
for k in $(seq 1 "$MAXW"); do
    if ! netns_tbf "$TAG-w$k" eth0 "$WORKER_MBIT" 2>>"$OUT/tc.err" ||
        ! netns_tbf "$NS_BR" "to-w$k" "$WORKER_MBIT" 2>>"$OUT/tc.err"; then
        skip_all "this kernel refuses the tbf qdisc ($(tail -n 1 "$OUT/tc.err"))"
    fi
done
# The round trip between two hosts (the model's latency), from ping if there.
if command -v ping >/dev/null 2>&1; then
    rtt=$(ip netns exec "$TAG-w1" ping -c 5 -i 0.2 -q "$NET.1" 2>/dev/null | grep -oE '= [0-9.]+/[0-9.]+' | cut -d/ -f2)
    echo "rtt_ms=${rtt:-}"
fi

cores=$(nproc)
failed=0
for w in $COUNTS; do
    pids=()
    for k in $(seq 1 "$w"); do
        ip netns exec "$TAG-w$k" timeout 600 "$PFW" --connect "$EP" --threads "$WTHREADS" --name "w$k" \
            --exit-on-bye -v >"$OUT/w$w-$k.out" 2>"$OUT/w$w-$k.err" &
        pids+=($!)
    done
    t0=$(date +%s.%N)
    ip netns exec "$NS_C" timeout 600 "$PF" render "$SCENE" -o "$OUT/w$w.png" "$@" --threads "$cores" \
        --bind "$EP" --workers 0 --min-workers "$w" --verify 0 --max-wait 120 --fanout "$FANOUT" -v \
        >"$OUT/w$w.out" 2>"$OUT/w$w.err"
    rc=$?
    t1=$(date +%s.%N)
    # The workers leave on the coordinator's BYE; any still there after 5 s
    # is killed, so the next run starts with fresh ones.
    end=$((SECONDS + 5))
    for p in "${pids[@]}"; do
        while kill -0 "$p" 2>/dev/null && [ "$SECONDS" -lt "$end" ]; do sleep 0.1; done
        kill -9 "$p" 2>/dev/null
        wait "$p" 2>/dev/null
    done
    [ "$rc" -eq 0 ] || failed=1
    echo "run W=$w rc=$rc wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')"
done
exit "$failed"
