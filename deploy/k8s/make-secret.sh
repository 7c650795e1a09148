#!/usr/bin/env bash
# Makes the farm's two CURVE Secrets from secret.template.yaml and prints them
# (docs/cluster.md):
#
#   deploy/k8s/make-secret.sh | kubectl apply -f -
#   deploy/k8s/make-secret.sh --keys DIR | kubectl apply -n render -f -
#
# Without --keys it makes a fresh coordinator key pair and one worker key
# pair (shared by every worker pod) with `photonfarm keygen` in a private
# temporary directory, which it deletes; with --keys DIR it uses
# DIR/coordinator.key and DIR/worker.key made earlier. The output holds secret
# keys: pipe it to kubectl rather than keeping it in a file.
#
# usage: make-secret.sh [--keys DIR] [--photonfarm PATH]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
template=$here/secret.template.yaml

keys=""
pf=""
while [ $# -gt 0 ]; do
  case $1 in
    --keys) keys=${2:?--keys needs a directory}; shift 2 ;;
    --photonfarm) pf=${2:?--photonfarm needs a path}; shift 2 ;;
    -h | --help) sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "make-secret: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
if [ -z "$pf" ]; then
  pf=$(command -v photonfarm || true)
  [ -n "$pf" ] || [ ! -x "$here/../../build/bin/photonfarm" ] || pf=$here/../../build/bin/photonfarm
fi

tmp=$(mktemp -d)
chmod 0700 "$tmp"
trap 'rm -rf "$tmp"' EXIT

if [ -z "$keys" ]; then
  if [ -z "$pf" ] || [ ! -x "$pf" ]; then
    echo "make-secret: photonfarm not found (install it, or pass --photonfarm PATH, or --keys DIR)" >&2
    exit 1
  fi
  (cd "$tmp" && "$pf" keygen coordinator >/dev/null && "$pf" keygen worker >/dev/null)
  keys=$tmp
fi
for f in coordinator.key worker.key; do
  if [ ! -r "$keys/$f" ]; then
    echo "make-secret: cannot read $keys/$f" >&2
    exit 1
  fi
done

# The public halves: the public-key line of each key pair file (what
# `photonfarm keygen` also writes to NAME.pub).
pubkey() {
  local line
  line=$(grep -E '^[[:space:]]*public-key[[:space:]]*=' "$1" | head -n 1)
  if [ -z "$line" ]; then
    echo "make-secret: $1 has no public-key line" >&2
    return 1
  fi
  printf '# photonfarm CURVE public key (Z85)\npublic-key = %s\n' "$(echo "${line#*=}" | tr -d '[:space:]')"
}
pubkey "$keys/coordinator.key" >"$tmp/coordinator.pub.out"
pubkey "$keys/worker.key" >"$tmp/allowed-workers.out"

b64() { base64 -w 0 <"$1"; }
sed -e "s|\"@COORDINATOR_KEY_B64@\"|$(b64 "$keys/coordinator.key")|" \
  -e "s|\"@ALLOWED_WORKERS_B64@\"|$(b64 "$tmp/allowed-workers.out")|" \
  -e "s|\"@WORKER_KEY_B64@\"|$(b64 "$keys/worker.key")|" \
  -e "s|\"@COORDINATOR_PUB_B64@\"|$(b64 "$tmp/coordinator.pub.out")|" \
  "$template"
