// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/exposure_plan.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
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

// Where the glow stops the longest exposure short of the edge's sigmas, N frames there averaged
// raise its signal to noise by sqrt(N): the plan takes the fewest that reach edge_sigmas, at most
// max_longest_frames, and none (1) when the longest exposure alone reaches them or N is not allowed.
TEST(ExposurePlan, FramesAtTheLongestMakeUpForTheGlowWithinTheirLimit) {
  const double range = 4095 - 64;
  const CameraInfo camera = Camera12Bit();
  const ProbeMeasurement brightest = Probe("all dots", 0.5 * range / (4 * kPeriodUs));
  const ProbeMeasurement glow = Probe("black", 0.1 * range / (100 * kPeriodUs));  // 10 % at 100 periods.
  const ProbeMeasurement lobe = Probe("dot (1, 1)", 3e-4);                        // Edge at 2.3 sigma in one frame.
  ExposurePlanOptions options;
  options.max_dark_fraction = 0.1;
  options.max_longest_frames = 1000;
  ExposurePlan plan;
  ASSERT_TRUE(PlanExposures(brightest, glow, {lobe}, camera, kPeriodS, options, &plan).ok());
  const double t = plan.exposures_us.back();
  ASSERT_NEAR(t, 100 * kPeriodUs, 1e-6);
  const double edge = options.edge_fraction * lobe.peak_dn_per_us;
  const double one =
      edge * t / std::sqrt(Sqr(*camera.read_noise_dn) + (edge + glow.peak_dn_per_us) * t / camera.gain_e_per_dn);
  ASSERT_LT(one, options.edge_sigmas);
  const int n = plan.longest_frames;
  EXPECT_GE(one * std::sqrt(n), options.edge_sigmas * (1 - 1e-9)) << n;
  EXPECT_LT(one * std::sqrt(n - 1), options.edge_sigmas) << n;
  EXPECT_NE(plan.why.find(std::to_string(n) + " frames there, averaged"), std::string::npos) << plan.why;
  // At most max_longest_frames, saying how many were wanted.
  options.max_longest_frames = 2;
  ASSERT_TRUE(PlanExposures(brightest, glow, {lobe}, camera, kPeriodS, options, &plan).ok());
  EXPECT_EQ(plan.longest_frames, 2);
  EXPECT_NE(plan.why.find("frames wanted, at most 2"), std::string::npos) << plan.why;
  // The default takes none, and a lobe bright enough in one frame needs none.
  options.max_longest_frames = 1;
  ASSERT_TRUE(PlanExposures(brightest, glow, {lobe}, camera, kPeriodS, options, &plan).ok());
  EXPECT_EQ(plan.longest_frames, 1);
  options.max_longest_frames = 1000;
  ASSERT_TRUE(PlanExposures(brightest, glow, {Probe("dot (1, 1)", 40)}, camera, kPeriodS, options, &plan).ok());
  EXPECT_EQ(plan.longest_frames, 1);
  EXPECT_EQ(plan.why.find("averaged"), std::string::npos) << plan.why;
}

// The response bracket: the brightest pixel at 5 % of the range in the shortest exposure, the
// dimmest lit pixels at 95 % in the longest, one stop apart, whole refresh periods; the cap is
// said when it stops the longest short.
TEST(ExposurePlan, TheResponseBracketSpansTheWeightedRangeOneStopApart) {
  const double range = 4095 - 64;
  ProbeMeasurement brightest = Probe("the pattern's brightest pixel", 0.5 * range / (100 * kPeriodUs));
  ProbeMeasurement dimmest = Probe("the pattern's dimmest lit pixels", 0.25 * range / (100 * kPeriodUs));
  ExposurePlan plan;
  const ResponseBracketPlanOptions response;
  ASSERT_TRUE(
      PlanResponseBracket(brightest, dimmest, Camera12Bit(), kPeriodS, ExposurePlanOptions(), response, &plan).ok());
  ASSERT_GE(plan.exposures_us.size(), 2u);
  EXPECT_TRUE(WholePeriods(plan.exposures_us));
  EXPECT_NEAR(plan.exposures_us.front(), 10 * kPeriodUs, 1e-6);  // 0.05 / 0.5 of 100 periods.
  EXPECT_NEAR(plan.exposures_us.back(), 380 * kPeriodUs, 1e-6);  // 0.95 / 0.25 of 100 periods.
  for (size_t k = 1; k < plan.exposures_us.size(); ++k) {
    EXPECT_LE(plan.exposures_us[k] / plan.exposures_us[k - 1], 2 * (1 + 1.0 / 60)) << "step " << k;
  }
  EXPECT_NE(plan.why.find("the response's low end"), std::string::npos) << plan.why;
  // The cap stops the longest: said, and the bracket ends there.
  ExposurePlanOptions capped;
  capped.max_exposure_us = 200 * kPeriodUs;
  ASSERT_TRUE(PlanResponseBracket(brightest, dimmest, Camera12Bit(), kPeriodS, capped, response, &plan).ok());
  EXPECT_NEAR(plan.exposures_us.back(), 200 * kPeriodUs, 1e-6);
  EXPECT_NE(plan.why.find("capped"), std::string::npos) << plan.why;
  // No light is an error naming the state.
  dimmest.peak_dn_per_us = 0;
  const Status dark =
      PlanResponseBracket(brightest, dimmest, Camera12Bit(), kPeriodS, ExposurePlanOptions(), response, &plan);
  EXPECT_FALSE(dark.ok());
  EXPECT_NE(dark.message().find("the pattern's brightest pixel"), std::string::npos) << dark.message();
}

