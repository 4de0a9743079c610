#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# THE demo command (README): installs Debian packages, builds, simulates a shadow-map capture
# of the bundled contamination pattern, fits tau and prints the error against ground truth.
# Extra arguments go to `thinslab demo` (e.g. --board-distance-mm 10).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target thinslab
./build/app/thinslab demo --out demo_out "$@"
