# tests/integration/netns.sh: "hosts" on one machine as network namespaces
# (sourced by test_cluster.sh and scale_hosts.sh). Each host namespace has
# eth0, one end of a veth pair whose other end is a port of the bridge br0 in
# a bridge namespace; the hosts get NET.1, NET.2, ... on a private /24 with
# no route out, so nothing touches the host's own network. The caller sets
# the array NAMESPACES (every namespace it makes, bridge first: the teardown
# deletes exactly these, which takes their veths and the bridge with them).
# shellcheck shell=bash
# shellcheck disable=SC2154 # NAMESPACES belongs to the sourcing script

ns_exists() { ip netns list 2>/dev/null | grep -qE "^$1( |\$)"; }

# netns_teardown: kills every process in the caller's namespaces (kill -9)
# and deletes the namespaces.
netns_teardown() {
    local ns p
    for ns in "${NAMESPACES[@]}"; do
        ns_exists "$ns" || continue
        for p in $(ip netns pids "$ns" 2>/dev/null); do
            kill -9 "$p" 2>/dev/null
        done
    done
    wait 2>/dev/null
    for ns in "${NAMESPACES[@]}"; do
        ns_exists "$ns" && ip netns del "$ns" 2>/dev/null
    done
    return 0
}

# netns_setup NET BRIDGE_NS HOST_NS:BRIDGE_PORT...: makes every namespace in
# NAMESPACES, the bridge in BRIDGE_NS and one veth pair per host (NET.1 for
# the first, NET.2 for the next, ...). Returns non-zero, with the failing
# command's message on stderr, when the kernel or the container refuses any
# step.
netns_setup() {
    local net=$1 br=$2 ns pair brport i=1
    shift 2
    for ns in "${NAMESPACES[@]}"; do
        ip netns add "$ns" || return 1
        ip -n "$ns" link set lo up || return 1
    done
    ip -n "$br" link add br0 type bridge || return 1
    ip -n "$br" link set br0 up || return 1
    for pair in "$@"; do
        ns=${pair%%:*}
        brport=${pair#*:}
        ip link add eth0 netns "$ns" type veth peer name "$brport" netns "$br" || return 1
        ip -n "$br" link set "$brport" master br0 || return 1
        ip -n "$br" link set "$brport" up || return 1
        ip -n "$ns" addr add "$net.$i/24" dev eth0 || return 1
        ip -n "$ns" link set eth0 up || return 1
        i=$((i + 1))
    done
}

# netns_tbf NS DEV MBIT: a token bucket (tc tbf) on DEV's egress in NS, MBIT
# Mbit/s; the burst is 32 kB (or a tick's worth of bytes at high rates, which
# tbf needs), the queue 400 ms. Fails (message on stderr) where tc or the
# tbf qdisc is missing.
netns_tbf() {
    local burst=$(($3 * 1000000 / 8 / 250))
    [ "$burst" -lt 32768 ] && burst=32768
    ip netns exec "$1" tc qdisc add dev "$2" root tbf rate "${3}mbit" burst "$burst" latency 400ms
}

# netns_rx_bytes NS: bytes received on eth0 in namespace NS.
netns_rx_bytes() {
    local v
    v=$(ip netns exec "$1" cat /sys/class/net/eth0/statistics/rx_bytes 2>/dev/null)
    echo "${v:-0}"
}
