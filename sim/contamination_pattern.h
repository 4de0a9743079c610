// SPDX-License-Identifier: Apache-2.0
// Procedural contamination textures tau(x, y) for the simulated rig: fingerprint ridges
// (lipid), dust specks, a water streak (dirt) and clean glass, as in Gu et al. 2007 Fig. 10.
#pragma once

#include <cstdint>

#include "thinslab/core/image.h"

namespace thinslab {

struct ContaminationPatternOptions {
  int width_px = 200;
  int height_px = 200;
  double max_tau = 1.5;  // Densest dust speck; fingerprint ridges reach about 0.6.
  int num_dust_specks = 30;
  uint64_t seed = 1;
};

// Channel "tau", unitless optical thickness >= 0, band-limited (features >= 2 px wide) so a
// rectified capture can resolve it. Roughly a third of the area is left clean.
Image GenerateContaminationPattern(const ContaminationPatternOptions& options);

}  // namespace thinslab
