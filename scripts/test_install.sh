#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# thinslab as an installed library (issue #25): installs BUILD_DIR into a fresh prefix, checks the
# installed CLI finds its data relative to itself, makes a small capture with it, builds the
# downstream project examples/refit against the prefix (find_package(thinslab), thinslab::refit)
# and checks that its fit through the API, and the installed Python package's (when built), equal
# the installed CLI's `fit tau` of the same capture.
# Usage: scripts/test_install.sh BUILD_DIR. Called by scripts/test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
build=$(realpath "$1")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix
fail() { echo "test_install: $*" >&2; exit 1; }

cmake --install "$build" --prefix "$prefix" > "$work/install.log"
thinslab=$prefix/bin/thinslab
"$thinslab" version | grep -qx "data: $prefix/share/thinslab/data" ||
  fail "the installed CLI does not find $prefix/share/thinslab/data: $("$thinslab" version | tail -1)"
for f in include/thinslab/pipeline/tau_pipeline.h include/thinslab/core/version.h include/thinslab/fit/cost_functions \
         lib/cmake/thinslab/thinslabConfig.cmake share/thinslab/data/patterns/demo_contamination.exr share/doc/thinslab/format.md \
         share/bash-completion/completions/thinslab; do
  [ -e "$prefix/$f" ] || fail "not installed: $f"
done
if find "$prefix/include" -name '*test*' | grep -q .; then fail "test helpers installed under include/"; fi

# A small capture with the bundled demo pattern (found through the installed data folder).
"$thinslab" sim shadow-maps "$work/capture" --camera-width-px 200 --camera-height-px 150 --photons 20000 \
  --frames 2 > "$work/sim.log" 2>&1 || { cat "$work/sim.log"; fail "the installed CLI's sim shadow-maps failed"; }
"$thinslab" fit tau "$work/capture" --out "$work/cli_fit" > "$work/cli_fit.log" 2>&1 ||
  { cat "$work/cli_fit.log"; fail "the installed CLI's fit tau failed"; }

cmake -S examples/refit -B "$work/example" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" \
  > "$work/example_configure.log" || { cat "$work/example_configure.log"; fail "examples/refit does not configure"; }
cmake --build "$work/example" > "$work/example_build.log" || { cat "$work/example_build.log"; fail "examples/refit does not build"; }
"$work/example/refit_tau" "$work/capture" "$work/api_fit" > "$work/api_fit.log" 2>&1 ||
  { cat "$work/api_fit.log"; fail "refit_tau failed"; }
grep -q '"result": "success"' "$work/api_fit/summary.json" || fail "the API fit did not succeed"
# Same capture, same options: the same map, so the same comparison with the ground truth.
cmp -s "$work/api_fit/comparison.json" "$work/cli_fit/comparison.json" ||
  fail "the API fit and the CLI fit differ: $(diff "$work/api_fit/comparison.json" "$work/cli_fit/comparison.json" | head -5)"
# An install with the Aravis back-end also serves a program that links thinslab::devices.
if grep -qE "set\(THINSLAB_WITH_ARAVIS (ON|1|TRUE|YES)\)" "$prefix/lib/cmake/thinslab/thinslabConfig.cmake"; then
  "$work/example/camera_options" 127.0.0.1 > /dev/null || fail "camera_options (thinslab::devices) failed"
elif [ -e "$work/example/camera_options" ]; then
  fail "camera_options was built against an install without Aravis"
fi
# The Python package, when built: importable from the prefix, finding the install's data.
if [ -d "$prefix"/lib/python3*/dist-packages/thinslab ]; then
  site=$(echo "$prefix"/lib/python3*/dist-packages)
  python=$(sed -n 's/^Python3_EXECUTABLE:[A-Z]*=//p' "$build/CMakeCache.txt")
  (cd "$work" && PYTHONPATH="$site" "${python:-python3}" -c "
import os, thinslab
assert os.environ['THINSLAB_DATA_DIR'] == '$prefix/share/thinslab/data', os.environ.get('THINSLAB_DATA_DIR')
fit = thinslab.fit_tau('$work/capture', out='$work/python_fit')
assert fit.summary['result'] == 'success' and fit.maps['tau'].shape == tuple(fit.summary['grid'][::-1])
print('python', thinslab.__version__, 'from', thinslab.__file__)") > "$work/python.log" 2>&1 ||
    { cat "$work/python.log"; fail "the installed Python package does not work"; }
  cmp -s "$work/python_fit/comparison.json" "$work/cli_fit/comparison.json" ||
    fail "the Python fit and the CLI fit differ"
fi
echo "test_install: $build installed, examples/refit built against it, API fit = CLI fit"
