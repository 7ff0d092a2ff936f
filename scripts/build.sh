#!/usr/bin/env bash
# Configure (once) and build handskin into build/. Incremental on re-runs.
set -euo pipefail
cd "$(dirname "$0")/.."
JOBS=${JOBS:-$(nproc)}
if [ ! -f build/CMakeCache.txt ]; then
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
fi
cmake --build build -j "$JOBS"
bash scripts/install_python.sh
