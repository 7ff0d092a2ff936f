#!/usr/bin/env bash
# Install the front-end packages web/package-lock.json pins (npm registry) into
# web/node_modules. Idempotent: skips npm when they are already there.
set -euo pipefail
cd "$(dirname "$0")/../web"
if [ -d node_modules/gltf-validator ] && [ -d node_modules/three ] && [ -d node_modules/playwright-core ] && [ -d node_modules/puppeteer-core ] && [ -x node_modules/.bin/esbuild ] &&
   [ node_modules/.package-lock.json -nt package-lock.json ]; then
  echo "npm: web/node_modules up to date"
  exit 0
fi
npm ci --no-audit --no-fund --loglevel=error
