#!/usr/bin/env bash
# Every command's outputs on the fixture and a few family pairs, into one folder, so that a
# refactor can show "behaviour unchanged" (issue 36): run it before and after, then
#   python3 scripts/same_outputs.py <before> <after>
# Usage: scripts/snapshot_outputs.sh <handskin-binary> <folder> [family-work-folder]
# Each command writes into <folder>/<name> through the same scratch path, so the paths that
# reports record are equal between two snapshots. Family pairs are made (synth hand + synth
# scan) in the family folder unless they are there already.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "$1")
SNAP=$(realpath -m "$2")
FAM=${3:-/tmp/family-study}
SCRATCH=/tmp/handskin-snapshot-scratch
rm -rf "$SNAP" "$SCRATCH"
mkdir -p "$SNAP" "$SCRATCH" "$FAM"
FX=fixtures/default
# shot NAME CMD... : run CMD (which writes into $SCRATCH/o), keep its outputs and its stdout;
# FILES=1 shot ...: the same for a command that writes files into $SCRATCH/o, made first
shot() {
  local name=$1; shift
  rm -rf "$SCRATCH/o"
  if [ -n "${FILES:-}" ]; then mkdir -p "$SCRATCH/o"; fi
  "$@" > "$SCRATCH/stdout.txt" 2>/dev/null || echo "exit $?" >> "$SCRATCH/stdout.txt"
  mkdir -p "$SNAP/$name"
  if [ -d "$SCRATCH/o" ]; then cp -r "$SCRATCH/o/." "$SNAP/$name/"; fi
  mv "$SCRATCH/stdout.txt" "$SNAP/$name/stdout.txt"
}
O=$SCRATCH/o
pair() {  # pair HAND SEED RADIUS SYNTH-OPTS... -> $FAM/HAND-sSEED
  local h=$1 s=$2 r=$3; shift 3
  if [ ! -f "$FAM/$h/hand.ply" ]; then "$BIN" -q synth hand --out "$FAM/$h" --no-render "$@" >/dev/null; fi
  if [ ! -f "$FAM/$h-s$s/back.json" ]; then
    "$BIN" -q synth scan --mesh "$FAM/$h/hand.ply" --rig "$FAM/$h/hand_rig.json" --out "$FAM/$h-s$s" \
      --seed "$s" --marker-radius "$r" --no-render >/dev/null
  fi
}
pair S02 2 3.0 --side left
pair S05 1 2.5 --hand-length 175 --set index.pip.flex=25 --set middle.pip.flex=28 --set ring.pip.flex=30 \
  --set little.pip.flex=32 --set middle.dip.flex=15
pair S07 3 3.5 --hand-length 170 --set thumb.cmc.flex=18 --thumb-pronation 60
echo "snapshot: run" >&2
shot run "$BIN" -q run --back $FX/back --palm $FX/palm --rig $FX/rig.json --out "$O" --pipeline pipelines/cubist.json
cp -r "$SNAP/run" "$SCRATCH/run"
shot run-auto "$BIN" -q run --back $FX/back --palm $FX/palm --out "$O"
for p in S02-s2 S05-s1 S07-s3; do
  echo "snapshot: $p" >&2
  shot "$p-auto" "$BIN" -q run --back "$FAM/$p/back" --palm "$FAM/$p/palm" --truth "$FAM/$p/truth.json" --out "$O"
  shot "$p-given" "$BIN" -q run --back "$FAM/$p/back" --palm "$FAM/$p/palm" --rig "$FAM/$p/rig.json" \
    --truth "$FAM/$p/truth.json" --out "$O"
done
echo "snapshot: clouds" >&2
if [ ! -f "$FAM/S05-cloud/cloud.ply" ]; then
  "$BIN" -q synth cloud --mesh "$FAM/S05/hand.ply" --rig "$FAM/S05/hand_rig.json" --out "$FAM/S05-cloud" --seed 4 \
    --halves >/dev/null
fi
shot cloud "$BIN" -q run --cloud "$FAM/S05-cloud/cloud.ply" --truth "$FAM/S05-cloud/truth.json" --out "$O"
shot cloud-halves "$BIN" -q run --cloud "$FAM/S05-cloud/a.ply" --cloud "$FAM/S05-cloud/b.ply" \
  --rig "$FAM/S05-cloud/rig.json" --out "$O"
echo "snapshot: stage commands" >&2
shot register "$BIN" -q register --back $FX/back --palm $FX/palm --out "$O"
cp -r "$SNAP/register" "$SCRATCH/reg"
shot skin "$BIN" -q skin --merged "$SCRATCH/reg/merged.ply" --rig $FX/rig.json --out "$O"
shot skin-auto "$BIN" -q skin --merged "$SCRATCH/reg/merged.ply" --out "$O" --baseline
shot patches "$BIN" -q patches --skin-dir "$SCRATCH/run" --out "$O"
FILES=1 shot pose "$BIN" -q pose --skin "$SCRATCH/run/skin.glb" --set index.pip.flex=60 --set thumb.mcp.flex=30 \
  --out "$O/posed.ply" --png "$O/posed.png" --size 256
FILES=1 shot pose-glb "$BIN" -q pose --skin "$SCRATCH/run/skin.glb" --set middle.mcp.flex=70 --blend lbs --out "$O/posed.glb"
mkdir -p "$SCRATCH/keys"
printf 'time,index.mcp.flex,middle.pip.flex\n0,0,0\n0.5,40,60\n1,10,20\n' > "$SCRATCH/keys/keys.csv"
FILES=1 shot animate "$BIN" -q animate --skin "$SCRATCH/run/skin.glb" --keys "$SCRATCH/keys/keys.csv" --fps 10 \
  --out "$O/anim.glb" --csv "$O/anim.csv"
FILES=1 shot render-mesh "$BIN" -q render --mesh "$SCRATCH/run/skin.ply" --rig $FX/rig.json --view palm --size 200 --out "$O/r.png"
FILES=1 shot render-scan "$BIN" -q render --scan $FX/back --size 200 --out "$O/s.png"
FILES=1 shot solve "$BIN" -q solve --model builtin:anatomical --set index.pip.flex=60 --rig $FX/rig.json --json \
  --png "$O/solve.png"
printf 'index.mcp.flex,middle.pip.flex\n0,0\n40,60\n,20\n' > "$SCRATCH/keys/inputs.csv"
FILES=1 shot solve-batch "$BIN" -q solve --model builtin:anatomical --inputs "$SCRATCH/keys/inputs.csv" --out "$O/batch.csv"
shot synth-hand "$BIN" -q synth hand --out "$O" --side left --hand-length 170 --facet-size 3
shot synth-cloud "$BIN" -q synth cloud --mesh "$FAM/S02/hand.ply" --rig "$FAM/S02/hand_rig.json" --out "$O" \
  --seed 6 --spacing 1.2 --halves
shot synth-scan "$BIN" -q synth scan --mesh "$FAM/S02/hand.ply" --rig "$FAM/S02/hand_rig.json" --out "$O" --seed 5 \
  --resolution 200
FILES=1 shot convert "$BIN" -q convert --in $FX/palm --out "$O/palm.pcd"
FILES=1 shot model "$BIN" -q model --model builtin:anatomical --out "$O/model.json"
rm -rf "$SCRATCH"
echo "snapshot: $SNAP" >&2
