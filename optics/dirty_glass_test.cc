// SPDX-License-Identifier: Apache-2.0
#include "thinslab/optics/dirty_glass.h"

#include <gtest/gtest.h>

namespace thinslab {
namespace {

// Total single-scattered power leaving the bottom of a thin layer, per unit incident
// irradiance: integral of L mu d omega over the lower hemisphere.
double TransmittedSingleScatter(double tau, double albedo, double g) {
  const int n = 20000;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double mu = (i + 0.5) / n;
    sum += LayerSingleScatterRadiance(tau, mu, albedo, g) * mu * 2.0 * kPi / n;
  }
  return sum;
}

// For tau -> 0 the layer scatters omega0 * tau of the light once, and the forward hemisphere
// receives the part of the phase function with cos >= 0.
TEST(DirtyGlass, ThinLayerLimitScattersAlbedoTimesTau) {
  const double tau = 1e-4, albedo = 0.3;
  for (double g : {0.0, 0.8}) {
    double forward = 0;
    const int n = 20000;
    for (int i = 0; i < n; ++i) forward += HenyeyGreenstein((i + 0.5) / n, g) * 2.0 * kPi / n;
    EXPECT_NEAR(TransmittedSingleScatter(tau, albedo, g) / (albedo * tau * forward), 1.0, 1e-3);
  }
}

// Energy: direct plus single-scattered transmission never exceeds 1, and single scattering
// alone never exceeds what the layer removed from the direct beam times the albedo.
TEST(DirtyGlass, EnergyBounded) {
  for (double tau : {0.01, 0.3, 1.0, 3.0}) {
    for (double g : {0.0, 0.8, 0.95}) {
      const double scattered = TransmittedSingleScatter(tau, 1.0, g);
      EXPECT_LE(scattered, 1.0 - LayerDirectTransmittance(tau) + 1e-6);
      EXPECT_GE(scattered, 0.0);
    }
  }
}

TEST(DirtyGlass, GrazingAndNormalLimitsAreFinite) {
  EXPECT_NEAR(LayerSingleScatterRadiance(0.5, 1.0, 1.0, 0.0),
              kInv4Pi * 0.5 * std::exp(-0.5), 1e-12);
  const double near_one = LayerSingleScatterRadiance(0.5, 1.0 - 1e-9, 1.0, 0.0);
  EXPECT_NEAR(near_one, kInv4Pi * 0.5 * std::exp(-0.5), 1e-6);
  EXPECT_TRUE(std::isfinite(LayerSingleScatterRadiance(0.5, 1e-6, 1.0, 0.8)));
}

}  // namespace
}  // namespace thinslab
