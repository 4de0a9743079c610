// SPDX-License-Identifier: Apache-2.0
// Henyey-Greenstein phase function, as used by Gu et al. 2007 (Sec. 3.1) for p(theta).
// p(cos_theta; g) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos_theta)^(3/2)); integrates to 1 over
// the sphere. g is the mean cosine of the scattering angle (unitless, (-1, 1)); cos_theta is
// the cosine between the propagation directions before and after scattering.
#pragma once

#include <cmath>

#include "thinslab/core/math.h"

namespace thinslab {

template <typename T>
T HenyeyGreenstein(const T& cos_theta, const T& g) {
  using std::pow;
  const T denom = T(1) + g * g - T(2) * g * cos_theta;
  return (T(1) - g * g) * T(kInv4Pi) / (denom * sqrt(denom));
}

// Samples cos_theta with density proportional to HenyeyGreenstein(., g) (times 2 pi), from a
// uniform u in [0, 1). Standard inversion (e.g. pbrt-v4 SampleHenyeyGreenstein).
inline double SampleHenyeyGreensteinCosTheta(double u, double g) {
  if (std::abs(g) < 1e-3) return 1.0 - 2.0 * u;
  const double s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u);
  return Clamp((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0);
}

}  // namespace thinslab
