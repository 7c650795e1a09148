#!/usr/bin/env bash
# The README's first command: installs what is missing, builds, and renders
# the bundled demo scene (the mirror-and-glass Cornell box) to
# cornell-spheres.png and cornell-spheres.pfm in the current folder.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/deploy/install-deps.sh"
"$root/deploy/build.sh"
"$root/build/bin/photonfarm" render "$root/scenes/cornell-spheres/scene.json" \
  -o cornell-spheres.png --hdr cornell-spheres.pfm "$@"
echo "demo: wrote $(pwd)/cornell-spheres.png"
