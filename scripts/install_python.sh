#!/usr/bin/env bash
# Make the system python3 import handskin from this build (docs/python.md): a .pth file in its
# site-packages (root: /usr/local/lib/python3.X/dist-packages; otherwise the user's site)
# naming build/python, where the build assembles the package. Idempotent; run by build.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-/usr/bin/python3}
[ -x "$PY" ] || { echo "install_python: no $PY" >&2; exit 1; }
pkg="$(pwd)/build/python"
[ -f "$pkg/handskin/__init__.py" ] || { echo "install_python: $pkg/handskin is not built" >&2; exit 1; }
site=$("$PY" -c 'import site; print(site.getsitepackages()[0])')
if ! { mkdir -p "$site" 2>/dev/null && [ -w "$site" ]; }; then
  site=$("$PY" -m site --user-site)
  mkdir -p "$site"
fi
if [ "$(cat "$site/handskin.pth" 2>/dev/null)" != "$pkg" ]; then
  echo "$pkg" > "$site/handskin.pth"
  echo "install_python: $PY imports handskin from $pkg ($site/handskin.pth)"
fi
