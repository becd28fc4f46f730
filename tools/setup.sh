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
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j2
