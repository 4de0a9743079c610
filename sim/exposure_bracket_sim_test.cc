// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/exposure_bracket_sim.h"

#include <gtest/gtest.h>

#include <cmath>

namespace thinslab {
namespace {

// The response curves are monotone maps of [0, 1] onto [0, 1] with a finite slope at 0, and
// InverseResponseCurve inverts them.
TEST(SensorResponseCurve, MonotoneNormalisedAndInvertible) {
  for (SimResponseCurve curve : {SimResponseCurve::kLinear, SimResponseCurve::kGamma, SimResponseCurve::kSCurve}) {
    SimSensorOptions sensor;
    sensor.response = curve;
    EXPECT_NEAR(sensor.ResponseCurve(0), 0, 1e-12);
    EXPECT_NEAR(sensor.ResponseCurve(1), 1, 1e-12);
    double previous = -1;
    for (double s = -0.01; s <= 1.0; s += 0.001) {
      const double v = sensor.ResponseCurve(s);
      EXPECT_GT(v, previous) << s;
      previous = v;
      EXPECT_NEAR(sensor.InverseResponseCurve(v), s, 1e-9) << s;
    }
    const double slope0 = (sensor.ResponseCurve(1e-4) - sensor.ResponseCurve(0)) / 1e-4;
    EXPECT_LT(slope0, 100);  // Finite at 0: noise below black stays near black.
  }
  SimSensorOptions gamma;
  gamma.response = SimResponseCurve::kGamma;
  EXPECT_GT(gamma.ResponseCurve(0.1), 0.2);  // A tone curve lifts shadows (linear: 0.1).
}

// The default sensor is linear and unchanged: noise-free DN = round(e / gain + black).
TEST(SensorResponseCurve, DefaultIsLinear) {
  SimSensorOptions sensor;
  sensor.enable_noise = false;
  Image electrons(4, 1);
  electrons.data() = {0.0f, 1000.0f, 15000.0f, 40000.0f};
  const Image raw = ApplySensor(electrons, sensor, 1);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(raw.data()[i], std::round(electrons.data()[i] / sensor.gain_e_per_dn() + sensor.black_level_dn));
  }
  EXPECT_EQ(raw.data()[3], sensor.saturation_dn());
}

TEST(ExposureBracketSim, FramesDarksAndErrors) {
  BracketSimOptions options;
  options.width_px = 32;
  options.height_px = 16;
  options.exposures_us = {10, 100, 1000};
  options.frames_per_exposure = 2;
  options.dark_frames_per_exposure = 1;
  options.ambient_e_per_us = 1;
  SimulatedBracket bracket;
  ASSERT_TRUE(SimulateBracket(options, &bracket).ok());
  ASSERT_EQ(bracket.frames.size(), 6u);
  ASSERT_EQ(bracket.darks.size(), 3u);
  EXPECT_EQ(bracket.frame_exposures_us[5], 1000);
  // Longer exposures are brighter on average; the scene spans min..max.
  auto mean = [](const Image& image) {
    double sum = 0;
    for (float v : image.data()) sum += v;
    return sum / image.data().size();
  };
  EXPECT_LT(mean(bracket.frames[0]), mean(bracket.frames[2]));
  EXPECT_LT(mean(bracket.darks[0]), mean(bracket.darks[2]));
  float lo = 1e30f, hi = 0;
  for (float v : bracket.scene_e_per_us.data()) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  EXPECT_LT(lo, options.min_e_per_us * 1.3);
  EXPECT_GT(hi, options.max_e_per_us * 0.7);
  options.exposures_us = {10, -1};
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("BracketSimOptions::exposures_us[1]"), std::string::npos);
  EXPECT_FALSE(SimulateBracket(options, &bracket).ok());
}

}  // namespace
}  // namespace thinslab
