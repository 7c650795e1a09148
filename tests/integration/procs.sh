# tests/integration/procs.sh: the process helpers shared by the farm's shell
# tests (sourced by test_farm.sh and test_hostile.sh). The caller provides $T
# (its temporary folder) and the array PIDS (the pids its cleanup kills);
# these set LASTPID and rc.
# shellcheck shell=bash
# shellcheck disable=SC2154,SC2034 # T and PIDS belong to the sourcing script, which reads rc

# start NAME CMD...: runs CMD in the background with stdout and stderr in
# $T/NAME.out and $T/NAME.err; its pid is recorded (for the cleanup) and left
# in $LASTPID.
LASTPID=0
start() {
    local name=$1
    shift
    "$@" >"$T/$name.out" 2>"$T/$name.err" &
    LASTPID=$!
    PIDS+=("$LASTPID")
}

# wait_exit PID SECONDS: waits (bounded) for a child to end and leaves its
# exit code in $rc; one still running at the deadline is killed (kill -9) and
# rc is 124, as with timeout(1).
rc=0
wait_exit() {
    local pid=$1 end=$((SECONDS + $2))
    while kill -0 "$pid" 2>/dev/null && [ "$SECONDS" -lt "$end" ]; do
        sleep 0.1
    done
    if kill -0 "$pid" 2>/dev/null; then
        kill -9 "$pid" 2>/dev/null
        wait "$pid" 2>/dev/null
        rc=124
        return 1
    fi
    wait "$pid" 2>/dev/null
    rc=$?
    return 0
}

# wait_log FILE REGEX SECONDS: waits (bounded) until FILE has a line matching
# REGEX (grep -E).
wait_log() {
    local end=$((SECONDS + $3))
    while [ "$SECONDS" -lt "$end" ]; do
        grep -qE "$2" "$1" 2>/dev/null && return 0
        sleep 0.1
    done
    grep -qE "$2" "$1" 2>/dev/null
}

# stop PID...: kill -9 and reap (for processes whose end is not under test).
stop() {
    local p
    for p in "$@"; do
        kill -9 "$p" 2>/dev/null
        wait "$p" 2>/dev/null
    done
    return 0
}
