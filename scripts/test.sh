#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# THE test command (README, .ci/run): installs Debian packages, configures, builds, runs every
# test; installs and builds a downstream project against the install; builds the refit-only
# (device-free) tree and runs the device-free stages' tests there; then, unless THINSLAB_SKIP_SANITIZERS=1, rebuilds with ASan+UBSan and runs every test
# again except those labelled `matrix` (simulation-heavy stability and knob sweeps and the heavier
# cases of the e2e tests, whose code the remaining cases run under the sanitizers: the laser
# lobe's seed and g entries, the 10-mm dirty-glass board, the dmf CLI ladder, the tau/g stability
# matrix, the acquired dot-scan chain of cli_gamma_test, the Blender round trip).
# Measured on the 2-core CI machine: see docs/benchmarks.md (CI time).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
jobs=$(nproc)
# The Python tests use Debian's interpreter, whose numpy, pytest and matplotlib install_deps.sh
# installs (not another python3 earlier on PATH, e.g. pyenv's).
python=/usr/bin/python3
# ccache (the project's own cache in build-ccache/): the refit-only tree compiles the same sources
# with the same flags as build/, so it is served from the cache except app/ (its device defines).
# CCACHE_BASEDIR makes the two trees' absolute paths relative, so their commands hash alike.
launcher=()
if command -v ccache > /dev/null; then
  export CCACHE_DIR="$PWD/build-ccache" CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1 CCACHE_MAXSIZE=5G
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DTHINSLAB_WERROR=ON -DPython3_EXECUTABLE="$python" "${launcher[@]}"
cmake --build build -j"$jobs"
(cd build && ctest --output-on-failure -j"$jobs")
# Installed: the CLI finds its data, a downstream project builds against the prefix (issue #25).
bash scripts/test_install.sh build

# The refit-only tree (issue #25), on a machine without the device libraries (Aravis and
# umockdev; SDL2's and libusb's development files, whose runtimes Blender and OpenCV's videoio
# need), Google Benchmark and Open MPI's development files and tools: scripts/without_packages.py
# hides their installed files in a private mount namespace (where root and unshare(2) allow one;
# else it says so, and scripts/test_refit_tree.sh's build.ninja and ldd checks remain).
hidden_packages=libaravis-dev,libaravis-0.8-0,gir1.2-aravis-0.8,libsdl2-dev,libusb-1.0-0-dev
hidden_packages+=,libumockdev-dev,libumockdev0,gir1.2-umockdev-1.0,umockdev,libbenchmark-dev,libbenchmark1debian
hidden_packages+=,libopenmpi-dev,openmpi-bin,libcoarrays-openmpi-dev
"$python" scripts/without_packages.py "$hidden_packages" bash scripts/test_refit_tree.sh "$python" "${launcher[@]}"

if [ "${THINSLAB_SKIP_SANITIZERS:-0}" != "1" ]; then
  # -g1: line tables and function names, all the sanitizers' stack traces need; full debug info
  # made the sanitizer build about half of the CI time (docs/benchmarks.md, CI). -O1, as the
  # AddressSanitizer documentation advises: -O2 with UBSan took 1.3-1.8x longer to compile.
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTHINSLAB_SANITIZE=ON \
    -DTHINSLAB_BUILD_BENCH=OFF -DTHINSLAB_WERROR=ON -DTHINSLAB_WITH_PYTHON=OFF \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG"
  # Only what the pass runs: the binary and the executables of the tests not labelled `matrix`.
  cmake --build build-asan -j"$jobs" --target thinslab thinslab_sanitizer_tests
  # System libraries (glib, SDL, X11) keep some allocations until exit; scripts/lsan.supp lists
  # those by library name only, never thinslab code.
  lsan_options=""
  [ -f scripts/lsan.supp ] && lsan_options="suppressions=$PWD/scripts/lsan.supp"
  (cd build-asan && ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS="$lsan_options" UBSAN_OPTIONS=print_stacktrace=1 \
    ctest --output-on-failure -j"$jobs" -LE matrix)
fi
echo "thinslab: all tests passed"
