#!/usr/bin/env bash
# test_cli.sh: end-to-end tests of the photonfarm command line. It runs the
# real executable on the shipped scenes and on the broken scenes in
# tests/data/cli/, and checks exit codes, messages and the files written: PNG
# structure, PFM headers and values, determinism across thread counts, the
# `compare` subcommand and the --terms switch.
#
# usage: tests/integration/test_cli.sh [path/to/photonfarm]   (default: build/bin/photonfarm)
#
# Every render is tiny (at most 40x40 pixels, 1 spp, 20000 photons, 8 gather
# rays) so the whole script takes a few seconds. Checks that expose a known bug
# in the program are run with known_bug instead of check: they print
# "KNOWN BUG: ..." and do not fail the suite until the bug is fixed, at which
# point they say so and should be turned back into plain checks.
set -u

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PF=${1:-$ROOT/build/bin/photonfarm}
# The script changes directory, so the program's path must not be relative.
case $PF in
/*) ;;
*) PF=$PWD/$PF ;;
esac
if [ ! -x "$PF" ]; then
    echo "test_cli.sh: $PF is not an executable" >&2
    echo "0 passed, 1 failed"
    exit 1
fi

T=$(mktemp -d "${TMPDIR:-/tmp}/pf_cli.XXXXXX") || exit 1
trap 'rm -rf "$T"' EXIT
cd "$T" || exit 1

DATA=$ROOT/tests/data/cli
SCENES=$ROOT/scenes
SMALL=(--spp 1 --photons 20000 --caustic-photons 20000 --gather 8 -q)

# shellcheck source=tests/integration/lib.sh
. "$ROOT/tests/integration/lib.sh"

# check MESSAGE COMMAND...: one check; passes when COMMAND succeeds. A
# failure names the last photonfarm command and shows its stderr.
check() {
    local msg=$1
    shift
    if "$@"; then
        ok "$msg"
    else
        bad "$msg (last command: $LAST, exit $rc)"
        if [ -s "$T/err" ]; then
            sed 's/^/        stderr: /' "$T/err" | head -5
        fi
    fi
}

# run ARGS...: runs photonfarm with ARGS, keeping its exit code in $rc and its
# output in $T/out and $T/err. The timeout turns a hang into a failure
# (exit 124) rather than a stalled suite.
rc=0
LAST="(none)"
run() {
    LAST="photonfarm $*"
    timeout 60 "$PF" "$@" >"$T/out" 2>"$T/err"
    rc=$?
}

rc_is() { [ "$rc" -eq "$1" ]; }
err_has() { grep -qF -- "$1" "$T/err"; }
out_has() { grep -qF -- "$1" "$T/out"; }
# err_has_all S...: stderr contains every S.
err_has_all() {
    local x
    for x in "$@"; do err_has "$x" || return 1; done
}
out_has_all() {
    local x
    for x in "$@"; do out_has "$x" || return 1; done
}

# Image inspection in Python, which reads binary formats without guesswork.
#   png FILE: checks the signature, every chunk's CRC, IHDR, that the IDAT
#             stream inflates to exactly the bytes the size needs, and IEND;
#             prints "W H".
#   pfm FILE: checks the "PF" header and that the file holds exactly W*H*3
#             floats; prints "W H BAD MEAN" where BAD counts NaN, infinite and
#             negative values and MEAN is the mean of the finite values.
cat >"$T/img.py" <<'EOF'
import binascii, math, struct, sys, zlib

def png(path):
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit("%s: bad PNG signature" % path)
    pos, chunks = 8, []
    while pos < len(data):
        if pos + 12 > len(data) or pos + 12 + struct.unpack(">I", data[pos:pos + 4])[0] > len(data):
            sys.exit("%s: truncated chunk at byte %d" % (path, pos))
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        crc = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0]
        if len(body) != n or binascii.crc32(kind + body) != crc:
            sys.exit("%s: bad %r chunk" % (path, kind))
        chunks.append((kind, body))
        pos += 12 + n
    if not chunks or chunks[0][0] != b"IHDR" or chunks[-1][0] != b"IEND":
        sys.exit("%s: IHDR must come first and IEND last" % path)
    w, h, depth, ctype = struct.unpack(">IIBB", chunks[0][1][:10])
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(ctype)
    if depth != 8 or channels is None:
        sys.exit("%s: unexpected depth %d / colour type %d" % (path, depth, ctype))
    raw = zlib.decompress(b"".join(b for k, b in chunks if k == b"IDAT"))
    if len(raw) != h * (1 + w * channels):
        sys.exit("%s: IDAT holds %d bytes, %dx%d needs %d" % (path, len(raw), w, h, h * (1 + w * channels)))
    print(w, h)

def pfm(path):
    data = open(path, "rb").read()
    fields, pos = [], 0
    while len(fields) < 4:
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while pos < len(data) and not data[pos:pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos].decode("ascii", "replace"))
    pos += 1  # exactly one whitespace byte ends the header
    if fields[0] != "PF":
        sys.exit("%s: not a colour PFM (magic %r)" % (path, fields[0]))
    w, h, scale = int(fields[1]), int(fields[2]), float(fields[3])
    n = w * h * 3
    if len(data) - pos != 4 * n:
        sys.exit("%s: %dx%d needs %d bytes of pixels, file has %d" % (path, w, h, 4 * n, len(data) - pos))
    vals = struct.unpack(("<" if scale < 0 else ">") + "%df" % n, data[pos:])
    bad = sum(1 for v in vals if not math.isfinite(v) or v < 0)
    good = [v for v in vals if math.isfinite(v)]
    print(w, h, bad, repr(sum(good) / len(good) if good else 0.0))

try:
    {"png": png, "pfm": pfm}[sys.argv[1]](sys.argv[2])
except (OSError, ValueError, struct.error, zlib.error) as e:
    sys.exit("%s: %s" % (sys.argv[2], e))
EOF

# png_is FILE W H: FILE is a well-formed PNG of that size.
png_is() { [ "$(python3 "$T/img.py" png "$1" 2>&1)" = "$2 $3" ]; }
# pfm_size_is FILE W H: FILE is a well-formed PFM of that size.
pfm_size_is() {
    local s
    s=$(python3 "$T/img.py" pfm "$1" 2>&1) || return 1
    set -- $s "$2" "$3"
    [ "$1" = "$5" ] && [ "$2" = "$6" ]
}
# pfm_clean FILE: no NaN, infinite or negative value, and not all black.
pfm_clean() {
    local s
    s=$(python3 "$T/img.py" pfm "$1" 2>&1) || return 1
    set -- $s
    [ "$3" = 0 ] && python3 -c "import sys; sys.exit(not float(sys.argv[1]) > 0)" "$4"
}
# differ A B: the files A and B differ.
differ() { ! cmp -s "$1" "$2"; }
pfm_mean() {
    local s
    s=$(python3 "$T/img.py" pfm "$1") || return 1
    set -- $s
    echo "$4"
}
# darker A B: the PFM A has a lower mean than the PFM B.
darker() {
    local a b
    a=$(pfm_mean "$1") && b=$(pfm_mean "$2") || return 1
    python3 -c "import sys; sys.exit(not float(sys.argv[1]) < float(sys.argv[2]))" "$a" "$b"
}
files_same() { cmp -s "$1" "$2"; }
files_differ() { [ -f "$1" ] && [ -f "$2" ] && ! cmp -s "$1" "$2"; }
# relmse_is V: the table printed by `compare` gives relMSE V.
relmse_is() { [ "$(awk '$1 == "relMSE" { print $2 }' "$T/out")" = "$1" ]; }

# ---------------------------------------------------------------------------
echo "# 1. help, version and usage errors"

OPTIONS=(--size --spp --photons --caustic-photons --gather --threads --seed --exposure --hdr -o --terms)
run --help
check "--help exits 0" rc_is 0
for o in "${OPTIONS[@]}"; do
    check "--help mentions $o" out_has " $o"
done
run render --help
check "render --help exits 0" rc_is 0
for o in "${OPTIONS[@]}"; do
    check "render --help mentions $o" out_has " $o"
done
run --version
check "--version exits 0" rc_is 0
check "--version prints 'photonfarm X.Y.Z'" grep -qE '^photonfarm [0-9]+\.[0-9]+\.[0-9]+' "$T/out"

run
check "no arguments exits 2" rc_is 2
check "no arguments prints the usage on stderr" err_has "usage:"
run frobnicate
check "unknown command exits 2" rc_is 2
check "unknown command is named in the message" err_has "frobnicate"
run render --bogus "$SCENES/cornell-box/scene.json"
check "unknown option exits 2" rc_is 2
check "unknown option is named in the message" err_has "--bogus"
run render
check "render without a scene exits 2" rc_is 2
run render "$SCENES/cornell-box/scene.json" "$SCENES/bunny/scene.json"
check "render with two scenes exits 2" rc_is 2
run render "$SCENES/cornell-box/scene.json" -o
check "-o without its argument exits 2" rc_is 2

# Each bad value must be refused before the scene is even read.
bad_value() {
    local opt=$1 val=$2
    rm -f "$T/bad.png"
    run render "$opt" "$val" "$SCENES/cornell-box/scene.json" -o "$T/bad.png"
    check "$opt '$val' exits 2" rc_is 2
    check "$opt '$val': the message names $opt" err_has "$opt"
    check "$opt '$val': no image is written" test ! -e "$T/bad.png"
}
bad_value --size 0x5
bad_value --size 5x0
bad_value --size 32
bad_value --spp -1
bad_value --spp 0
bad_value --photons abc
bad_value --photons -5
bad_value --caustic-photons 1.5
bad_value --gather x
bad_value --threads x
bad_value --threads -1
bad_value --seed -1
bad_value --exposure nan
bad_value --terms bogus

# The option is named on the line that reports the bad value.
run render --size 0x5 "$SCENES/cornell-box/scene.json"
check "the bad-value message reads \"bad value '0x5' for --size\"" \
    err_has "bad value '0x5' for --size"
# Trailing junk after the height is refused.
run render --size 16x16junk "$SCENES/cornell-box/scene.json" "${SMALL[@]}" -o "$T/junk.png"
check "--size '16x16junk' is refused with exit 2" rc_is 2
# strtoull would skip leading blanks and wrap "-1" to 2^64-1: only digits pass.
run render --seed " -1" "$SCENES/cornell-box/scene.json" "${SMALL[@]}" --size 8x8 -o "$T/seed.png"
check "--seed ' -1' is refused with exit 2" rc_is 2

# ---------------------------------------------------------------------------
echo "# 2. the shipped scenes render to valid PNG and PFM files"

# Non-square sizes catch a transposed width and height.
render_scene() {
    local name=$1 w=$2 h=$3
    run render "$SCENES/$name/scene.json" "${SMALL[@]}" --size "${w}x$h" -o "$T/$name.png" --hdr "$T/$name.pfm"
    check "$name: render exits 0" rc_is 0
    check "$name: the PNG is well formed and ${w}x$h" png_is "$T/$name.png" "$w" "$h"
    check "$name: the PFM is well formed and ${w}x$h" pfm_size_is "$T/$name.pfm" "$w" "$h"
}
render_scene cornell-box 40 24
render_scene cornell-spheres 32 32
render_scene bunny 24 40

mkdir -p "$T/default" && cd "$T/default" || exit 1
run render "$SCENES/cornell-box/scene.json" "${SMALL[@]}" --size 16x16
check "without -o, scenes/cornell-box/scene.json renders (exit 0)" rc_is 0
check "without -o, the output is ./cornell-box.png, a 16x16 PNG" png_is cornell-box.png 16 16
run render "$SCENES/cornell-spheres/CornellBox-Sphere-Jensen.obj" "${SMALL[@]}" --size 16x16
check "without -o, an OBJ's output is named after its stem" png_is CornellBox-Sphere-Jensen.png 16 16
cd "$T" || exit 1

# ---------------------------------------------------------------------------
echo "# 3. an OBJ alone and a PLY alone render"

run render "$SCENES/cornell-spheres/CornellBox-Sphere-Jensen.obj" "${SMALL[@]}" --size 32x32 \
    -o "$T/obj.png" --hdr "$T/obj.pfm"
check "OBJ alone: render exits 0" rc_is 0
check "OBJ alone: the PNG is well formed and 32x32" png_is "$T/obj.png" 32 32
run render "$SCENES/bunny/bun_zipper_res4.ply" "${SMALL[@]}" --size 32x32 -o "$T/ply.png" --hdr "$T/ply.pfm"
check "PLY alone: render exits 0" rc_is 0
check "PLY alone: the PNG is well formed and 32x32" png_is "$T/ply.png" 32 32

# ---------------------------------------------------------------------------
echo "# 4. malformed input exits 3 and says where"

# bad_input FILE WHERE...: rendering FILE exits 3, writes nothing, and the
# message contains every WHERE string (file:line, and what is wrong).
bad_input() {
    local file=$1
    shift
    rm -f "$T/bad.png"
    run render "$file" "${SMALL[@]}" --size 8x8 -o "$T/bad.png"
    check "$(basename "$file"): exits 3" rc_is 3
    local s
    for s in "$@"; do
        check "$(basename "$file"): the message contains '$s'" err_has "$s"
    done
    check "$(basename "$file"): no image is written" test ! -e "$T/bad.png"
}
bad_input "$DATA/syntax-error.json" "syntax-error.json:4:" "syntax"
bad_input "$DATA/unknown-key.json" "unknown-key.json:5:" "samples_per_pixel"
bad_input "$DATA/missing-obj.json" "missing-obj.json:6:" "no-such-model.obj"
# The no-light check runs on the finished scene, which has no line to point
# at, so only the file is named.
bad_input "$DATA/no-light.json" "no-light.json" "no light"
bad_input "$DATA/no-such-scene.json" "no-such-scene.json"
bad_input "$DATA/not-a-scene.txt" "not-a-scene.txt" ".txt"

# ---------------------------------------------------------------------------
echo "# 5. rendered images are finite, non-negative and not black"

for f in cornell-box cornell-spheres bunny obj ply; do
    check "$f.pfm: no NaN, infinity or negative value, mean > 0" pfm_clean "$T/$f.pfm"
done

# ---------------------------------------------------------------------------
echo "# 6. determinism"

# cornell-spheres has glass and a mirror, so the caustic map is exercised too.
SPHERES=("$SCENES/cornell-spheres/scene.json" "${SMALL[@]}" --size 32x32)
run render "${SPHERES[@]}" --threads 1 -o "$T/t1.png" --hdr "$T/t1.pfm"
check "--threads 1 renders (exit 0)" rc_is 0
run render "${SPHERES[@]}" --threads 2 -o "$T/t2.png" --hdr "$T/t2.pfm"
check "--threads 2 renders (exit 0)" rc_is 0
check "--threads 1 and --threads 2 give byte-identical PFMs" files_same "$T/t1.pfm" "$T/t2.pfm"
check "the --threads 2 render is the same as the default-seed scene render" \
    files_same "$T/t2.pfm" "$T/cornell-spheres.pfm"
run render "${SPHERES[@]}" --threads 2 --seed 7 -o "$T/s7.png" --hdr "$T/s7.pfm"
check "--seed 7 renders (exit 0)" rc_is 0
check "--seed 7 gives a different PFM than seed 1" files_differ "$T/t1.pfm" "$T/s7.pfm"

# Exposure only scales the PNG; the linear PFM must not change.
run render "${SPHERES[@]}" --exposure 2 -o "$T/e2.png" --hdr "$T/e2.pfm"
check "--exposure 2 renders (exit 0)" rc_is 0
check "--exposure 2 leaves the PFM unchanged" files_same "$T/t1.pfm" "$T/e2.pfm"
check "--exposure 2 changes the PNG" files_differ "$T/t1.png" "$T/e2.png"

# --hdr by extension: OpenEXR float holds the PFM's values exactly, half
# within half precision (and in a smaller file).
run render "${SPHERES[@]}" -o "$T/x1.png" --hdr "$T/x1.exr"
check "--hdr x.exr renders (exit 0)" rc_is 0
run compare "$T/x1.exr" "$T/t1.pfm"
check "--hdr x.exr (float) holds the PFM's values exactly (relMSE 0)" relmse_is 0
run render "${SPHERES[@]}" -o "$T/x2.png" --hdr "$T/x2.exr" --hdr-half
check "--hdr x.exr --hdr-half renders (exit 0)" rc_is 0
run compare "$T/x2.exr" "$T/t1.pfm"
check "--hdr-half is within half precision of the float image (relMSE $(awk '$1 == "relMSE" { print $2 }' "$T/out"))" \
    awk -v v="$(awk '$1 == "relMSE" { print $2 }' "$T/out")" 'BEGIN { exit !(v != "" && v + 0 > 0 && v + 0 < 1e-5) }'
check "--hdr-half writes a smaller file than float" \
    test "$(stat -c %s "$T/x2.exr")" -lt "$(stat -c %s "$T/x1.exr")"

# ---------------------------------------------------------------------------
echo "# 7. compare"

run compare "$T/t1.pfm" "$T/t1.pfm"
check "compare image with itself exits 0" rc_is 0
check "compare image with itself gives relMSE 0" relmse_is 0
run compare --json "$T/t1.pfm" "$T/t1.pfm"
check "compare --json with itself exits 0" rc_is 0
check "compare --json with itself gives relmse 0 and the size" \
    out_has_all '"relmse":0,' '"width":32,"height":32'

run render "${SPHERES[@]}" --size 16x16 -o "$T/c16.png" --hdr "$T/c16.pfm"
run render "${SPHERES[@]}" --size 24x24 -o "$T/c24.png" --hdr "$T/c24.pfm"
run render "${SPHERES[@]}" --size 32x16 -o "$T/c32x16.png" --hdr "$T/c32x16.pfm"
run compare "$T/t1.pfm" "$T/c16.pfm"
check "compare 32x32 against 16x16 (factor 2) exits 0" rc_is 0
check "compare 32x32 against 16x16 reports the downsampling" out_has "downsampled x2 to 16x16"
run compare "$T/c16.pfm" "$T/t1.pfm"
check "compare 16x16 against 32x32 (reference larger) exits 0" rc_is 0
run compare "$T/c24.pfm" "$T/c16.pfm"
check "compare 24x24 against 16x16 (factor 1.5) exits 4" rc_is 4
check "the size mismatch names both files" err_has_all c24.pfm c16.pfm
run compare "$T/c32x16.pfm" "$T/c16.pfm"
check "compare 32x16 against 16x16 (factors 2 and 1) exits 4" rc_is 4
run compare "$T/nope.pfm" "$T/t1.pfm"
check "compare with a missing image exits 3" rc_is 3
check "the message names the missing image" err_has nope.pfm
run compare "$T/t1.pfm" "$T/nope.pfm"
check "compare with a missing reference exits 3" rc_is 3
run compare "$T/t1.png" "$T/t1.pfm"
check "compare with a PNG instead of a PFM exits 3" rc_is 3
run compare "$T/t1.pfm"
check "compare with one image exits 2" rc_is 2
run compare "$T/t1.pfm" "$T/t1.pfm" --frob
check "compare with an unknown option exits 2" rc_is 2

# ---------------------------------------------------------------------------
echo "# 8. --terms"

run render "${SPHERES[@]}" --terms direct -o "$T/direct.png" --hdr "$T/direct.pfm"
check "--terms direct renders (exit 0)" rc_is 0
check "--terms direct gives a clean, non-black PFM" pfm_clean "$T/direct.pfm"
check "--terms direct is darker than the full render" darker "$T/direct.pfm" "$T/t1.pfm"
run render "${SPHERES[@]}" --terms emitted,direct,caustic,indirect -o "$T/allterms.png" --hdr "$T/allterms.pfm"
check "--terms emitted,direct,caustic,indirect equals the default render" files_same "$T/allterms.pfm" "$T/t1.pfm"
run render "${SPHERES[@]}" --terms direct,bogus -o "$T/bogus.png"
check "--terms direct,bogus exits 2" rc_is 2

# ---------------------------------------------------------------------------
echo "# 9. unwritable outputs"

run render "$SCENES/cornell-box/scene.json" "${SMALL[@]}" --size 8x8 -o /nonexistent/dir/x.png
check "-o /nonexistent/dir/x.png exits 1" rc_is 1
check "the message names /nonexistent/dir/x.png" err_has /nonexistent/dir/x.png
run render "$SCENES/cornell-box/scene.json" "${SMALL[@]}" --size 8x8 -o "$T/w.png" --hdr /nonexistent/dir/x.pfm
check "--hdr /nonexistent/dir/x.pfm exits 1" rc_is 1
check "the message names /nonexistent/dir/x.pfm" err_has /nonexistent/dir/x.pfm
mkdir -p "$T/adir"
run render "$SCENES/cornell-box/scene.json" "${SMALL[@]}" --size 8x8 -o "$T/adir"
check "-o naming a directory exits 1" rc_is 1
check "-o naming a directory leaves no temporary file" test ! -e "$T/adir.tmp"

# ---------------------------------------------------------------------------
echo "# 10. --time-limit and --quality"

# timed_run LIMIT ARGS...: run, and keep the wall time in $wall.
wall=0
timed_run() {
    local t0 t1
    t0=$(date +%s.%N)
    run "$@"
    t1=$(date +%s.%N)
    wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f", b - a }')
}
# within LIMIT: the last run's wall time is under LIMIT plus half a second
# for starting the process and loading the scene (the planner counts from
# its own start).
within() { awk -v w="$wall" -v l="$1" 'BEGIN { exit !(w <= l + 0.5) }'; }
# uses_most LIMIT: the last run's wall time is at least 80 % of LIMIT (the
# passes go on until the deadline; a planner that stops early fails).
uses_most() { awk -v w="$wall" -v l="$1" 'BEGIN { exit !(w >= 0.8 * l) }'; }

timed_run render "$SCENES/cornell-spheres/scene.json" --size 128x128 --time-limit 4 -o "$T/tl.png" --hdr "$T/tl.pfm"
check "--time-limit 4 renders (exit 0)" rc_is 0
check "--time-limit 4 finishes within 4 s (took $wall s)" within 4
check "--time-limit 4 uses most of its 4 s (took $wall s)" uses_most 4
check "--time-limit logs the plan it made" err_has "time limit 4 s:"
check "--time-limit logs each pass" err_has "pass 2: "
check "--time-limit gives a clean, non-black PFM" pfm_clean "$T/tl.pfm"
spp=$(sed -n 's/.*passes: [0-9]* whole.*, \([0-9]*\) samples per pixel.*/\1/p' "$T/err" | head -1)
check "--time-limit 4 at 128x128 affords several samples per pixel over its passes (${spp:-none})" test "${spp:-0}" -ge 4
run render "$SCENES/cornell-spheres/scene.json" --size 64x64 --time-limit 3 --spp 2 -o "$T/tl2.png"
check "--time-limit keeps a given --spp" err_has "caustic photons, 2 spp x"
timed_run render "$SCENES/cornell-box/scene.json" --size 96x96 --time-limit 6 --workers 2 -o "$T/tlf.png" --hdr "$T/tlf.pfm"
check "--time-limit 6 with two workers renders (exit 0)" rc_is 0
check "--time-limit 6 with two workers finishes within 6 s (took $wall s)" within 6
check "--time-limit 6 with two workers uses most of its 6 s (took $wall s)" uses_most 6
check "the farm's image under a time limit is clean" pfm_clean "$T/tlf.pfm"
check "the farm renders passes under a time limit" err_has "pass 2: "

