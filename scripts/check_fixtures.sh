#!/usr/bin/env bash
# Fails when fixtures/default differs from what scripts/make_fixtures.sh produces now.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-./build/handskin}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
bash scripts/make_fixtures.sh "$BIN" "$tmp/default" >/dev/null
if diff -r fixtures/default "$tmp/default"; then
  echo "fixtures/default is up to date"
else
  echo "fixtures/default differs from a fresh regeneration: run scripts/make_fixtures.sh and review"
  exit 1
fi
