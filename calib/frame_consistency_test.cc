// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/frame_consistency.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "thinslab/calib/frame_noise.h"
#include "thinslab/core/math.h"

namespace thinslab {
namespace {

// A textured scene (smooth blobs and a fine sinusoid), value `scale` at its brightest, imaged
// with shot noise (gain 4 e-/DN) and 3 DN read noise, shifted by `shift_px` columns.
Image Frame(double scale, int shift_px, uint32_t seed, double gamma = 1) {
  constexpr int kW = 120, kH = 90;
  Image image(kW, kH, 0.0f);
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0, 1);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const double u = x - shift_px;
      const double scene = 0.2 + 0.5 * std::exp(-(Sqr(u - 40) + Sqr(y - 40)) / 300.0) +
                           0.3 * (0.5 + 0.5 * std::sin(u * 0.7) * std::cos(y * 0.45));
      const double mean = scale * std::pow(scene, gamma);
      image.at(x, y) = static_cast<float>(mean + std::sqrt(9 + mean / 4) * normal(rng));
    }
  }
  return image;
}

FrameNoiseModel Noise() {
  FrameNoiseModel model;
  model.variance_floor = 9;
  model.variance_per_value = 0.25;
  model.method = "declared";
  return model;
}

// Per-pixel variances from the noise model at each frame's own values.
Image Variance(const Image& frame) {
  Image variance = frame;
  for (float& v : variance.data()) v = static_cast<float>(Noise().Variance(v));
  return variance;
}

FramePairComparison Compare(const Image& a, const Image& b, double expected_ratio = 1) {
  FramePairComparison comparison;
  EXPECT_TRUE(
      CompareFramePair(a, b, Variance(a), Variance(b), expected_ratio, 4095, FramePairOptions(), &comparison).ok());
  return comparison;
}

TEST(FrameConsistency, RepeatsAgreeWithinTheNoise) {
  const FramePairComparison c = Compare(Frame(2000, 0, 1), Frame(2000, 0, 2));
  ASSERT_TRUE(c.measured());
  EXPECT_NEAR(c.ratio, 1.0, 0.003);
  EXPECT_LT(c.ratio_sigma, 0.002);
  EXPECT_LT(c.outlier_fraction, 1e-3);
}

TEST(FrameConsistency, BracketNeighboursGiveTheExposureRatio) {
  const FramePairComparison c = Compare(Frame(1000, 0, 3), Frame(3000, 0, 4), 3);
  ASSERT_TRUE(c.measured());
  EXPECT_NEAR(c.ratio, 3.0, 0.01);
  EXPECT_LT(c.outlier_fraction, 1e-3);
}

// A camera response left unlinearised bends the ratio with the level; the per-level ratios take
// it, so it is not read as motion.
TEST(FrameConsistency, AnUnlinearisedResponseIsNotMotion) {
  // Values of a gamma-0.8 camera at 1x and 2.5x the exposure: v = (t L)^0.8.
  const FramePairComparison c = Compare(Frame(1000, 0, 5, 0.8), Frame(1000 * std::pow(2.5, 0.8), 0, 6, 0.8), 2.5);
  ASSERT_TRUE(c.measured());
  EXPECT_LT(c.outlier_fraction, 0.005);
}

TEST(FrameConsistency, AMovedSceneDiffersInManyPixels) {
  const FramePairComparison c = Compare(Frame(2000, 0, 7), Frame(2000, 2, 8));
  ASSERT_TRUE(c.measured());
  EXPECT_GT(c.outlier_fraction, 0.1);
}

TEST(FrameConsistency, AFlickerChangesTheRatioNotTheStructure) {
  const FramePairComparison c = Compare(Frame(2000, 0, 9), Frame(2000 * 1.08, 0, 10));
  ASSERT_TRUE(c.measured());
  EXPECT_NEAR(c.ratio, 1.08, 0.004);
  EXPECT_LT(c.outlier_fraction, 1e-3);
}

TEST(FrameConsistency, DarkFramesAreNotCompared) {
  const FramePairComparison c = Compare(Frame(5, 0, 11), Frame(5, 0, 12));
  EXPECT_FALSE(c.measured());
}

// Across a wide bracket the short frame's values are mostly noise and quantisation, whatever the
// long frame shows: such pixels are not compared (their ratios would read as motion and flicker).
TEST(FrameConsistency, PixelsTheShortFrameCannotResolveAreNotCompared) {
  const FramePairComparison c = Compare(Frame(4, 0, 13), Frame(4 * 800, 0, 14), 800);
  EXPECT_FALSE(c.measured());
}

TEST(FrameConsistency, BadInputIsAnError) {
  FramePairComparison c;
  EXPECT_FALSE(
      CompareFramePair(Image(4, 4), Image(5, 4), Image(4, 4), Image(5, 4), 1, 4095, FramePairOptions(), &c).ok());
  FramePairOptions options;
  options.outlier_sigmas = 0;
  const Status s = CompareFramePair(Image(4, 4), Image(4, 4), Image(4, 4), Image(4, 4), 1, 4095, options, &c);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("FramePairOptions::outlier_sigmas"), std::string::npos);
}

}  // namespace
}  // namespace thinslab
