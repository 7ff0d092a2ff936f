#!/usr/bin/env bash
# Build the libFuzzer targets of the readers (scan, rig, angle CSV, posture model, motion capture,
# pipeline file; the scan, model and pipeline targets also substitute extreme numbers) with clang (a separate build tree)
# and run each for a fixed number of inputs from a fixed seed, so a run is reproducible
# (a time cap guards slow machines: 180 s a target, so that the six and the clang build stay
# within the test's 1500 s; on 2026-12-02's machine, idle, the targets took 27-172 s for their
# 500 000 inputs, and 785 s in all inside CI, beside the other tests).
# Usage: scripts/fuzz.sh [runs-per-target] [seed]
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-500000}
SEED=${2:-1}
if [ ! -f build-fuzz/CMakeCache.txt ]; then
  CC=clang CXX=clang++ cmake -S . -B build-fuzz -DHANDSKIN_FUZZ_ONLY=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
fi
cmake --build build-fuzz -j "${JOBS:-2}" >/dev/null
corpus="" log=""
trap 'rm -rf "$corpus"; rm -f "$log"' EXIT  # the working corpus and log, also when a target fails
for target in scan rig angles model mocap pipeline; do
  corpus=$(mktemp -d)
  cp fuzz/corpus/"$target"/* "$corpus"/ 2>/dev/null || true
  echo "fuzz: $target, $RUNS inputs from seed $SEED"
  log=$(mktemp)
  set +e
  ./build-fuzz/fuzz_"$target" -runs="$RUNS" -seed="$SEED" -max_total_time=180 -max_len=65536 -rss_limit_mb=2048 \
    -print_final_stats=1 "$corpus" >"$log" 2>&1
  rc=$?
  set -e
  grep -E "^stat::number_of_executed_units|^Done" "$log" || true
  if [ "$rc" -ne 0 ]; then
    tail -n 60 "$log"
    echo "fuzz: $target FAILED (exit $rc)"
    exit "$rc"
  fi
  rm -f "$log"
  rm -rf "$corpus"
done