# --passes: pass 0 is the one-pass render, bit for bit; more passes differ
# from it; threads do not change the image.
PS=(render "$SCENES/cornell-spheres/scene.json" --size 48x48 --spp 4 --photons 20000 --caustic-photons 20000)
run "${PS[@]}" -o "$T/p0.png" --hdr "$T/p0.pfm"
run "${PS[@]}" --passes 1 -o "$T/p1.png" --hdr "$T/p1.pfm"
check "--passes 1 renders the image without --passes, bit for bit" cmp -s "$T/p0.pfm" "$T/p1.pfm"
run "${PS[@]}" --passes 3 --threads 2 -o "$T/p3.png" --hdr "$T/p3.pfm"
check "--passes 3 renders (exit 0)" rc_is 0
check "--passes 3 logs three passes" err_has "pass 3: 4 spp"
check "--passes 3 sums 12 samples per pixel" err_has "passes: 3 whole, 12 samples per pixel"
check "--passes 3 is another image than one pass" differ "$T/p0.pfm" "$T/p3.pfm"
run "${PS[@]}" --passes 3 --threads 1 -o "$T/p3b.png" --hdr "$T/p3b.pfm"
check "--passes 3 gives the same bits on 1 and 2 threads" cmp -s "$T/p3.pfm" "$T/p3b.pfm"
for v in 0 -1 abc; do
    run "${PS[@]}" --passes "$v" -o "$T/x.png"
    check "--passes $v exits 2" rc_is 2
