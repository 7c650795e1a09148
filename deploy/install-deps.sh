#!/usr/bin/env bash
# Installs the Debian/Ubuntu packages photonfarm needs to build and run,
# only those that are missing. Run as root (or with sudo available).
# Usage: deploy/install-deps.sh [--test] [--fuzz] [--bench] [--check]
#   --test   also the tools the test suite uses (shellcheck, yamllint,
#            systemd-analyze, ip/tc for the network-namespace cluster test, python3,
#            gnuplot for the bench_smoke test's plot)
#   --fuzz   also clang and its libFuzzer/sanitizer runtimes (deploy/fuzz.sh)
#   --bench  also what bench/bench.py needs (python3, gnuplot for the plots)
#   --check  list what is missing, install nothing
set -euo pipefail

packages=(cmake make gcc pkg-config libzmq3-dev libpng-dev libembree-dev libcjson-dev zlib1g-dev libtinyexr-dev libstb-dev)
check_only=0
for arg in "$@"; do
  case "$arg" in
    --test) packages+=(python3 shellcheck yamllint iproute2 systemd gnuplot-nox) ;;
    --fuzz) packages+=(clang libclang-rt-14-dev) ;;
    --bench) packages+=(python3 gnuplot-nox) ;;
    --check) check_only=1 ;;
    *) echo "install-deps: unknown option $arg (usage: install-deps.sh [--test] [--fuzz] [--bench] [--check])" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "install-deps: all packages present (${packages[*]})"
  exit 0
fi
echo "install-deps: missing: ${missing[*]}"
if [ "$check_only" = 1 ]; then
  exit 1
fi

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then
    sudo_cmd=(sudo)
  else
    echo "install-deps: not root and no sudo: install these as root: ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -q
"${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: installed ${missing[*]}"
