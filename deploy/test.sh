#!/usr/bin/env bash
# The README's second command: installs what is missing (the build's
# packages and the test tools), builds with warnings as errors, and runs every
# test with ctest (unit, integration, accuracy, farm, deploy, cluster).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/deploy/install-deps.sh" --test
"$root/deploy/build.sh" -DPF_WERROR=ON
cd "$root/build"
ctest --output-on-failure --timeout 1200 "$@"