// A brightest state that saturates even in the shortest probe (one refresh period) would
// saturate in every frame of the session: refused, naming the state and the remedy.
TEST(ExposurePlan, ABrightestStateSaturatedAtTheShortestExposureIsRefused) {
  const double range = 4095 - 64;
  ProbeMeasurement brightest = Probe("level 1", 2 * range / kPeriodUs);
  brightest.saturated = true;
  ExposurePlan plan;
  const Status status =
      PlanExposures(brightest, Probe("black", 0), {}, Camera12Bit(), kPeriodS, ExposurePlanOptions(), &plan);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("level 1 saturates even at 11.76 ms, one refresh period"), std::string::npos)
      << status.message();
  EXPECT_NE(status.message().find("neutral-density"), std::string::npos) << status.message();
  const Status response = PlanResponseBracket(brightest, Probe("dimmest", range / kPeriodUs), Camera12Bit(), kPeriodS,
                                              ExposurePlanOptions(), ResponseBracketPlanOptions(), &plan);
  EXPECT_FALSE(response.ok());
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

// A lobe's ring (a mean over many pixels) brings its own measured signal to noise: the longest
// exposure is where it reaches edge_sigmas as sqrt(t) grows it, with no gain needed.
TEST(ExposurePlan, AMeasuredRingSignalToNoiseScalesAsTheSquareRootOfTheExposure) {
  const double range = 4095 - 64;
  ExposurePlanOptions options;
  ProbeMeasurement ring = Probe("the lobe's ring at 60 degrees", 1e-3);
  ring.exposure_us = 1000;
  ring.snr = 2.5;
  ExposurePlan plan;
  CameraInfo camera = Camera12Bit();
  camera.gain_e_per_dn = 0;  // Unknown: the ring's path does not use it.
  ASSERT_TRUE(
      PlanExposures(Probe("spot", 0.5 * range / 20), Probe("laser off", 0), {ring}, camera, 0, options, &plan).ok());
  EXPECT_NEAR(plan.exposures_us.front(), 20, 1e-9);
  EXPECT_NEAR(plan.exposures_us.back(), 1000 * Sqr(options.edge_sigmas / 2.5), 1e-6);
  EXPECT_NE(plan.why.find("the lobe's ring at 60 degrees at 10 standard errors"), std::string::npos) << plan.why;
  // Beyond the cap: the cap, and what the ring would have needed.
  options.max_exposure_us = 4000;
  ASSERT_TRUE(
      PlanExposures(Probe("spot", 0.5 * range / 20), Probe("laser off", 0), {ring}, camera, 0, options, &plan).ok());
  EXPECT_NEAR(plan.exposures_us.back(), 4000, 1e-9);
  EXPECT_NE(plan.why.find("would need 16 ms"), std::string::npos) << plan.why;
}

// The ring's pixels seen by a camera straight above the beam: all at the ring's angles on the
// board, none elsewhere, and none when the ring lies outside the view.
TEST(ExposurePlan, TheLaserRingPixelsLieAtTheOuterAngleOnTheBoard) {
  LaserProbeGeometry geometry;
  CameraInfo& camera = geometry.camera;
  camera.id = "cam0";
  camera.width_px = camera.height_px = 200;
  camera.fx_px = camera.fy_px = 200;
  camera.cx_px = camera.cy_px = 100;
  // The camera 80 mm above the sample plane, looking down (-z): x_cam = x, y_cam = -y, z_cam = h - z.
  camera.cam_from_sample.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Eigen::Vector3d::UnitX()));
  camera.cam_from_sample.translation = Eigen::Vector3d(0, 0, 0.08);
  geometry.laser.present = true;
  geometry.laser.origin_in_sample = Eigen::Vector3d(0, 0, 0.5);
  geometry.board_distance_m = 0.02;
  geometry.outer_angle_deg = 45;
  const std::vector<int> ring = LaserRingPixels(geometry);
  ASSERT_GT(ring.size(), 100u);
  const double inner = 0.02 * std::tan((45 - 2.5) * kPi / 180), outer = 0.02;
  for (int i : ring) {
    // The pixel centre's board point: radius = (pixel offset / f) * (camera height + D).
    const double px = (i % 200) + 0.5 - 100.5, py = (i / 200) + 0.5 - 100.5;
    const double r = std::hypot(px, py) / 200 * 0.1;
    EXPECT_GE(r, inner - 1e-12);
    EXPECT_LE(r, outer + 1e-12);
  }
  // A ring wider than the view: no pixel.
  geometry.outer_angle_deg = 85;
  geometry.ring_width_deg = 1;
  EXPECT_TRUE(LaserRingPixels(geometry).empty());
  std::string error;
  geometry.board_distance_m = 0;
  EXPECT_FALSE(geometry.Check(&error));
  EXPECT_NE(error.find("rig.board.distance_m"), std::string::npos) << error;
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
