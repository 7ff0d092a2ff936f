#!/usr/bin/env bash
# patches.step read by a CAD client the project does not hold (FreeCAD, Debian's
# freecad-python3): the fixture's run (98 patches) and a refined fit of it (T-junctions), each
# one closed shell of one face per patch (scripts/check_step_freecad.py). Run from another
# working directory, as a user would. Usage: check_step_clients.sh HANDSKIN_BINARY
set -euo pipefail
bin=$(realpath "$1")
src=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
"$bin" -q run --back "$src/fixtures/default/back" --palm "$src/fixtures/default/palm" --rig "$src/fixtures/default/rig.json" --out run
/usr/bin/python3 "$src/scripts/check_step_freecad.py" run
"$bin" -q patches --skin-dir run --rig "$src/fixtures/default/rig.json" --patch-tolerance 0.5 --out refined > /dev/null
/usr/bin/python3 "$src/scripts/check_step_freecad.py" refined
