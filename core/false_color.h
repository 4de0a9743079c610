// SPDX-License-Identifier: Apache-2.0
// False-colour PNG of one image channel (viridis) with a labelled colour bar, written
// atomically. Pixels where `mask` (optional, same size) is non-zero are drawn grey.
#pragma once

#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct FalseColorOptions {
  double min_value = 0;
  double max_value = 1;
  std::string label;  // Shown above the colour bar, e.g. "tau".
  int scale = 2;      // Nearest-neighbour magnification of small maps.
};

Status WriteFalseColorPng(const std::string& path, const Image& image, int channel, const Image* mask,
                          const FalseColorOptions& options);

}  // namespace thinslab
