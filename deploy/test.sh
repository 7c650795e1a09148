#!/usr/bin/env bash
# The README's second command: installs what is missing, builds with
# warnings as errors, and runs every test with ctest.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/deploy/install-deps.sh"
"$root/deploy/build.sh" -DPF_WERROR=ON
cd "$root/build"
ctest --output-on-failure --timeout 1200 "$@"
