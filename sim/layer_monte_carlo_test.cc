// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/layer_monte_carlo.h"

#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/optics/dirty_glass.h"

namespace thinslab {
namespace {

// Brute-force Monte Carlo checks the analytic single-scattering model (Gu et al. 2007
// Eq. 6): the first-order exit radiance agrees bin by bin where the bins hold enough photons.
TEST(LayerMonteCarlo, FirstOrderMatchesGuEq6) {
  LayerMonteCarloOptions options;
  options.albedo = 0.5;
  options.g = 0.6;
  options.num_photons = 400000;
  options.num_mu_bins = 16;
  for (double tau : {0.1, 0.8}) {
    const LayerExitDistribution dist = SimulateLayer(tau, options);
    EXPECT_NEAR(dist.direct, std::exp(-tau), 4 * std::sqrt(std::exp(-tau) / options.num_photons));
    for (int b = 4; b < 16; ++b) {
      // Bin average of the analytic radiance weighted by mu (the histogram counts flux).
      double num = 0, den = 0;
      for (int k = 0; k < 200; ++k) {
        const double mu = (b + (k + 0.5) / 200) / 16;
        num += LayerSingleScatterRadiance(tau, mu, 0.5, 0.6) * mu;
        den += mu;
      }
      const double analytic = num / den;
      EXPECT_NEAR(dist.single_scatter[b] / analytic, 1.0, 0.05) << "tau=" << tau << " bin=" << b;
    }
  }
}

// Energy: transmitted + absorbed + reflected = 1, so transmitted scattered + direct <= 1, and
// with albedo 0 nothing is scattered.
TEST(LayerMonteCarlo, EnergyAndAbsorberLimits) {
  LayerMonteCarloOptions options;
  options.num_photons = 50000;
  options.albedo = 1.0;
  options.g = 0.8;
  const LayerExitDistribution dist = SimulateLayer(1.0, options);
  double transmitted = dist.direct;
  const int n = static_cast<int>(dist.single_scatter.size());
  for (int b = 0; b < n; ++b) {
    const double mu = (b + 0.5) / n;
    transmitted += (dist.single_scatter[b] + dist.multiple_scatter[b]) * mu * 2 * kPi / n;
  }
  EXPECT_LE(transmitted, 1.0 + 1e-9);
  EXPECT_GT(transmitted, 0.8);  // g = 0.8, albedo 1: most light still goes forward.
  options.albedo = 0.0;
  const LayerExitDistribution absorber = SimulateLayer(1.0, options);
  for (int b = 0; b < n; ++b) EXPECT_EQ(absorber.single_scatter[b] + absorber.multiple_scatter[b], 0.0);
}

}  // namespace
}  // namespace thinslab
