// SPDX-License-Identifier: Apache-2.0
// The simulated display's emission curve: normalised and monotonic for every curve, sRGB
// continuous at its toe, the 8-bit drive rounded as the PatternWindow rounds it, a table that
// inverts the curve linearising the display up to the drive quantisation, and the CLI spec
// round-tripping with errors that name the option.
#include "thinslab/sim/sim_display_transfer.h"

#include <gtest/gtest.h>

#include <cmath>

namespace thinslab {
namespace {

TEST(SimDisplayTransferTest, CurvesAreNormalisedAndMonotonic) {
  for (const char* spec : {"linear", "power:2.2", "power:0.8", "srgb", "power:2.2/8bit", "srgb/10bit"}) {
    SimDisplayTransfer t;
    ASSERT_TRUE(ParseSimDisplayTransfer(spec, "t", &t).ok()) << spec;
    EXPECT_EQ(t.Emitted(0), 0) << spec;
    EXPECT_NEAR(t.Emitted(1), 1, 1e-15) << spec;
    double previous = 0;
    for (int i = 1; i <= 1000; ++i) {
      const double e = t.LightForLevel(i / 1000.0, IdentityGammaTable());
      EXPECT_GE(e, previous) << spec << " at " << i / 1000.0;
      previous = e;
    }
    EXPECT_EQ(t.ToString(), spec);
  }
  SimDisplayTransfer srgb;
  ASSERT_TRUE(ParseSimDisplayTransfer("srgb", "t", &srgb).ok());
  EXPECT_NEAR(srgb.Emitted(0.04045 - 1e-9), srgb.Emitted(0.04045 + 1e-9), 1e-6);  // IEC 61966-2-1 toe.
  EXPECT_NEAR(srgb.Emitted(0.5), 0.214041, 1e-6);
}

TEST(SimDisplayTransferTest, EightBitDriveRoundsLikeTheWindow) {
  SimDisplayTransfer t;
  ASSERT_TRUE(ParseSimDisplayTransfer("linear/8bit", "t", &t).ok());
  EXPECT_DOUBLE_EQ(t.QuantizeDrive(0.25), 64.0 / 255);  // std::lround(255 * 0.25) = 64.
  EXPECT_DOUBLE_EQ(t.QuantizeDrive(1.0 / 16), 16.0 / 255);
  EXPECT_DOUBLE_EQ(t.QuantizeDrive(1.5), 1.0);
}

TEST(SimDisplayTransferTest, TheCurvesOwnTableLinearisesItUpToQuantisation) {
  SimDisplayTransfer t;
  ASSERT_TRUE(ParseSimDisplayTransfer("power:2.2/8bit", "t", &t).ok());
  GammaTable table;
  for (int i = 0; i <= 255; ++i) table.drive_to_light.push_back({i / 255.0, std::pow(i / 255.0, 2.2)});
  for (double level : {0.01, 0.1, 0.25, 0.5, 0.9}) {
    // Rounding moves the drive d = level^(1/2.2) by at most half a step, 0.5 / 255, hence the
    // light by dL/dd * 0.5 / 255 = 2.2 d^1.2 * 0.5 / 255 (plus 1 % for the curvature).
    const double half_step_light = 2.2 * std::pow(level, 1.2 / 2.2) * 0.5 / 255;
    EXPECT_NEAR(t.LightForLevel(level, table), level, 1.01 * half_step_light) << level;
  }
  EXPECT_NEAR(t.LightForLevel(0.25, IdentityGammaTable()), std::pow(64.0 / 255, 2.2), 1e-12);
}

TEST(SimDisplayTransferTest, BadSpecsNameTheOption) {
  SimDisplayTransfer t;
  for (const char* spec : {"gamma", "power:", "power:-1", "power:x", "srgb/8", "srgb/17bit", ""}) {
    const Status s = ParseSimDisplayTransfer(spec, "sim-display-transfer", &t);
    EXPECT_FALSE(s.ok()) << spec;
    EXPECT_NE(s.message().find("--sim-display-transfer"), std::string::npos) << s.message();
  }
}

}  // namespace
}  // namespace thinslab
