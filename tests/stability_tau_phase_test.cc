// SPDX-License-Identifier: Apache-2.0
// Stability matrix of issue #8 for the tau fit (shadow maps, Gu et al. 2007 Eqs. 5-7) and the
// laser-lobe g fit (Gu Eq. 8), CI-sized. Every case is a capture of the simulated rigs (Monte
// Carlo layer transport with all scattering orders, perspective camera, shot and read noise,
// 12-bit quantisation, saturation) run through the unchanged pipelines. Each fit either meets
// the tolerance stated here or says why not: a per-pixel status, a sigma that covers the error,
// or a non-success result with a message. No case may write a NaN or inf. The finer sweep and
// the charts of the failure boundaries: bench/stability_tau_phase.cc, docs/stability.md.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "thinslab/app/stability_cases.h"
#include "thinslab/sim/contamination_pattern.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

std::string Label(const char* format, double value) {
  char text[128];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

// Texture side in texels (80 um pitch): small enough for the sanitizer build, large enough
// that the specks pattern has clean and dense regions.
constexpr int kTextureSize = 48;

// RMS |tau - tau_true| of a map at the nominal exposure: the 1.3-1.8 % relative RMS of
// docs/models/dirty_glass_tau.md on a pattern whose RMS tau is ~0.17, with margin for the
// small camera (docs/stability.md measured 0.0035).
constexpr double kNominalMaxRmsAbsErrorTau = 0.01;
// Near tau = 0 the error is the frame noise, ~0.0014 per pixel at the nominal exposure.
constexpr double kNearZeroMaxRmsAbsErrorTau = 0.003;
constexpr double kNearZeroMaxAbsBiasTau = 0.001;
// Where noise or the unmodelled multiple scattering dominates, the fit's own sigma_tau must
// cover the error: RMS error at most this many times the RMS sigma_tau of the same pixels.
constexpr double kMaxErrorOverSigmaTau = 1.5;
// A pixel on the bright side of a clamped edge mixes in up to a quarter of dark light through
// the camera footprint: -ln(1 - 0.25) ~ 0.3.
constexpr double kMaxBrightSideEdgeErrorTau = 0.3;

TauStabilityCase SpecksCase() {
  TauStabilityCase c;
  c.sim = SmallShadowMapRig(/*seed=*/1);
  ContaminationPatternOptions pattern;
  pattern.width_px = kTextureSize;
  pattern.height_px = kTextureSize;
  pattern.num_dust_specks = 6;
  c.tau_true = GenerateContaminationPattern(pattern);
  return c;
}

TauStabilityCase UniformCase(double tau) {
  TauStabilityCase c = SpecksCase();
  c.tau_true = UniformTau(kTextureSize, kTextureSize, tau);
  return c;
}

TauStabilityResult RunTau(const TauStabilityCase& c, const std::string& label) {
  TempDir dir;
  TauStabilityResult r;
  const Status harness = RunTauStabilityCase(c, dir.path(), &r);
  EXPECT_TRUE(harness.ok()) << harness.message();
  std::printf("%s: %s; ok %lld dark %lld saturated %lld clamped %lld next-to-clamped %lld; RMS error %.4f "
              "(sigma_tau %.4f; within 1 / 2 sigma %.2f / %.2f), bias %+.4f, max %.3f, realigned %.4f, "
              "split-half rms z %.3f\n",
              label.c_str(), r.pipeline.ok() ? "fitted" : r.pipeline.message().c_str(), static_cast<long long>(r.ok),
              static_cast<long long>(r.dark), static_cast<long long>(r.saturated), static_cast<long long>(r.clamped),
              static_cast<long long>(r.next_to_clamped), r.rms_abs_error, r.rms_sigma_tau,
              r.ok > 0 ? static_cast<double>(r.within_1_sigma) / r.ok : 0.0,
              r.ok > 0 ? static_cast<double>(r.within_2_sigma) / r.ok : 0.0, r.mean_error, r.max_abs_error,
              r.rms_abs_error_realigned, r.consistency_rms_z);
  // Whatever happened, the written map is finite and every status is a documented code.
  EXPECT_EQ(r.non_finite_values, 0) << label;
  EXPECT_EQ(r.invalid_status, 0) << label;
  return r;
}

TauStabilityCase WithExposureScale(TauStabilityCase c, double scale) {
  c.sim.session.exposure_time_us = scale * c.sim.rig.exposure_time_us;
  return c;
}

TEST(TauStability, NominalCaptureMeetsTolerance) {
  const TauStabilityResult r = RunTau(SpecksCase(), "nominal");
  ASSERT_TRUE(r.pipeline.ok()) << r.pipeline.message();
  EXPECT_EQ(r.ok, r.pixels);
  EXPECT_LE(r.rms_abs_error, kNominalMaxRmsAbsErrorTau);
}

// Less light: pixel noise grows as 1/sqrt(light); sigma_tau follows it, and pixels whose noise
// exceeds TauFitOptions::max_sigma_tau are dark instead of fitted.
TEST(TauStability, LowLightErrorStaysWithinSigmaOrIsFlaggedDark) {
  for (double scale : {0.01, 0.002}) {
    const TauStabilityResult r = RunTau(WithExposureScale(SpecksCase(), scale), Label("exposure x%g", scale));
    ASSERT_TRUE(r.pipeline.ok()) << r.pipeline.message();
    ASSERT_GT(r.ok, 0);
    // Noise dominates here, so sigma_tau must be neither too narrow nor too wide.
    EXPECT_LE(r.rms_abs_error, kMaxErrorOverSigmaTau * r.rms_sigma_tau) << "exposure x" << scale;
    EXPECT_GE(r.rms_abs_error, r.rms_sigma_tau / kMaxErrorOverSigmaTau) << "exposure x" << scale;
    EXPECT_EQ(r.ok + r.dark, r.pixels);
    // At x0.002 the densest specks' noise passes max_sigma_tau (docs/stability.md: 609 pixels).
    if (scale <= 0.002) {
      EXPECT_GT(r.dark, 0);
    }
  }
}

// Signal at the dark floor (a few electrons per frame): nothing is measurable, and the fit says
// so instead of returning a map of noise.
TEST(TauStability, UnderExposureAtTheDarkFloorIsRefusedAsDark) {
  const TauStabilityResult r = RunTau(WithExposureScale(SpecksCase(), 0.0003), "exposure x0.0003");
  ASSERT_FALSE(r.pipeline.ok());
  EXPECT_NE(r.pipeline.message().find("dark"), std::string::npos) << r.pipeline.message();
}

// Over-exposure: the clean board near the image centre saturates first. Saturated pixels are
// flagged, the rest keep the nominal accuracy; beyond half the region the fit refuses.
TEST(TauStability, OverExposureIsFlaggedSaturatedNeverFitted) {
  const TauStabilityResult mild = RunTau(WithExposureScale(SpecksCase(), 1.3), "exposure x1.3");
  ASSERT_TRUE(mild.pipeline.ok()) << mild.pipeline.message();
  EXPECT_GT(mild.saturated, 0);
  EXPECT_LE(mild.rms_abs_error, kNominalMaxRmsAbsErrorTau);

  const TauStabilityResult heavy = RunTau(WithExposureScale(SpecksCase(), 2.0), "exposure x2");
  ASSERT_FALSE(heavy.pipeline.ok());
  EXPECT_NE(heavy.pipeline.message().find("saturated"), std::string::npos) << heavy.pipeline.message();
}

TEST(TauStability, TauNearZeroHasSmallAbsoluteError) {
  const TauStabilityResult r = RunTau(UniformCase(0.005), "uniform tau 0.005");
  ASSERT_TRUE(r.pipeline.ok()) << r.pipeline.message();
  EXPECT_EQ(r.ok, r.pixels);
  EXPECT_LE(r.rms_abs_error, kNearZeroMaxRmsAbsErrorTau);
  EXPECT_LE(std::abs(r.mean_error), kNearZeroMaxAbsBiasTau);
}

// A dense uniform layer: Eq. 6 misses the multiply scattered light and the map reads low
// (~5 % at tau 2); sigma_tau carries that model term and covers the error.
TEST(TauStability, DenseLayerErrorIsCoveredBySigma) {
  const TauStabilityResult r = RunTau(UniformCase(2.0), "uniform tau 2");
  ASSERT_TRUE(r.pipeline.ok()) << r.pipeline.message();
  EXPECT_EQ(r.ok, r.pixels);
  EXPECT_LE(r.rms_abs_error, kMaxErrorOverSigmaTau * r.rms_sigma_tau);
}

// The coverage goal of issue #24 (>= 60 % of status-ok pixels within 1 sigma_tau, >= 90 % within
// 2) where the light Eq. 6 leaves out is spread over the map: a bright layer (albedo 0.9) close
// to the board, and hard-edged patches whose multiply scattered light lands on their thin
// neighbours. Before the model term was convolved over the layer (2026-12-07) these read
// 0.45 / 0.74 and 0.54 / 0.81 (docs/stability.md, "Coverage of the error bars").
TEST(TauStability, SpreadMultipleScatteringIsCoveredBySigma) {
  constexpr double kGoalWithin1Sigma = 0.6, kGoalWithin2Sigma = 0.9;
  TauStabilityCase bright = SpecksCase();
  bright.sim.rig.layer_albedo = 0.9;
  bright.sim.rig.board_distance_m = 5e-3;
  TauStabilityCase edges = SpecksCase();
  const double patch_taus[4] = {0.5, 1, 2, 3};
  edges.tau_true = PatchTau(kTextureSize, kTextureSize, patch_taus, 0);
  for (const auto& [c, label] : {std::pair{bright, "albedo 0.9, board 5 mm"}, std::pair{edges, "patches tau 0.5-3"}}) {
    const TauStabilityResult r = RunTau(c, label);
    ASSERT_TRUE(r.pipeline.ok()) << label << ": " << r.pipeline.message();
    ASSERT_GE(r.ok, r.pixels / 2) << label;
    EXPECT_GE(static_cast<double>(r.within_1_sigma) / r.ok, kGoalWithin1Sigma) << label;
    EXPECT_GE(static_cast<double>(r.within_2_sigma) / r.ok, kGoalWithin2Sigma) << label;
  }
}

// Reference "auto" judges the clean pixels of the shadow frame itself; they carry the light the
// specks scatter onto them, so the surface read every tau +0.006 high, beyond sigma_tau (0.31 /
// 0.69 within 1 / 2 sigma). The surface is now refitted through the shadow less the modelled S.
TEST(TauStability, JudgedReferenceOfASpeckledShadowIsCoveredBySigma) {
  TauStabilityCase c = SpecksCase();
  c.run.fit.reference = "auto";
  const TauStabilityResult r = RunTau(c, "reference auto");
  ASSERT_TRUE(r.pipeline.ok()) << r.pipeline.message();
  ASSERT_GE(r.ok, r.pixels / 2);
  EXPECT_LE(std::abs(r.mean_error), 0.003);
  EXPECT_GE(static_cast<double>(r.within_1_sigma) / r.ok, 0.6);
  EXPECT_GE(static_cast<double>(r.within_2_sigma) / r.ok, 0.9);
}

// Beyond tau_max: clamped, and the pixels around a clamped one (lower bounds only) flagged; no
// pixel with tau_true > tau_max passes as ok, and no clamp without cause.
TEST(TauStability, TauBeyondTauMaxIsClampedNeverReportedOk) {
  TauStabilityCase c = SpecksCase();
  const double patch_taus[4] = {5, 6, 4.5, 8};
  c.tau_true = PatchTau(kTextureSize, kTextureSize, patch_taus, 0.1);
  const TauStabilityResult r = RunTau(c, "patches tau 4.5-8");
  ASSERT_TRUE(r.pipeline.ok()) << r.pipeline.message();
  EXPECT_GT(r.clamped, 0);
  EXPECT_GT(r.next_to_clamped, 0);
  EXPECT_EQ(r.ok_beyond_tau_max, 0);
  EXPECT_EQ(r.clamped_below_tau_max, 0);
  EXPECT_LE(r.max_abs_error, kMaxBrightSideEdgeErrorTau);

  // All of the layer beyond tau_max: nothing to fit, and the message counts why.
  const TauStabilityResult all = RunTau(UniformCase(5.0), "uniform tau 5");
  ASSERT_FALSE(all.pipeline.ok());
  EXPECT_NE(all.pipeline.message().find("clamped at tau_max"), std::string::npos) << all.pipeline.message();
}

// A camera pose error of 3 pixels moves the rectified map rigidly (both the shadow and the
// reference frames are rectified with the same pose, so m = I / I_clean stays consistent):
// the error against the truth grows, but against the truth moved by the predicted board shift
// it is back at the nominal level. Nothing in a shadow-map capture can see the shift.
TEST(TauStability, PoseErrorShiftsTheMapRigidly) {
  TauStabilityCase c = SpecksCase();
  const TauStabilityResult nominal = RunTau(c, "pose error 0 px");
  c.pose_error_px = 3;
  const TauStabilityResult r = RunTau(c, "pose error 3 px");
  ASSERT_TRUE(r.pipeline.ok()) << r.pipeline.message();
  EXPECT_GT(r.pose_error_board_texels, 0.5);
  EXPECT_GT(r.rms_abs_error, 3 * nominal.rms_abs_error);
  EXPECT_LE(r.rms_abs_error_realigned, kNominalMaxRmsAbsErrorTau);
  // Documented blind spot (docs/stability.md): the split-half consistency does not rise (both
  // halves share the pose). If this fails, a diagnostic now sees pose errors; update the doc.
  ASSERT_GT(nominal.consistency_rms_z, 0);
  EXPECT_LE(r.consistency_rms_z, nominal.consistency_rms_z + 0.1);
}

// ---- g fit ----

// |g - g_true| of docs/models/laser_lobe_g.md (tests/e2e_laser_lobe_test.cc), and the error in
// units of sigma_g a successful fit may show.
constexpr double kMaxAbsErrorG = 0.03;
constexpr double kMaxErrorInSigmaG = 3;

PhaseStabilityResult RunPhase(const PhaseStabilityCase& c, const std::string& label) {
  TempDir dir;
  PhaseStabilityResult r;
  const Status harness = RunPhaseStabilityCase(c, dir.path(), &r);
  EXPECT_TRUE(harness.ok()) << harness.message();
  const PhaseFitSummary& s = r.summary;
  std::printf("%s: %s, g = %.4f +- %.4f (true %.3f), chi2/dof %.1f, significance %.0f: %s\n", label.c_str(),
              s.ResultName().c_str(), s.g, s.sigma_g, c.sim.rig.layer_g, s.chi2_reduced, s.detection_significance,
              s.message.c_str());
  EXPECT_TRUE(r.summary_finite) << label;
  EXPECT_EQ(r.non_finite_in_files, 0) << label;
  return r;
}

// The contract of every g case: a success meets the tolerance and its sigma covers the error;
// anything else is a non-success result with a message saying why.
void ExpectGWithinToleranceOrFlagged(const PhaseStabilityResult& r, double g_true, const std::string& label) {
  const PhaseFitSummary& s = r.summary;
  if (s.IsUsable()) {
    EXPECT_TRUE(r.pipeline.ok()) << label;
    EXPECT_GT(s.sigma_g, 0) << label;
    EXPECT_LE(std::abs(s.g - g_true), kMaxAbsErrorG) << label;
    EXPECT_LE(std::abs(s.g - g_true), kMaxErrorInSigmaG * s.sigma_g) << label;
  } else {
    EXPECT_NE(s.result, PhaseFitSummary::Result::kNotRun) << label;
    EXPECT_FALSE(s.message.empty()) << label;
  }
}

TEST(PhaseStability, GNearOneAndNearZero) {
  for (double g : {0.0, 0.95, 0.99}) {
    PhaseStabilityCase c;
    c.sim = SmallLaserLobeRig(/*tau=*/0.3, g, /*seed=*/1);
    const std::string label = Label("g %g", g);
    const PhaseStabilityResult r = RunPhase(c, label);
    ExpectGWithinToleranceOrFlagged(r, g, label);
  }
}

// A forward lobe (g 0.8, tau 0.3, albedo 0.3) on the small rig reads ~0.005 low from the multiple
// scattering Eq. 8 leaves out, and the data cannot tell the twice-scattered lobe from a lower g:
// before sigma_g held the shift at the layer's predicted second order (2026-12-07) none of four
// seeds was within 1 sigma_g (sigma_g 0.0015-0.0036). The coverage goal of issue #24 on four
// seeds: at least 3 within 1 sigma_g, all within 2.
TEST(PhaseStability, ForwardLobeMultipleScatteringIsCoveredBySigma) {
  int within_1 = 0, within_2 = 0;
  for (int seed = 101; seed <= 104; ++seed) {
    PhaseStabilityCase c;
    c.sim = SmallLaserLobeRig(/*tau=*/0.3, /*g=*/0.8, seed);
    c.fit.tau = 0.3;
    const PhaseStabilityResult r = RunPhase(c, Label("g 0.8, seed %g", seed));
    ASSERT_TRUE(r.summary.IsUsable()) << r.summary.message;
    const double error = std::abs(r.summary.g - 0.8);
    within_1 += error <= r.summary.sigma_g;
    within_2 += error <= 2 * r.summary.sigma_g;
    // The term is the predicted second order's shift, not noise: it must not dwarf the error.
    EXPECT_LE(r.summary.sigma_g, 4 * error) << "seed " << seed;
  }
  EXPECT_GE(within_1, 3);
  EXPECT_EQ(within_2, 4);
}

// Tiny tau: below the detection limit the fit reports no measurable scattering, never a g.
TEST(PhaseStability, TinyTauIsNoMeasurableScatteringOrWithinTolerance) {
  for (double tau : {0.0, 1e-7, 1e-5}) {
    PhaseStabilityCase c;
    c.sim = SmallLaserLobeRig(tau, 0.8, /*seed=*/2);
    c.fit.tau = tau > 0 ? tau : 0.3;
    const std::string label = Label("tau %g", tau);
    const PhaseStabilityResult r = RunPhase(c, label);
    ExpectGWithinToleranceOrFlagged(r, 0.8, label);
    if (tau == 0) {
      EXPECT_EQ(r.summary.result, PhaseFitSummary::Result::kNoMeasurableScattering) << r.summary.message;
    }
  }
}

// High noise: a three-exposure bracket with heavy read noise. Up to ~300 e- the fit holds with a
// wider sigma_g; beyond, g is not determined and the fit must say so (PhaseFitOptions::max_sigma_g).
TEST(PhaseStability, HighNoiseWidensSigmaOrFailsWithMessage) {
  for (double read_noise_e : {200.0, 1000.0}) {
    PhaseStabilityCase c;
    c.sim = SmallLaserLobeRig(0.3, 0.8, /*seed=*/1);
    c.sim.rig.sensor.read_noise_e = read_noise_e;
    c.sim.session.exposure_times_us = {20, 200, 2000};
    const std::string label = Label("read noise %g e-", read_noise_e);
    const PhaseStabilityResult r = RunPhase(c, label);
    ExpectGWithinToleranceOrFlagged(r, 0.8, label);
    if (read_noise_e >= 1000) {
      EXPECT_EQ(r.summary.result, PhaseFitSummary::Result::kFailure);
      EXPECT_NE(r.summary.message.find("not determined"), std::string::npos) << r.summary.message;
    }
  }
}

}  // namespace
}  // namespace thinslab
