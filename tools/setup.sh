#!/usr/bin/env bash
# Installs the Debian 12 packages SweptCCD needs (deploy/debian-packages.txt)
# and builds it into build/ (Release, -j2).
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
packages=$(grep -v '^#' deploy/debian-packages.txt)
# NodeSource's nodejs bundles npm and conflicts with Debian's npm package:
# Debian's npm only where no npm is installed (deploy/debian-packages.txt).
if command -v npm >/dev/null 2>&1; then packages=$(grep -vx npm <<< "$packages"); fi
# shellcheck disable=SC2086
$SUDO apt-get install -y -qq --no-install-recommends $packages >/dev/null
# With ccache where it is installed (CI adds it): paths relative to the
# checkout, so a clone in another folder reuses an earlier build's objects.
launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD}
fi
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
cmake --build build -j2
