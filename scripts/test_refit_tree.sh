#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The refit-only tree (issue #25): configured with every device back-end, Google Benchmark and
# MPI off, built, checked to name and link no device library, its device-free stages' tests
# (label `refit`) run, and its install serving the downstream project. Called by scripts/test.sh
# through scripts/without_packages.py, which hides the device, benchmark and MPI packages (as on
# a machine without them) where it can make a private mount namespace.
# Usage: scripts/test_refit_tree.sh PYTHON [CMAKE_ARGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
python=$1
shift
jobs=$(nproc)
cmake -S . -B build-refit -G Ninja -DCMAKE_BUILD_TYPE=Release -DTHINSLAB_WERROR=ON -DTHINSLAB_BUILD_BENCH=OFF \
  -DPython3_EXECUTABLE="$python" "$@" \
  -DTHINSLAB_WITH_ARAVIS=OFF -DTHINSLAB_WITH_V4L2=OFF -DTHINSLAB_WITH_SDL=OFF -DTHINSLAB_WITH_USB=OFF -DTHINSLAB_WITH_MPI=OFF
if grep -iE "aravis|sdl2|libusb|umockdev|benchmark|openmpi" build-refit/build.ninja | grep -qv "THINSLAB_WITH_"; then
  echo "thinslab: the refit-only tree refers to a device, benchmark or MPI library:" >&2
  grep -ioE "[^ ]*(aravis|sdl2|libusb|umockdev|benchmark|openmpi)[^ ]*" build-refit/build.ninja |
    grep -v THINSLAB_WITH_ | sort -u >&2
  exit 1
fi
cmake --build build-refit -j"$jobs" --target thinslab thinslab_refit_tests
if command -v ccache > /dev/null && [ -n "${CCACHE_DIR:-}" ]; then ccache --show-stats | grep -E "Hits|Misses" || true; fi
# libusb-1.0 itself may be present: OpenCV's videoio links it (Debian's libopencv-videoio).
for binary in build-refit/app/thinslab build-refit/python/thinslab/_thinslab*.so; do
  [ -e "$binary" ] || continue
  if ldd "$binary" | grep -iE "aravis|SDL2|libusb|umockdev|benchmark|libmpi"; then
    echo "thinslab: $binary of the refit-only tree links a device, benchmark or MPI library" >&2
    exit 1
  fi
done
(cd build-refit && ctest --output-on-failure -j"$jobs" -L refit)
bash scripts/test_install.sh build-refit
