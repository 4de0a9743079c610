// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/ladder_choice.h"

#include <gtest/gtest.h>

namespace thinslab {
namespace {

TEST(SimplestRungWithinNoise, KeepsTheSimplestRungWhoseExcessIsWithinNoise) {
  // Rung 1 is best by 0.1 per measurement, but the paired differences scatter by ~1: within noise.
  const std::vector<double> noisy_a = {1.0, 3.0, 0.5, 2.5, 1.0, 3.0, 0.5, 2.5};
  std::vector<double> noisy_b = noisy_a;
  for (size_t k = 0; k < noisy_b.size(); ++k) noisy_b[k] += (k % 2 ? -1.0 : 0.8);
  EXPECT_EQ(SimplestRungWithinNoise({noisy_a, noisy_b}, 2.0), 0);
  // The same excess with no scatter of the differences is significant.
  std::vector<double> shifted = noisy_a;
  for (double& e : shifted) e -= 0.1;
  EXPECT_EQ(SimplestRungWithinNoise({noisy_a, shifted}, 2.0), 1);
}

TEST(SimplestRungWithinNoise, AnExcessBelowTheMeasurementNoiseIsWithinNoiseHoweverLargeThePool) {
  // 10000 measurements: rung 0 misses each by 0.01 more than rung 1, with no scatter, so the
  // paired test alone resolves it; the measurements' own variance is 0.02 per measurement.
  const std::vector<double> best(10000, 0.03), simpler(10000, 0.04);
  EXPECT_EQ(SimplestRungWithinNoise({simpler, best}, 2.0), 1);
  EXPECT_EQ(SimplestRungWithinNoise({simpler, best}, 2.0, std::vector<double>(10000, 0.02)), 0);
  // An excess above the noise still takes the better rung.
  EXPECT_EQ(SimplestRungWithinNoise({simpler, best}, 2.0, std::vector<double>(10000, 0.005)), 1);
  // Variances that do not pair with the errors are ignored.
  EXPECT_EQ(SimplestRungWithinNoise({simpler, best}, 2.0, std::vector<double>(3, 1.0)), 1);
}

TEST(SimplestRungWithinNoise, SkipsUnavailableRungsAndReportsNone) {
  EXPECT_EQ(SimplestRungWithinNoise({{}, {5, 5, 5}, {1, 1, 1}}, 2.0), 2);
  EXPECT_EQ(SimplestRungWithinNoise({{}, {}}, 2.0), -1);
}

}  // namespace
}  // namespace thinslab
