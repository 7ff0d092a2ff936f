#!/usr/bin/env bash
# The hand studio end to end (web/tests/studio.js): `handskin studio` on the default fixture's
# skin.glb, the page in headless Chromium (playwright-core), the L2 slider in input mode moves
# the other fingers and the picture; screenshots go to <artefacts>/studio_*.png.
# Usage: scripts/check_studio.sh <handskin-binary> [artefacts-folder]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1")
ART=${2:-build/test-artefacts}
[ -d web/node_modules/playwright-core ] || { echo "check_studio: run scripts/npm.sh first" >&2; exit 1; }
command -v chromium >/dev/null || { echo "check_studio: chromium is needed (scripts/setup.sh installs it)" >&2; exit 1; }
mkdir -p "$ART"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$BIN" -q run --back fixtures/default/back --palm fixtures/default/palm --rig fixtures/default/rig.json --out "$work/run" >/dev/null
node web/tests/studio.js "$BIN" "$work/run/skin.glb" "$ART"
