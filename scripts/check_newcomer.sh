#!/usr/bin/env bash
# The README's newcomer path, run from another working directory (issue 40): the first
# command (scripts/demo.sh: set-up, build, the run on the default hand) started from a
# temporary folder, its outputs checked; then what a newcomer does next with them, from
# elsewhere again — `patches --skin-dir` on the folder and on a moved copy, `pose --skin`,
# `render --mesh` of the patches — and the system python3 importing handskin in a new shell.
# Usage: scripts/check_newcomer.sh   (as CTest runs it: test newcomer_path)
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
mkdir elsewhere && cd elsewhere
OUT="$work/out/default" bash "$SRC/scripts/demo.sh" > "$work/demo.log" 2>&1 || { tail -20 "$work/demo.log"; exit 1; }
grep -q "handskin: outputs are in $work/out/default" "$work/demo.log" || { echo "check_newcomer: demo.sh did not say where"; exit 1; }
for f in report.json report.html skin.ply skin.obj skin.mtl skin.glb texture.png patches.step merged.ply registration.json; do
  [ -s "$work/out/default/$f" ] || { echo "check_newcomer: $f missing"; exit 1; }
done
python3 - "$work/out/default/report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["gates_passed"], r["gates"]
assert r["outputs"]["skin_glb"] == "skin.glb", r["outputs"]  # relative to the report
assert not r["inputs"]["back"].startswith("/"), r["inputs"]
PY
H="$SRC/build/handskin"
cd / && "$H" -q patches --skin-dir "$work/out/default" --out "$work/p1" > /dev/null
mv "$work/out" "$work/moved" && cd "$work" && "$H" -q patches --skin-dir moved/default --out "$work/p2" > /dev/null
cmp <(python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print(r["data_to_surface_mm"], r["patches"])' "$work/p1/report.json") \
    <(python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); print(r["data_to_surface_mm"], r["patches"])' "$work/p2/report.json")
cd /tmp && "$H" -q pose --skin "$work/moved/default/skin.glb" --set index.pip.flex=60 --out "$work/posed.stl" > /dev/null
"$H" -q render --mesh "$work/moved/default/patches.obj" --out "$work/patches.png" > /dev/null
env -i PATH=/usr/bin:/bin HOME="${HOME:-/root}" /usr/bin/python3 -c \
  "import handskin; m = handskin.PostureModel(); assert len(m.solve({'index.pip.flex': 60.0})) == len(handskin.dofs())"
echo "check_newcomer: demo.sh from $work/elsewhere, then patches, pose, render and python from elsewhere: ok"
