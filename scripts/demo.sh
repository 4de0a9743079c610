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
# A whole acquisition through the driver interfaces on the simulated CRT-monitor rig: a 6 x 6
# dot scan with a two-exposure bracket per dot, resumable with --resume (docs/acquisition.md).
rm -rf demo_out/acquire_dot_scan
./build/app/thinslab acquire dot-scan demo_out/acquire_dot_scan --grid-nx 6 --grid-ny 6 --exposures-us 20000,80000 \
  --camera-width-px 320 --camera-height-px 240
./build/app/thinslab info demo_out/acquire_dot_scan | tail -n 4
