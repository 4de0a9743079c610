// SPDX-License-Identifier: Apache-2.0
// False-colour PNG of one image channel with its legend, written atomically: a sequential
// colour bar (viridis) for magnitudes, a diverging one (blue-white-red, symmetric about 0) for
// signed quantities, or a named legend for categories (status codes). An optional scale bar in
// mm when the map's pitch is known. Pixels where `mask` (optional, same size) is non-zero are
// drawn grey.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

enum class ColorScale { kSequential, kDiverging, kCategorical };

struct FalseColorOptions {
  ColorScale scale_kind = ColorScale::kSequential;
  double min_value = 0;  // kDiverging uses +-max(|min_value|, |max_value|).
  double max_value = 1;
  std::string label;  // Shown above the colour bar or legend, e.g. "tau".
  // kCategorical: the name of code k (the pixel value, an integer); codes outside are drawn grey.
  std::vector<std::string> category_names;
  int scale = 2;              // Nearest-neighbour magnification of small maps.
  double pixel_pitch_m = 0;   // > 0: a scale bar in mm.
};

Status WriteFalseColorPng(const std::string& path, const Image& image, int channel, const Image* mask,
                          const FalseColorOptions& options);

}  // namespace thinslab