done
# In process, progressive passes keep a checkpoint: kill -9 after the second
# pass, --resume, and the image is the uninterrupted one, bit for bit.
PR=(render "$SCENES/cornell-spheres/scene.json" --size 96x96 --spp 4 --photons 30000 --caustic-photons 30000
    --passes 4 --threads 2)
run "${PR[@]}" -o "$T/pr_ref.png" --hdr "$T/pr_ref.pfm"
"$PF" "${PR[@]}" -o "$T/pr.png" --hdr "$T/pr.pfm" >"$T/pr.out" 2>"$T/pr.err" &
prpid=$!
for i in $(seq 600); do grep -q "pass 2: " "$T/pr.err" 2>/dev/null && break; sleep 0.05; done
kill -9 "$prpid" 2>/dev/null
wait "$prpid" 2>/dev/null
check "kill -9 after the second pass leaves a checkpoint" test -s "$T/pr.png.ckpt"
run "${PR[@]}" -o "$T/pr.png" --hdr "$T/pr.pfm" --resume
check "--resume in process finishes (exit 0)" rc_is 0
check "... from the passes the checkpoint holds" err_has "resuming from $T/pr.png.ckpt: "
check "... with the uninterrupted image, bit for bit" cmp -s "$T/pr.pfm" "$T/pr_ref.pfm"
check "... and removes the checkpoint" test ! -e "$T/pr.png.ckpt"
run render "$SCENES/cornell-spheres/scene.json" --size 32x32 -o "$T/x.png" --resume
check "--resume of a one-pass render in process exits 2" rc_is 2
for v in 0 -1 abc 1e9; do
    run render "$SCENES/cornell-box/scene.json" --time-limit "$v" -o "$T/x.png"
    check "--time-limit $v exits 2" rc_is 2
