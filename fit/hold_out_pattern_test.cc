// SPDX-License-Identifier: Apache-2.0
// Hold-out patterns of the dot grid (issue #23 section 4): which dots `fit dmf --hold-out`
// keeps out of the fit.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "thinslab/fit/dmf_map_fit.h"

namespace thinslab {
namespace {

int HeldOut(const std::vector<uint8_t>& train) { return static_cast<int>(std::count(train.begin(), train.end(), 0)); }

TEST(HoldOutPattern, NoHoldOutFitsEveryDot) {
  EXPECT_EQ(HeldOut(HoldOutTrainMask(7, 5, false, HoldOutPattern())), 0);
}

TEST(HoldOutPattern, CheckerboardHoldsOutEveryOtherDot) {
  const std::vector<uint8_t> train = HoldOutTrainMask(6, 4, true, HoldOutPattern());
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 6; ++x) EXPECT_EQ(train[y * 6 + x], (x + y) % 2 == 0) << x << ", " << y;
  }
}

TEST(HoldOutPattern, BlocksAreTilesInACheckerboard) {
  HoldOutPattern pattern;
  pattern.kind = "blocks";
  pattern.block = 3;
  const std::vector<uint8_t> train = HoldOutTrainMask(9, 6, true, pattern);
  EXPECT_EQ(train[0], 1);            // Tile (0, 0) fitted.
  EXPECT_EQ(train[3], 0);            // Tile (1, 0) held out.
  EXPECT_EQ(train[2 * 9 + 2], 1);    // Still tile (0, 0).
  EXPECT_EQ(train[3 * 9 + 0], 0);    // Tile (0, 1).
  EXPECT_EQ(train[3 * 9 + 3], 1);    // Tile (1, 1).
  EXPECT_EQ(HeldOut(train), 27);
}

TEST(HoldOutPattern, RandomHoldsOutTheFractionReproduciblyPerSeed) {
  HoldOutPattern pattern;
  pattern.kind = "random";
  pattern.fraction = 0.3;
  const std::vector<uint8_t> a = HoldOutTrainMask(40, 40, true, pattern);
  EXPECT_NEAR(HeldOut(a) / 1600.0, 0.3, 0.04);  // Binomial sd 0.011.
  EXPECT_EQ(a, HoldOutTrainMask(40, 40, true, pattern));
  pattern.seed = 2;
  const std::vector<uint8_t> b = HoldOutTrainMask(40, 40, true, pattern);
  EXPECT_NE(a, b);
  EXPECT_NEAR(HeldOut(b) / 1600.0, 0.3, 0.04);
}

TEST(HoldOutPattern, CheckNamesTheOption) {
  std::string error;
  HoldOutPattern pattern;
  pattern.kind = "stripes";
  EXPECT_FALSE(pattern.Check(&error));
  EXPECT_NE(error.find("--hold-out-pattern"), std::string::npos) << error;
  pattern = HoldOutPattern();
  pattern.fraction = 1;
  EXPECT_FALSE(pattern.Check(&error));
  EXPECT_NE(error.find("--hold-out-fraction"), std::string::npos) << error;
  pattern = HoldOutPattern();
  pattern.block = 0;
  EXPECT_FALSE(pattern.Check(&error));
  EXPECT_NE(error.find("--hold-out-block"), std::string::npos) << error;
  EXPECT_TRUE(HoldOutPattern().Check(&error));
}

}  // namespace
}  // namespace thinslab
