// SPDX-License-Identifier: Apache-2.0
#include "calib/hdr_merge.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace thinslab {
namespace {

// A radiance ramp over 6 decades seen through a 3-exposure bracket of a 12-bit linear sensor
// with shot and read noise: the merge is linear (re-exposing it reproduces every unsaturated
// frame within noise), unbiased, never uses saturated samples, and flags pixels saturated in
// every frame.
TEST(HdrMerge, LinearUnbiasedAndIgnoresSaturation) {
  const int w = 600, h = 20;
  const double gain = 8, read = 3, saturation = 4000;
  const std::vector<double> exposures = {10, 100, 1000};
  Image truth(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) truth.at(x, y) = static_cast<float>(std::pow(10.0, -2.5 + 6.0 * x / (w - 1)));
  }
  std::mt19937 rng(4);
  std::normal_distribution<double> normal(0, 1);
  std::vector<Image> frames(exposures.size(), Image(w, h));
  std::vector<HdrFrame> bracket;
  for (size_t k = 0; k < exposures.size(); ++k) {
    for (size_t i = 0; i < truth.data().size(); ++i) {
      const double mean = truth.data()[i] * exposures[k];
      const double dn = mean + std::sqrt(mean / gain + read * read) * normal(rng);
      frames[k].data()[i] = static_cast<float>(std::min(std::round(dn), saturation));
    }
    bracket.push_back({&frames[k], exposures[k]});
  }
  HdrMergeOptions options;
  options.saturation_dn = saturation;
  options.gain_e_per_dn = gain;
  options.read_noise_dn = read;
  HdrImage hdr;
  ASSERT_TRUE(MergeExposureBracket(bracket, options, &hdr).ok());
  int flagged = 0, reexposed = 0, merged = 0;
  double sum_z = 0, sum_z2 = 0;
  for (size_t i = 0; i < truth.data().size(); ++i) {
    const double r = truth.data()[i];
    const double mean0 = r * exposures[0];
    // Within 5 sigma of saturation the noise decides: skip.
    if (std::abs(mean0 - saturation) < 5 * std::sqrt(mean0 / gain + read * read)) continue;
    if (mean0 >= saturation) {
      EXPECT_EQ(hdr.all_saturated.data()[i], 1) << i;
      ++flagged;
      continue;
    }
    EXPECT_EQ(hdr.all_saturated.data()[i], 0);
    const double z = (hdr.radiance.data()[i] - r) / std::sqrt(hdr.variance.data()[i]);
    ++merged;
    sum_z += z;
    sum_z2 += z * z;
    for (size_t k = 0; k < exposures.size(); ++k) {
      const double dn = frames[k].data()[i];
      if (dn >= saturation || r * exposures[k] < 50) continue;
      const double predicted = hdr.radiance.data()[i] * exposures[k];
      EXPECT_NEAR(predicted, dn, 5 * std::sqrt(dn / gain + read * read)) << "pixel " << i << " exposure " << k;
      ++reexposed;
    }
  }
  const double n = std::max(1, merged);
  EXPECT_GT(flagged, 0);
  EXPECT_GT(reexposed, 10000);
  EXPECT_NEAR(sum_z / n, 0.0, 0.1);                   // Unbiased.
  EXPECT_NEAR(std::sqrt(sum_z2 / n), 1.0, 0.15);      // The variance channel is calibrated.
}

TEST(HdrMerge, BadInputNamesTheProblem) {
  Image a(4, 4), b(5, 4);
  HdrMergeOptions options;
  options.saturation_dn = 100;
  HdrImage hdr;
  Status status = MergeExposureBracket({{&a, 10}, {&b, 100}}, options, &hdr);
  EXPECT_NE(status.message().find("5x4"), std::string::npos);
  status = MergeExposureBracket({{&a, 10}, {&a, 0}}, options, &hdr);
  EXPECT_NE(status.message().find("exposure_time_us"), std::string::npos);
  options.saturation_dn = 0;
  status = MergeExposureBracket({{&a, 10}}, options, &hdr);
  EXPECT_NE(status.message().find("HdrMergeOptions::saturation_dn"), std::string::npos);
}

}  // namespace
}  // namespace thinslab
