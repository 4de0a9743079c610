// SPDX-License-Identifier: Apache-2.0
// Camera sensor: photo-electrons -> shot noise (Poisson), read noise (Gaussian), conversion
// gain, black level, quantisation to bit_depth and clipping at full scale (saturation).
#pragma once

#include <cstdint>
#include <random>
#include <string>

#include "core/image.h"

namespace thinslab {

struct SimSensorOptions {
  double full_well_e = 30000;  // Electrons at full scale.
  double read_noise_e = 6;     // RMS electrons.
  int bit_depth = 12;
  double black_level_dn = 64;
  bool enable_noise = true;

  double gain_e_per_dn() const { return full_well_e / ((1 << bit_depth) - 1 - black_level_dn); }
  double saturation_dn() const { return (1 << bit_depth) - 1; }
  bool Check(std::string* error) const;
};

// Converts an image of expected electrons to raw DN (integers stored as float).
Image ApplySensor(const Image& electrons, const SimSensorOptions& options, uint64_t seed);

}  // namespace thinslab
