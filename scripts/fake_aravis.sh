#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Starts Aravis's stand-alone GigE Vision fake camera on the loopback interface for manual
# trials, e.g. in another shell:  thinslab acquire ... --camera aravis:127.0.0.1
# Only one fake can serve UDP port 3956 per address: stop this one (Ctrl-C) before running
# tests/aravis_fake_camera_test, which starts its own in-process. Its image is Aravis's test
# pattern, not the simulated rig (the test's in-process fake is the one fed by sim/).
# Usage: scripts/fake_aravis.sh [interface, default lo] [serial, default THINSLAB01]
set -euo pipefail
interface="${1:-lo}"
serial="${2:-THINSLAB01}"
binary="$(command -v arv-fake-gv-camera-0.8 || true)"
if [ -z "$binary" ]; then
  echo "fake_aravis.sh: arv-fake-gv-camera-0.8 not found; it ships in Debian's aravis-tools package" \
       "(apt-get install aravis-tools)" >&2
  exit 1
fi
echo "fake_aravis.sh: serving GigE Vision fake camera '$serial' on $interface (Ctrl-C stops it)" >&2
exec "$binary" -i "$interface" -s "$serial"
