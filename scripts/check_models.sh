#!/usr/bin/env bash
# Fails when models/ differs from what scripts/make_models.sh produces now.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-./build/handskin}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
bash scripts/make_models.sh "$BIN" "$tmp/models" >/dev/null
if diff -r models "$tmp/models"; then
  echo "models/ is up to date"
else
  echo "models/ differs from a fresh regeneration: run scripts/make_models.sh and review"
  exit 1
fi
