// SPDX-License-Identifier: Apache-2.0
#include "sim/sensor_model.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace thinslab {

bool SimSensorOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(full_well_e > 0)) {
    msg << "SimSensorOptions::full_well_e = " << full_well_e << ". Violated constraint: > 0";
  } else if (!(read_noise_e >= 0)) {
    msg << "SimSensorOptions::read_noise_e = " << read_noise_e << ". Violated constraint: >= 0";
  } else if (bit_depth < 8 || bit_depth > 16) {
    msg << "SimSensorOptions::bit_depth = " << bit_depth << ". Violated constraint: 8..16";
  } else if (!(black_level_dn >= 0 && black_level_dn < (1 << bit_depth) / 2)) {
    msg << "SimSensorOptions::black_level_dn = " << black_level_dn << ". Violated constraint: [0, 2^bit_depth / 2)";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

Image ApplySensor(const Image& electrons, const SimSensorOptions& options, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double gain = options.gain_e_per_dn();
  const double max_dn = options.saturation_dn();
  Image raw(electrons.width(), electrons.height());
  for (size_t i = 0; i < raw.data().size(); ++i) {
    double e = std::max(0.0, static_cast<double>(electrons.data()[i]));
    if (options.enable_noise) {
      if (e < 30) {
        e = std::poisson_distribution<int>(e)(rng);
      } else {
        e += std::sqrt(e) * normal(rng);
      }
      e += options.read_noise_e * normal(rng);
    }
    const double dn = std::round(e / gain + options.black_level_dn);
    raw.data()[i] = static_cast<float>(std::clamp(dn, 0.0, max_dn));
  }
  return raw;
}

}  // namespace thinslab
