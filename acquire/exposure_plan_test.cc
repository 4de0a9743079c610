// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/exposure_plan.h"

#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/core/math.h"

namespace thinslab {
namespace {

constexpr double kPeriodS = 1.0 / 85;
constexpr double kPeriodUs = 1e6 / 85;

CameraInfo Camera12Bit() {
  CameraInfo camera;
  camera.id = "cam0";
  camera.bit_depth = 12;
  camera.black_level_dn = 64;
  camera.saturation_dn = 4095;
  camera.gain_e_per_dn = 7.4;
  camera.read_noise_dn = 1.0;
  return camera;
}

ProbeMeasurement Probe(const std::string& label, double dn_per_us) {
  ProbeMeasurement m;
  m.label = label;
  m.exposure_us = kPeriodUs;
  m.peak_dn_per_us = dn_per_us;
  return m;
}

bool WholePeriods(const std::vector<double>& exposures) {
  for (double t : exposures) {
    if (std::abs(t / kPeriodUs - std::round(t / kPeriodUs)) > 1e-9) return false;
  }
  return true;
}

// The brightest state at half the range in the shortest exposure; the glow of a 0.2 % black
// display at 10 % in the longest, which then stops short of what the dim lobe's edge would need.
TEST(ExposurePlan, TheGlowLimitsTheLongestAndTheBrightestTheShortest) {
  const double range = 4095 - 64;
  const ProbeMeasurement brightest = Probe("all dots", 0.5 * range / (4 * kPeriodUs));  // Half range at 4 periods.
  const ProbeMeasurement glow = Probe("black", 0.1 * range / (100 * kPeriodUs));        // 10 % at 100 periods.
  const ProbeMeasurement lobe = Probe("dot (1, 1)", 1e-4);
  ExposurePlanOptions options;
  options.max_dark_fraction = 0.1;
  ExposurePlan plan;
  ASSERT_TRUE(PlanExposures(brightest, glow, {lobe}, Camera12Bit(), kPeriodS, options, &plan).ok());
  ASSERT_GE(plan.exposures_us.size(), 2u);
  EXPECT_NEAR(plan.exposures_us.front(), 4 * kPeriodUs, 1e-6);
  EXPECT_NEAR(plan.exposures_us.back(), 100 * kPeriodUs, 1e-6);
  EXPECT_TRUE(WholePeriods(plan.exposures_us));
  for (size_t k = 1; k < plan.exposures_us.size(); ++k) {
    EXPECT_LE(plan.exposures_us[k] / plan.exposures_us[k - 1], 16 * 1.1) << "step " << k;
  }
  EXPECT_NE(plan.why.find("black glow"), std::string::npos) << plan.why;
  EXPECT_NE(plan.why.find("would need"), std::string::npos) << plan.why;
  EXPECT_EQ(plan.probes.size(), 3u);
}

// A black display: the dimmest lobe's edge sets the longest exposure, where its signal clears
// the asked-for sigmas (and one period shorter would not).
TEST(ExposurePlan, WithoutGlowTheDimmestLobesEdgeSetsTheLongest) {
  const double range = 4095 - 64;
  ExposurePlanOptions options;
  const ProbeMeasurement brightest = Probe("all dots", 0.5 * range / kPeriodUs);
  const ProbeMeasurement black = Probe("black", 0);
  const ProbeMeasurement bright_lobe = Probe("dot (1, 1)", 0.01), dim_lobe = Probe("dot (2, 2)", 0.002);
  ExposurePlan plan;
  const CameraInfo camera = Camera12Bit();
  ASSERT_TRUE(PlanExposures(brightest, black, {bright_lobe, dim_lobe}, camera, kPeriodS, options, &plan).ok());
  const double t = plan.exposures_us.back();
  const double edge = options.edge_fraction * dim_lobe.peak_dn_per_us;
  auto sigmas = [&](double us) {
    return edge * us / std::sqrt(Sqr(*camera.read_noise_dn) + edge * us / camera.gain_e_per_dn);
  };
  EXPECT_GE(sigmas(t + kPeriodUs), options.edge_sigmas);
  EXPECT_LT(sigmas(t - kPeriodUs), options.edge_sigmas);
  EXPECT_NE(plan.why.find("dot (2, 2)"), std::string::npos) << plan.why;
  EXPECT_NEAR(plan.exposures_us.front(), kPeriodUs, 1e-6);
}

TEST(ExposurePlan, TheCapAndASingleExposure) {
  const double range = 4095 - 64;
  ExposurePlanOptions options;
  options.max_exposure_us = 10 * kPeriodUs;
  ExposurePlan plan;
  ASSERT_TRUE(PlanExposures(Probe("all dots", 0.5 * range / (10 * kPeriodUs)), Probe("black", 0), {}, Camera12Bit(),
                            kPeriodS, options, &plan)
                  .ok());
  ASSERT_EQ(plan.exposures_us.size(), 1u);
  EXPECT_NEAR(plan.exposures_us.front(), 10 * kPeriodUs, 1e-6);
}

TEST(ExposurePlan, NothingLitOrBadOptionsAreErrors) {
  ExposurePlan plan;
  Status s =
      PlanExposures(Probe("all dots", 0), Probe("black", 0), {}, Camera12Bit(), kPeriodS, ExposurePlanOptions(), &plan);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("all dots"), std::string::npos) << s.message();
  ExposurePlanOptions options;
  options.max_step_ratio = 1;
  s = PlanExposures(Probe("all dots", 1), Probe("black", 0), {}, Camera12Bit(), kPeriodS, options, &plan);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("max_step_ratio"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace thinslab
