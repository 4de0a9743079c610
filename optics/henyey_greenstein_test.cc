// SPDX-License-Identifier: Apache-2.0
#include "thinslab/optics/henyey_greenstein.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace thinslab {
namespace {

// Integral of p over the sphere by midpoint rule in cos_theta.
double SphereIntegral(double g) {
  const int n = 200000;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double mu = -1.0 + (i + 0.5) * 2.0 / n;
    sum += HenyeyGreenstein(mu, g) * 2.0 * kPi * (2.0 / n);
  }
  return sum;
}

double MeanCosine(double g) {
  const int n = 200000;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double mu = -1.0 + (i + 0.5) * 2.0 / n;
    sum += mu * HenyeyGreenstein(mu, g) * 2.0 * kPi * (2.0 / n);
  }
  return sum;
}

TEST(HenyeyGreenstein, NormalizedAndMeanCosineIsG) {
  for (double g : {-0.9, -0.3, 0.0, 0.5, 0.8, 0.95}) {
    EXPECT_NEAR(SphereIntegral(g), 1.0, 1e-3) << "g=" << g;
    EXPECT_NEAR(MeanCosine(g), g, 2e-3) << "g=" << g;
  }
}

TEST(HenyeyGreenstein, SignOfGSetsScatteringDirection) {
  EXPECT_GT(HenyeyGreenstein(1.0, 0.95), 100 * HenyeyGreenstein(-1.0, 0.95));
  EXPECT_GT(HenyeyGreenstein(-1.0, -0.95), 100 * HenyeyGreenstein(1.0, -0.95));
}

// Chi-square test of the sampler against the density in 20 cos_theta bins (expected counts
// >= 5), significance 0.01 (critical value for 19 dof: 36.19).
TEST(HenyeyGreenstein, SamplingMatchesDensityChiSquare) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (double g : {-0.9, 0.0, 0.5, 0.95}) {
    const int bins = 20, n = 200000;
    std::vector<double> observed(bins, 0), expected(bins, 0);
    for (int i = 0; i < n; ++i) {
      const double mu = SampleHenyeyGreensteinCosTheta(uni(rng), g);
      observed[std::min(bins - 1, static_cast<int>((mu + 1.0) / 2.0 * bins))] += 1;
    }
    for (int b = 0; b < bins; ++b) {
      const int sub = 2000;
      for (int k = 0; k < sub; ++k) {
        const double mu = -1.0 + (b + (k + 0.5) / sub) * 2.0 / bins;
        expected[b] += n * HenyeyGreenstein(mu, g) * 2.0 * kPi * (2.0 / bins / sub);
      }
    }
    double chi2 = 0;
    int dof = -1;
    for (int b = 0; b < bins; ++b) {
      if (expected[b] < 5) continue;
      chi2 += Sqr(observed[b] - expected[b]) / expected[b];
      ++dof;
    }
    ASSERT_EQ(dof, 19) << "g=" << g;
    EXPECT_LT(chi2, 36.19) << "g=" << g;
  }
}

}  // namespace
}  // namespace thinslab
