# tests/integration/lib.sh: the reporting helpers shared by the shell tests (sourced).
# check MESSAGE COMMAND... counts a pass or a failure; known_bug is a check
# whose failure is a reported bug (printed, not counted); skip records a check
# that cannot run here; finish prints the closing line ("N passed, M failed",
# plus ", K skipped" when any were) and returns the exit status.
# shellcheck shell=bash

pass=0
fail=0
skipped=0
known=0
failed=()

ok() {
    pass=$((pass + 1))
    echo "ok      $*"
}
bad() {
    fail=$((fail + 1))
    failed+=("$*")
    echo "FAIL    $*"
}
skip() {
    skipped=$((skipped + 1))
    echo "SKIP: $*"
}
# check MESSAGE COMMAND...: one check; passes when COMMAND succeeds.
check() {
    local msg=$1
    shift
    if "$@"; then ok "$msg"; else bad "$msg"; fi
}
# known_bug MESSAGE COMMAND...: a check that exposes a reported bug; a
# failure is printed as KNOWN BUG and does not fail the suite until fixed.
known_bug() {
    local msg=$1
    shift
    if "$@"; then
        ok "$msg (known bug appears fixed: make this a plain check)"
    else
        known=$((known + 1))
        echo "KNOWN BUG: $msg"
    fi
}
note() { echo "        $*"; }
# show FILE [N]: the last N lines of a log, indented, for a failure's context.
show() {
    [ -s "$1" ] && tail -n "${2:-12}" "$1" | sed "s|^|        $(basename "$1"): |"
    return 0
}
# finish: the failed checks again (a long log's tail, which is all CI may
# keep, still names them), then the closing line; returns 0 only when none
# failed.
finish() {
    local f
    for f in "${failed[@]}"; do
        echo "failed: $f"
    done
    [ "$known" -gt 0 ] && echo "$known known bug(s) reported above (not counted as failures)"
    if [ "$skipped" -gt 0 ]; then
        echo "$pass passed, $fail failed, $skipped skipped"
    else
        echo "$pass passed, $fail failed"
    fi
    [ "$fail" -eq 0 ]
}
