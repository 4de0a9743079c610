// SPDX-License-Identifier: Apache-2.0
// Random placement of prototype copies, as Gu et al. 2007 (Sec. 5.3) synthesize lipids
// (fingerprints, smudges: randomly scaled, rotated and tiled copies) and dirt (water streaks:
// the same with limited rotation and translation, "since the water stripes usually are on the
// top"). Each copy is a similarity transform of the prototype's tau map, resampled bilinearly
// (zero outside the prototype); overlapping copies add their tau (the alpha-over of
// coverages 1 - e^{-tau}, docs/models/contamination_synthesis.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct PlacementOptions {
  // Expected coverage: the number of copies is round(density * canvas area / mean copy area),
  // so density 1 puts as much copy area as canvas area. Unitless, [0, 100].
  double density = 0.3;
  double scale_min = 0.7, scale_max = 1.3;                 // Uniform scale of a copy, (0, 16].
  double rotation_min_deg = -180, rotation_max_deg = 180;  // Rotation about the copy centre.
  // Copy centre as a fraction of the canvas, x in [x_min, x_max], y in [y_min, y_max]
  // (0 = left/top edge, 1 = right/bottom).
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;
  // y = y_min + (y_max - y_min) u^top_bias, u uniform: 1 = uniform, > 1 favours the top
  // (the water-streak bias of Gu et al. Sec. 5.3). [1, 10].
  double top_bias = 1;
  // Output pixels per prototype pixel before the random scale (prototype pitch / layer pitch).
  double pitch_ratio = 1;

  bool Check(std::string* error) const;
};

struct PlacedCopy {
  double centre_x_px = 0, centre_y_px = 0;  // Canvas pixel coordinates of the copy centre.
  double scale = 1;                         // Random scale (before pitch_ratio).
  double rotation_deg = 0;
};

// Places copies of `prototype` (channel 0) on a width x height canvas, adding their tau into
// `canvas` (channel 0, created as "tau" if empty). Draws from `rng` in a fixed order, so a
// seed fixes the result. `copies` (optional) receives the transforms used.
Status PlaceCopies(const Image& prototype, int width, int height, const PlacementOptions& options, uint64_t seed,
                   Image* canvas, std::vector<PlacedCopy>* copies);

// Canonical defaults per category: lipid (full rotation, anywhere), dirt (rotation within
// +-10 deg, centres in the top half with top_bias 2), dust (not placed: quilted).
PlacementOptions DefaultPlacementForCategory(const std::string& category);

}  // namespace thinslab
