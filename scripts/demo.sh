#!/usr/bin/env bash
# Newcomer command 1: install, build, and run the pipeline on the embedded default hand.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/npm.sh    # three.js and esbuild for the studio page (handskin studio)
bash scripts/build.sh
OUT=${OUT:-out/default}
./build/handskin run --back fixtures/default/back --palm fixtures/default/palm \
  --rig fixtures/default/rig.json --out "$OUT" --pipeline pipelines/cubist.json
echo "handskin: outputs are in $(realpath "$OUT") (report.json, skin.ply, skin.obj, skin.png, merged.ply, registration.json, ...)"
