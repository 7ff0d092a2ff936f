#!/usr/bin/env bash
# Newcomer command 2: install, build, and run every test (unit, end-to-end, fuzz).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/npm.sh
bash scripts/build.sh
cd build
ctest --output-on-failure -j "${JOBS:-2}" "$@"
