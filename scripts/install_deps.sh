#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs every Debian 12 package thinslab needs. Idempotent: packages already
# installed are skipped, so a second run costs one dpkg query.
set -euo pipefail

packages=(
  build-essential
  cmake
  ninja-build
  ccache
  pkg-config
  libceres-dev
  libeigen3-dev
  libgoogle-glog-dev
  libgflags-dev
  libopencv-dev
  opencv-doc
  libopenexr-dev
  libaravis-dev
  libusb-1.0-0-dev
  libsdl2-dev
  xvfb
  x11-apps
  umockdev
  libumockdev-dev
  libgtest-dev
  libgmock-dev
  libbenchmark-dev
  nlohmann-json3-dev
  libcli11-dev
  openexr
  gnuplot-nox
  pybind11-dev
  python3-dev
  python3-numpy
  python3-pytest
  python3-matplotlib
  python3-openimageio
  python3-opencv
  chromium
  blender
  bc
  libopenmpi-dev
  openmpi-bin
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install_deps: installing ${missing[*]}"
sudo_cmd=()
[ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
