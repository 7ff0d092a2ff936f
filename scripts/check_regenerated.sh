#!/usr/bin/env bash
# Fails when a committed folder differs from what its generator script produces now: byte for
# byte, except JSON numbers within a relative 1e-9 (glibc's exp/log differ in the last bits
# between processors; scripts/same_regenerated.py says why).
# Usage: scripts/check_regenerated.sh <make-script> <folder> [handskin-binary]
#   e.g. scripts/check_regenerated.sh scripts/make_fixtures.sh fixtures/default build/handskin
set -euo pipefail
cd "$(dirname "$0")/.."
MAKE=$1
DIR=$2
BIN=${3:-./build/handskin}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
bash "$MAKE" "$BIN" "$tmp/out" >/dev/null
if python3 scripts/same_regenerated.py "$DIR" "$tmp/out"; then
  echo "$DIR is up to date"
else
  echo "$DIR differs from a fresh regeneration: run $MAKE and review"
  exit 1
fi
