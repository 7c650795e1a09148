#!/usr/bin/env bash
# The whole test suite under AddressSanitizer and UndefinedBehaviorSanitizer
# (LeakSanitizer included): a separate build in build-sanitize/ with
# -DPF_SANITIZE=ON. Any sanitizer report aborts the process and fails its
# test. About 5 minutes on 2 cores (the farm tests run their processes under
# the sanitizers too).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/deploy/install-deps.sh" --test
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S "$root" -B "$root/build-sanitize" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPF_SANITIZE=ON -DPF_WERROR=ON
cmake --build "$root/build-sanitize" -j "$jobs"
cd "$root/build-sanitize"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
ctest --output-on-failure --timeout 1800 "$@"
