#!/usr/bin/env bash
# Regenerate fixtures/default (the default hand's scan pair, rig and truth) with fixed seeds.
# Usage: scripts/make_fixtures.sh [handskin-binary] [output-folder]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-./build/handskin}
OUT=${2:-fixtures/default}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$BIN" --quiet synth hand --out "$work/hand" --posture flat --seed 1 --no-render >/dev/null
"$BIN" --quiet synth scan --mesh "$work/hand/hand.ply" --rig "$work/hand/hand_rig.json" --out "$work/scan" \
  --seed 2000 --no-render >/dev/null
mkdir -p "$OUT"
for f in back.png back.json palm.png palm.json back.photo.png palm.photo.png rig.json truth.json truth_skin.ply; do
  cp "$work/scan/$f" "$OUT/$f"
done
echo "$OUT"
