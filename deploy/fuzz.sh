#!/usr/bin/env bash
# Runs the libFuzzer targets (docs/fuzzing.md) for SECONDS each and prints a
# summary table: target, seconds, executions, exec/s, corpus size, coverage,
# result. Exits non-zero if any target found a crash, a hang (> 10 s on one
# input), a leak or an out-of-memory; the input that did it is saved in
# build-fuzz/artifacts/<target>/.
#
# Usage: bash deploy/fuzz.sh SECONDS [--jobs N] [TARGET...]
#   TARGET   json obj mtl ply pbrt msg sceneblob mapfile pfm (default: all)
#   --jobs N run N targets at once (default 1; on 2 cores use at most 2)
#
# Build: build-fuzz/ with clang, -DPF_FUZZ=ON -DPF_SANITIZE=ON (ASan, UBSan,
# LeakSanitizer). Corpus: build-fuzz/corpus/<target>/ starts from the seeds
# (fuzz/make_corpus, and tests/data/fuzz/<target>/) and keeps what the runs
# add, so a later run goes on from there; the seeds in git stay small.
# Logs: build-fuzz/logs/<target>.log. Summary: build-fuzz/summary.md.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
all_targets=(json obj mtl ply pbrt msg sceneblob mapfile pfm)

usage() {
  echo "usage: bash deploy/fuzz.sh SECONDS [--jobs N] [TARGET...]  (targets: ${all_targets[*]})" >&2
  exit 2
}

[ $# -ge 1 ] || usage
seconds=$1
shift
if ! [[ "$seconds" =~ ^[1-9][0-9]*$ ]]; then usage; fi
jobs=1
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --jobs)
      if [ $# -lt 2 ] || ! [[ "$2" =~ ^[1-9][0-9]*$ ]]; then usage; fi
      jobs=$2; shift 2 ;;
    -h|--help) usage ;;
    *)
      ok=0
      for t in "${all_targets[@]}"; do [ "$t" = "$1" ] && ok=1; done
      [ "$ok" = 1 ] || { echo "fuzz.sh: unknown target '$1'" >&2; usage; }
      targets+=("$1"); shift ;;
  esac
done
[ ${#targets[@]} -gt 0 ] || targets=("${all_targets[@]}")

# The longest input each target may grow to: a little above its largest
# seed (the bunny PLY is 34 KB; the photon-map seed about 10 KB).
max_len() {
  case "$1" in
    ply) echo 40000 ;;
    sceneblob|mapfile) echo 16384 ;;
    json|obj) echo 8192 ;;
    *) echo 4096 ;;
  esac
}

"$root/deploy/install-deps.sh" --fuzz >/dev/null
build="$root/build-fuzz"
if [ ! -f "$build/CMakeCache.txt" ]; then
  CC=clang cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPF_FUZZ=ON -DPF_SANITIZE=ON >/dev/null
fi
cmake --build "$build" --target fuzz_all -j 2 >"$build/build.log" 2>&1 || {
  tail -40 "$build/build.log" >&2
  echo "fuzz.sh: build failed (log: $build/build.log)" >&2
  exit 1
}

# Seeds: regenerated each run, merged into the working corpus.
rm -rf "$build/seeds"
"$build/bin/pf_make_corpus" --root "$root" "$build/seeds" >/dev/null
mkdir -p "$build/corpus" "$build/artifacts" "$build/logs" "$build/stats"
for t in "${targets[@]}"; do
  mkdir -p "$build/corpus/$t" "$build/artifacts/$t"
  cp -n "$build/seeds/$t"/* "$build/corpus/$t"/ 2>/dev/null || true
  cp -n "$root/tests/data/fuzz/$t"/* "$build/corpus/$t"/ 2>/dev/null || true
done

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

# One target: libFuzzer for $seconds, then a line of stats in stats/<t>.
run_one() {
  local t=$1 log="$build/logs/$1.log" dict=() extra=()
  [ -f "$root/fuzz/$t.dict" ] && dict=("-dict=$root/fuzz/$t.dict")
  case "$t" in msg|sceneblob|mapfile) extra=(-use_value_profile=1) ;; esac
  local before stamp rc=0
  before=$(find "$build/corpus/$t" -type f | wc -l)
  stamp="$build/stats/$t.start"
  touch "$stamp"
  # libFuzzer stops by itself after max_total_time; the outer timeout only
  # guards against the harness hanging outside an input.
  timeout $((seconds * 2 + 120)) "$build/bin/fuzz_$t" "$build/corpus/$t" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len="$(max_len "$t")" \
    -artifact_prefix="$build/artifacts/$t/" -print_final_stats=1 -detect_leaks=1 \
    "${dict[@]}" "${extra[@]}" >"$log" 2>&1 || rc=$?
  local execs rate cov corpus found result
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | awk '{print $2}')
  corpus=$(find "$build/corpus/$t" -type f | wc -l)
  found=$(find "$build/artifacts/$t" -type f -newer "$stamp" | wc -l)
  if [ "$found" -gt 0 ]; then
    result="FOUND $found: $(find "$build/artifacts/$t" -type f -newer "$stamp" -printf '%f ' | head -c 200)"
  elif [ "$rc" -ne 0 ]; then
    result="exit $rc (see logs/$t.log)"
    found=1
  else
    result="clean"
  fi
  printf '| %s | %s | %s | %s | %s -> %s | %s | %s |\n' "$t" "$seconds" "${execs:-?}" "${rate:-?}" \
    "$before" "$corpus" "${cov:-?}" "$result" >"$build/stats/$t"
  echo "$found" >"$build/stats/$t.found"
  echo "fuzz.sh: $t done: $result" >&2
}

echo "fuzz.sh: ${#targets[@]} targets x ${seconds} s, $jobs at a time; logs in $build/logs/" >&2
running=0
for t in "${targets[@]}"; do
  if [ "$running" -ge "$jobs" ]; then
    wait -n || true
    running=$((running - 1))
  fi
  run_one "$t" &
  running=$((running + 1))
done
wait

{
  echo "| target | seconds | executions | exec/s | corpus (before -> after) | coverage (edges) | result |"
  echo "|---|---|---|---|---|---|---|"
  for t in "${targets[@]}"; do cat "$build/stats/$t"; done
} | tee "$build/summary.md"

# A target that crashed could not remove its work folder (fuzz_util.h);
# remove those whose process is gone.
for d in /dev/shm/pf-fuzz-*-*; do
  [ -d "$d" ] || continue
  pid=${d##*-}
  kill -0 "$pid" 2>/dev/null || rm -rf "$d"
done

bad=0
for t in "${targets[@]}"; do
  bad=$((bad + $(cat "$build/stats/$t.found")))
done
if [ "$bad" -gt 0 ]; then
  echo "fuzz.sh: findings in $build/artifacts/ (reproduce: build-fuzz/bin/fuzz_TARGET FILE)" >&2
  exit 1
fi
echo "fuzz.sh: no crash, hang or leak" >&2
