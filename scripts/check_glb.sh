#!/usr/bin/env bash
# A real client on skin.glb: the Khronos glTF Validator (web/, npm gltf-validator) must report
# 0 errors and 0 warnings on the default fixture's skin.glb and on a posed one.
# Usage: scripts/check_glb.sh <handskin-binary>
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1")
if [ ! -d web/node_modules/gltf-validator ]; then
  echo "check_glb: web/node_modules/gltf-validator is missing: run scripts/npm.sh (scripts/test.sh does)" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$BIN" -q run --back fixtures/default/back --palm fixtures/default/palm --rig fixtures/default/rig.json --out "$work/run" >/dev/null
"$BIN" -q pose --model "$work/run/skin.glb" --set L2.flex=60 --set index.pip.flex=90 --out "$work/posed.glb" >/dev/null
node web/validate-gltf.js "$work/run/skin.glb" "$work/posed.glb"
