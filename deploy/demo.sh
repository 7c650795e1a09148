#!/usr/bin/env bash
# The README's first command: installs what is missing, builds, and renders
# the bundled demo scene (the mirror-and-glass Cornell box) with two local
# worker processes (the farm over loopback) to cornell-spheres.png and
# cornell-spheres.pfm in the current folder. Extra arguments go to
# `photonfarm render` (e.g. --quality draft).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/deploy/install-deps.sh"
"$root/deploy/build.sh"
"$root/build/bin/photonfarm" render "$root/scenes/cornell-spheres/scene.json" \
  --workers 2 -o cornell-spheres.png --hdr cornell-spheres.pfm "$@"
echo "demo: wrote $(pwd)/cornell-spheres.png"