done
run render "$SCENES/cornell-box/scene.json" --size 32x32 --quality draft --photons 20000 --caustic-photons 20000 -o "$T/q.png" --hdr "$T/q.pfm"
check "--quality draft renders (exit 0)" rc_is 0
check "--quality draft is named in the settings line" err_has "quality draft"
check "--quality draft keeps the given --photons" err_has "20000 global + 20000 caustic photons"
check "--quality draft gives a clean PFM" pfm_clean "$T/q.pfm"
run render "$SCENES/cornell-box/scene.json" --quality bogus -o "$T/x.png"
check "--quality bogus exits 2" rc_is 2

# ---------------------------------------------------------------------------
echo "# signals: SIGINT exits 130, SIGTERM 143, in process and with a farm"

# sig_run SIGNAL DELAY ARGS...: photonfarm ARGS in the background (with the
# signals' default dispositions, which a script's background job lacks),
# SIGNAL after DELAY seconds; its exit code in $rc.
sig_run() {
    local sig=$1 delay=$2 pid
    shift 2
    LAST="photonfarm $* (SIG$sig after $delay s)"
    env --default-signal=INT,TERM timeout 60 "$PF" "$@" >"$T/out" 2>"$T/err" &
    pid=$!
    sleep "$delay"
    kill -"$sig" "$pid" 2>/dev/null
    wait "$pid"
    rc=$?
}
run render --help
check "render --help names the exit codes 130 and 143" out_has "130 interrupted (SIGINT), 143 stopped (SIGTERM)"
SLOW=(render "$SCENES/cornell-spheres/scene.json" --size 256x256 --spp 256 --threads 1 -o "$T/sig.png")
sig_run TERM 1 "${SLOW[@]}" --workers 0
check "SIGTERM during an in-process render exits 143" rc_is 143
sig_run INT 1 "${SLOW[@]}" --workers 0
check "SIGINT during an in-process render exits 130" rc_is 130
check "... and writes no image" test ! -e "$T/sig.png"
sig_run TERM 2 "${SLOW[@]}" --workers 1
check "SIGTERM during a farm render exits 143" rc_is 143
check "... and says it was interrupted" err_has "interrupted"
# A photon pass stops within a block of photons: a long first one, cut.
t0=$(date +%s.%N)
sig_run INT 2 render "$SCENES/cornell-spheres/scene.json" --size 32x32 --spp 1 --passes 2 --photons 50000000 \
    --caustic-photons 100 --threads 2 -o "$T/sigph.png"
wall=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a - 2 }')
check "SIGINT during a photon pass exits 130" rc_is 130
check "... within a second of the signal (took $wall s)" within 0.5
# Progressive passes stop at the next tile and write the passes done.
PROG=(render "$SCENES/cornell-spheres/scene.json" --size 96x96 --time-limit 600 --threads 2 -o "$T/sigp.png" --hdr "$T/sigp.pfm")
t0=$(date +%s.%N)
sig_run INT 4 "${PROG[@]}"
wall=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a - 4 }')
check "SIGINT during progressive passes exits 130" rc_is 130
check "... within 2 s of the signal (took $wall s)" within 1.5
check "... and writes the image of the passes done" pfm_clean "$T/sigp.pfm"
check "... and says so" err_has "(interrupted)"
rm -f "$T/sigp.pfm"
t0=$(date +%s.%N)
sig_run TERM 5 "${PROG[@]}" --workers 2 --threads 1
wall=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a - 5 }')
check "SIGTERM during a farm's progressive passes exits 143" rc_is 143
check "... within 2 s of the signal (took $wall s)" within 1.5
check "... and writes the image of the passes done" pfm_clean "$T/sigp.pfm"

finish
