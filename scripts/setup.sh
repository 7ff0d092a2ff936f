#!/usr/bin/env bash
# Install every Debian package handskin needs (as root, or through sudo). Idempotent: when
# everything is present it returns at once without touching apt.
set -euo pipefail
PACKAGES=(
  build-essential cmake pkg-config clang libclang-rt-14-dev
  libeigen3-dev libpcl-dev mpi-default-dev libflann-dev liblz4-dev libcgal-dev libopenmesh-dev libceres-dev libsuitesparse-dev
  nlohmann-json3-dev libcli11-dev libpng-dev libssl-dev libgtest-dev libgmock-dev libbenchmark-dev libtinygltf-dev libosmesa6-dev libcpp-httplib-dev
  libocct-data-exchange-dev libocct-modeling-algorithms-dev libocct-modeling-data-dev libocct-foundation-dev
  chromium firefox-esr xvfb xauth fonts-dejavu-core blender python3-numpy python3-scipy freecad-python3
  pybind11-dev python3-dev python3-pytest
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Node.js and npm for the front-end tools (web/: the glTF validator); any install will do.
command -v node >/dev/null 2>&1 || missing+=(nodejs)
command -v npm >/dev/null 2>&1 || missing+=(npm)
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
