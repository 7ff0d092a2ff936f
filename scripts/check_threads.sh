#!/usr/bin/env bash
# --threads changes only the time (issue 39): the fixture's whole run, and its patches refined
# to a tolerance, made with one thread and with two, must come out the same bytes (timings
# aside: scripts/same_outputs.py). Each is made in the same folder in turn, so the paths that
# the reports record are the same.
# Usage: [KEEP=1] scripts/check_threads.sh <handskin-binary>   (KEEP: the two folders are kept, in $TMPDIR)
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1")
work=$(mktemp -d)
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
FX=fixtures/default
for t in 1 2; do
  "$BIN" -q --threads "$t" run --back $FX/back --palm $FX/palm --rig $FX/rig.json --out "$work/o" >/dev/null
  "$BIN" -q --threads "$t" patches --skin-dir "$work/o" --rig $FX/rig.json --patch-tolerance 0.5 --out "$work/o/refined" \
    >/dev/null
  mv "$work/o" "$work/threads$t"
done
python3 scripts/same_outputs.py "$work/threads1" "$work/threads2"
n=$(find "$work/threads1" -type f | wc -l)
echo "check_threads: $n files, the same bytes with 1 and 2 threads${KEEP:+ ($work)}"
