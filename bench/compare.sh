#!/usr/bin/env bash
# Every benchmark's ratio between a revision and this tree, in one run (issue 39):
#
#   bench/compare.sh REV [FILTER] [ROUNDS]
#
# Builds REV's handskin_bench in a git worktree (build-compare/<REV's short hash>, kept for the
# next comparison against the same REV: a first build takes ~15 min on 2 cores), and this
# tree's into build/ (scripts/build.sh's folder; uncommitted changes included). Then runs the two
# benchmarks in turn ROUNDS times (default 3; alternating, so that the machine's drift falls
# on both), with --benchmark_filter=FILTER (default: all), and prints a Markdown table of each
# benchmark's median time on either side and their ratio (bench/compare_table.py). The JSON
# of every run stays in build-compare/runs/.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 1 ] || [ $# -gt 3 ]; then
  echo "usage: bench/compare.sh REV [FILTER] [ROUNDS]" >&2
  exit 2
fi
REV=$1
FILTER=${2:-.}
ROUNDS=${3:-3}
case "$ROUNDS" in '' | *[!0-9]* | 0) echo "error: ROUNDS must be a whole number >= 1, not '$ROUNDS'" >&2; exit 2 ;; esac
base=$(git rev-parse --verify --quiet "$REV^{commit}") || { echo "error: $REV: not a revision of this repository" >&2; exit 2; }
short=$(git rev-parse --short "$base")
JOBS=${JOBS:-$(nproc)}
wt=build-compare/$short
if [ ! -d "$wt" ]; then
  git worktree add --detach "$wt" "$base" >/dev/null
fi
echo "compare: building $short's benchmarks in $wt" >&2
[ -f "$wt/build/CMakeCache.txt" ] || cmake -S "$wt" -B "$wt/build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$wt/build" -j "$JOBS" --target handskin_bench >/dev/null
echo "compare: building this tree's benchmarks in build/" >&2
[ -f build/CMakeCache.txt ] || cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$JOBS" --target handskin_bench >/dev/null
runs=build-compare/runs/$short-$(date +%Y%m%d-%H%M%S)
mkdir -p "$runs"
for r in $(seq 1 "$ROUNDS"); do
  for side in base head; do
    bin=$([ $side = base ] && echo "$wt/build/bench/handskin_bench" || echo build/bench/handskin_bench)
    echo "compare: round $r of $ROUNDS, $side" >&2
    "$bin" --benchmark_filter="$FILTER" --benchmark_format=json --benchmark_out="$runs/$side-$r.json" \
      --benchmark_out_format=json >/dev/null
  done
done
python3 bench/compare_table.py --base "$runs"/base-*.json --head "$runs"/head-*.json --base-name "$short" --head-name HEAD
