#!/usr/bin/env bash
# Real clients on skin.glb (web/, npm): the Khronos glTF Validator must report 0 errors and 0
# warnings on the default fixture's skin.glb and on a posed one; three.js's GLTFLoader in
# headless Chromium must load it, find the 25 joints and see the skin move when a joint
# turns (its screenshot goes to <artefacts>/three_skin.png); Blender (Debian's) must import it
# as an armature of 25 bones whose pose moves the mesh. An animation from `handskin animate`
# must pass the validator too, and Blender must import it with an action whose keyframes move
# the skin. skin.obj (with skin.mtl and texture.png) must import into Blender with its UVs and
# its texture, and an STL from `convert` with the skin's faces.
# Usage: scripts/check_glb.sh <handskin-binary> [artefacts-folder]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1")
ART=${2:-build/test-artefacts}
for m in gltf-validator three playwright-core; do
  if [ ! -d "web/node_modules/$m" ]; then
    echo "check_glb: web/node_modules/$m is missing: run scripts/npm.sh (scripts/test.sh does)" >&2
    exit 1
  fi
done
command -v chromium >/dev/null || { echo "check_glb: chromium is needed (scripts/setup.sh installs it)" >&2; exit 1; }
command -v blender >/dev/null || { echo "check_glb: blender is needed (scripts/setup.sh installs it)" >&2; exit 1; }
mkdir -p "$ART"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$BIN" -q run --back fixtures/default/back --palm fixtures/default/palm --rig fixtures/default/rig.json --out "$work/run" >/dev/null
"$BIN" -q pose --skin "$work/run/skin.glb" --set L2.flex=60 --set index.pip.flex=90 --out "$work/posed.glb" >/dev/null
printf 'time,L2.flex,I2.flex\n0,0,0\n1,60,0\n2,60,60\n' > "$work/keys.csv"
"$BIN" -q animate --skin "$work/run/skin.glb" --keys "$work/keys.csv" --inputs-only --fps 30 --out "$work/anim.glb" >/dev/null
node web/validate-gltf.js "$work/run/skin.glb" "$work/posed.glb" "$work/anim.glb"
node web/tests/three-skin.js "$work/run/skin.glb" "$ART/three_skin.png"
blender --background --factory-startup --python scripts/blender_import.py -- "$work/run/skin.glb" 2>&1 | grep "^blender_import:"
test "${PIPESTATUS[0]}" -eq 0
blender --background --factory-startup --python scripts/blender_animation.py -- "$work/anim.glb" 2>&1 | grep "^blender_animation:"
test "${PIPESTATUS[0]}" -eq 0
"$BIN" -q convert --in "$work/run/skin.glb" --out "$work/skin.stl" >/dev/null
size=$(python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print(next(s for s in r["stages"] if s["name"]=="texture")["size"])' "$work/run/report.json")
blender --background --factory-startup --python scripts/blender_obj.py -- "$work/run/skin.obj" "$work/skin.stl" 4002 8000 "$size" 2>&1 | grep "^blender_obj:"
test "${PIPESTATUS[0]}" -eq 0
