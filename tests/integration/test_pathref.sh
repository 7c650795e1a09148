#!/usr/bin/env bash
# bench/pathref.c, the brute-force path tracer that checks the photon mapper
# on scenes without a reference, checked itself against a renderer that is
# not photonfarm: the Cornell box at 128x128, 128 spp, with the reference's
# own reconstruction (Tungsten's tent of radius 1 pixel at 1024, box-
# downsampled 8 times: box+tent:0.125), against Tungsten's render
# (tests/data/references/cornell-box-128.pfm) after a 4x downsample with the
# light masked: relMSE at most 0.002 (its noise gives about 0.0003) and mean
# luminance within 1 %. A wrong MIS weight, a light pdf off by a factor or a
# lost bounce moves these by far more.
# Usage: test_pathref.sh PATHREF PHOTONFARM (from the repository root).
set -u
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/integration/lib.sh
. "$here/lib.sh"
pathref=$1
pf=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

if "$pathref" scenes/cornell-box/scene.json -o "$work/pt.pfm" --size 128x128 --spp 128 \
    --pixel-filter box+tent:0.125 > "$work/log" 2>&1; then
    ok "pathref renders the Cornell box: $(cat "$work/log")"
    out=$("$pf" compare "$work/pt.pfm" tests/data/references/cornell-box-128.pfm --downsample 4 --mask-above 5)
    echo "$out"
    rel=$(echo "$out" | awk '/^relMSE/ { print $2 }')
    lum=$(echo "$out" | awk '/^luminance/ { print $2 }')
    check "4x masked relMSE $rel <= 0.002" awk -v r="$rel" 'BEGIN { exit !(r != "" && r <= 0.002) }'
    check "luminance $lum within 1 %" awk -v l="$lum" 'BEGIN { exit !(l != "" && l >= 0.99 && l <= 1.01) }'
else
    bad "pathref failed: $(cat "$work/log")"
fi
"$pathref" > /dev/null 2>&1
check "no arguments: usage, exit 2" test $? -eq 2
finish
