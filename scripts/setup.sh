#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# THE setup command (README): installs the Debian packages, builds thinslab (Release) and installs
# it into PREFIX (default /usr/local): bin/thinslab, the libraries and headers with
# lib/cmake/thinslab (find_package(thinslab)), share/thinslab/data, the docs, and the Python
# package thinslab (lib/python3.X/dist-packages, on Debian's python3 path for /usr/local).
# Usage: bash scripts/setup.sh [PREFIX]. Needs root or sudo for /usr/local.
set -euo pipefail
cd "$(dirname "$0")/.."
prefix=${1:-/usr/local}
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=/usr/bin/python3
cmake --build build -j"$(nproc)"
cmake --install build --prefix "$prefix"
echo "thinslab installed into $prefix: $("$prefix/bin/thinslab" version | head -1)"
