#!/usr/bin/env bash
# The hand studio end to end: `handskin studio` on the default fixture's skin.glb, the page in
# - chromium (default): headless Chromium, driven by playwright-core (web/tests/studio.js);
# - firefox: Firefox ESR under Xvfb (headless Firefox has no WebGL without a GPU), driven by
#   puppeteer-core over WebDriver BiDi (web/tests/studio_firefox.js).
# The L2 slider in input mode moves the other fingers and the picture, keys play, the piano
# plays; screenshots go to <artefacts>/studio_*.png.
# Usage: scripts/check_studio.sh <handskin-binary> [artefacts-folder] [chromium|firefox]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1")
ART=${2:-build/test-artefacts}
BROWSER=${3:-chromium}
mkdir -p "$ART"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
case "$BROWSER" in
  chromium)
    [ -d web/node_modules/playwright-core ] || { echo "check_studio: run scripts/npm.sh first" >&2; exit 1; }
    command -v chromium >/dev/null || { echo "check_studio: chromium is needed (scripts/setup.sh installs it)" >&2; exit 1; }
    "$BIN" -q run --back fixtures/default/back --palm fixtures/default/palm --rig fixtures/default/rig.json --out "$work/run" >/dev/null
    node web/tests/studio.js "$BIN" "$work/run/skin.glb" "$ART" ;;
  firefox)
    [ -d web/node_modules/puppeteer-core ] || { echo "check_studio: run scripts/npm.sh first" >&2; exit 1; }
    command -v firefox-esr >/dev/null || { echo "check_studio: firefox-esr is needed (scripts/setup.sh installs it)" >&2; exit 1; }
    command -v xvfb-run >/dev/null || { echo "check_studio: xvfb-run is needed (scripts/setup.sh installs xvfb)" >&2; exit 1; }
    "$BIN" -q run --back fixtures/default/back --palm fixtures/default/palm --rig fixtures/default/rig.json --out "$work/run" >/dev/null
    # Firefox keeps its profile under $HOME: give it one of its own.
    HOME="$work" xvfb-run -a -s "-screen 0 1280x800x24" node web/tests/studio_firefox.js "$BIN" "$work/run/skin.glb" "$(realpath "$ART")" ;;
  *) echo "check_studio: unknown browser '$BROWSER' (chromium or firefox)" >&2; exit 2 ;;
esac
