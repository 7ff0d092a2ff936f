#!/usr/bin/env bash
# Regenerate models/: the two built-in parameter sets written out, and the models calibrated
# (thesis pairs with grids, Gaussian, mixture) from the shared Qualisys recording (../shared/data/mocap, BSD licence: see its LICENSE).
# Usage: scripts/make_models.sh [handskin-binary] [output-folder]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "${1:-./build/handskin}")
OUT=${2:-models}
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
MOCAP=$(realpath ../shared/data/mocap/qualisys-hand-recording.tsv)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# Made in the work folder, then copied over the committed files (handskin replaces only files
# it wrote itself: docs/formats.md "Files handskin writes"). Relative names inside the work
# folder, so the model's description and notes do not carry a temporary path.
cd "$work"
mkdir -p models
"$BIN" --quiet model --model builtin:anatomical --out models/anatomical.json >/dev/null
"$BIN" --quiet model --model builtin:thesis --out models/thesis-table-3.2.json >/dev/null
"$BIN" --quiet mocap --in "$MOCAP" --out qualisys-hand-recording-angles.csv >/dev/null
"$BIN" --quiet calibrate --angles qualisys-hand-recording-angles.csv --out models/qualisys-calibrated.json --method thesis-pairs --grids >/dev/null
"$BIN" --quiet calibrate --angles qualisys-hand-recording-angles.csv --out models/qualisys-gaussian.json >/dev/null
"$BIN" --quiet calibrate --angles qualisys-hand-recording-angles.csv --out models/qualisys-mixture.json --method mixture \
  --no-evaluate >/dev/null
for f in anatomical.json thesis-table-3.2.json qualisys-calibrated.json qualisys-gaussian.json qualisys-mixture.json; do
  cp "models/$f" "$OUT/$f"
done
echo "$OUT"
