// SPDX-License-Identifier: Apache-2.0
// System test of the laser-lobe g measurement (Gu et al. 2007, Sec. 5.2): the simulated rig
// makes the lobe by Monte Carlo transport with all scattering orders (not by Eq. 8), renders it
// through an oblique camera with vignetting and the sensor model over a 6-exposure bracket;
// the unchanged calibration and fit stages must recover g.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "tests/testing/temp_dir.h"
#include "thinslab/app/commands.h"
#include "thinslab/calib/exposure_check.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/pipeline/layer_from_phase.h"
#include "thinslab/sim/laser_lobe_rig.h"

namespace thinslab {
namespace {

// Test-sized rig: a 1024 x 768 camera (the default is 1600 x 1200), no clean-glass bracket.
SyntheticLaserSessionOptions TestRig(double g, uint64_t seed) {
  SyntheticLaserSessionOptions options;
  options.rig.layer_tau = 0.3;
  options.rig.layer_g = g;
  options.rig.seed = seed;
  options.rig.camera_width_px = 1024;
  options.rig.camera_height_px = 768;
  options.session.capture_clean = false;
  return options;
}

PhaseFitSummary SimulateAndFit(const SyntheticLaserSessionOptions& sim, const TempDir& dir, const std::string& name,
                               LaserLadderResult* ladder = nullptr) {
  const std::string session = dir / name;
  const Status synth = SynthesizeLaserLobeSession(sim, session);
  EXPECT_TRUE(synth.ok()) << synth.message();
  PhaseFitOptions options;
  options.tau = sim.rig.layer_tau > 0 ? sim.rig.layer_tau : 0.3;
  PhaseFitSummary summary;
  std::vector<LaserRing> rings;
  const Status fit =
      FitPhasePipeline(session, session + "/fit/phase", options, LaserLobePreparationOptions(), false, "# test\n", &summary, &rings, ladder);
  EXPECT_TRUE(fit.ok()) << fit.message();
  // The laser bracket's exposures are checked against its frames (calib/exposure_check.h); the
  // simulated camera applies what it reports unless sensor.exposure_offset_us is set.
  std::string text;
  EXPECT_TRUE(ReadFileToString(session + "/fit/phase/summary.json", &text).ok());
  const nlohmann::json check = nlohmann::json::parse(text, nullptr, false)["exposure_check"];
  if (sim.rig.sensor.exposure_offset_us == 0) {
    EXPECT_EQ(check["warning"], "") << name;
    EXPECT_LT(check["max_deviation"].get<double>(), kExposureCheckTolerance) << name;
  }
  return summary;
}

constexpr double kMaxAbsErrorG = 0.03;

class LaserLobeAccuracyTest : public ::testing::TestWithParam<double> {};

TEST_P(LaserLobeAccuracyTest, RecoversGWithinToleranceAndSigmaCoversTheError) {
  TempDir dir;
  const double g_true = GetParam();
  LaserLadderResult ladder;
  const PhaseFitSummary s = SimulateAndFit(TestRig(g_true, 1), dir, "session", &ladder);
  ASSERT_TRUE(s.IsUsable()) << s.message;
  // Model ladder (issue #8): a forward-scattering layer needs the HG rung; the isotropic slab
  // misses its held-out rings by far more than their noise (measured chi2 per ring: g 0.8
  // 1.3e5 for rung 1 against 380 for rung 2).
  std::printf("ladder: rung %d; held-out chi2 per ring %.3g, %.3g, %.3g\n", ladder.chosen_rung,
              ladder.held_out_chi2[0], ladder.held_out_chi2[1], ladder.held_out_chi2[2]);
  EXPECT_EQ(ladder.chosen_rung, 2);
  EXPECT_TRUE(std::filesystem::exists(dir / "session/fit/phase/ladder.json"));
  std::printf("g_true %.2f: g = %.4f +- %.4f (error %+.4f), chi2/dof %.1f\n", g_true, s.g, s.sigma_g, s.g - g_true,
              s.chi2_reduced);
  EXPECT_LE(std::abs(s.g - g_true), kMaxAbsErrorG);
  EXPECT_LE(std::abs(s.g - g_true), 2 * s.sigma_g);
  EXPECT_TRUE(std::filesystem::exists(dir / "session/fit/phase/lobe_plot.png"));
  EXPECT_GT(std::filesystem::file_size(dir / "session/fit/phase/lobe_plot.png"), 5000u);
}

INSTANTIATE_TEST_SUITE_P(HgG, LaserLobeAccuracyTest, ::testing::Values(0.2, 0.5, 0.8, 0.9),
                         [](const auto& param_info) {
                           return "g_" + std::to_string(static_cast<int>(std::lround(100 * param_info.param)));
                         });

// Coverage rule (docs/models/laser_lobe_g.md): |g - g_true| <= 2 sigma_g in at least 4 of 5 seeds.
TEST(LaserLobe, SigmaGCoversTheErrorInMostSeeds) {
  TempDir dir;
  int covered = 0;
  for (uint64_t seed = 11; seed <= 15; ++seed) {
    const PhaseFitSummary s = SimulateAndFit(TestRig(0.8, seed), dir, "seed_" + std::to_string(seed));
    ASSERT_TRUE(s.IsUsable()) << s.message;
    covered += std::abs(s.g - 0.8) <= 2 * s.sigma_g;
  }
  EXPECT_GE(covered, 4);
}

TEST(LaserLobe, CleanGlassIsFlaggedNotFitted) {
  TempDir dir;
  SyntheticLaserSessionOptions sim = TestRig(0.8, 2);
  sim.rig.layer_tau = 0;
  sim.session.capture_clean = true;
  LaserLadderResult ladder;
  const PhaseFitSummary s = SimulateAndFit(sim, dir, "clean", &ladder);
  EXPECT_EQ(s.result, PhaseFitSummary::Result::kNoMeasurableScattering) << s.message;
  EXPECT_NE(s.message.find("no measurable scattering"), std::string::npos);
  // Clean glass: the attenuator alone predicts the held-out rings within their noise.
  EXPECT_EQ(ladder.chosen_rung, 0);
  EXPECT_LT(ladder.held_out_chi2[0], 3);
}

// An isotropic scatterer (g = 0, all scattering orders in the Monte Carlo) comes out as the
// Frisvad thin isotropic slab: one parameter fewer than the HG layer, within noise of it.
TEST(LaserLobe, IsotropicLayerTakesTheIsotropicSlabRung) {
  TempDir dir;
  LaserLadderResult ladder;
  const PhaseFitSummary s = SimulateAndFit(TestRig(0.0, 4), dir, "isotropic", &ladder);
  ASSERT_TRUE(s.IsUsable()) << s.message;
  std::printf("isotropic: rung %d; held-out chi2 per ring %.3g, %.3g, %.3g; g %.4f\n", ladder.chosen_rung,
              ladder.held_out_chi2[0], ladder.held_out_chi2[1], ladder.held_out_chi2[2], ladder.gu_g);
  EXPECT_EQ(ladder.chosen_rung, 1);
  EXPECT_EQ(ladder.parameters[2] - ladder.parameters[ladder.chosen_rung], 1);
}

TEST(LaserLobe, OffCentreBeamAndSaturatedSpike) {
  TempDir dir;
  SyntheticLaserSessionOptions sim = TestRig(0.8, 3);
  sim.rig.beam_offset_m = Eigen::Vector2d(6e-3, -4e-3);
  sim.rig.spike_fill = 5;  // The spike saturates even at the shortest exposure.
  const PhaseFitSummary s = SimulateAndFit(sim, dir, "offset");
  ASSERT_TRUE(s.IsUsable()) << s.message;
  EXPECT_LT((s.beam_centre_m - sim.rig.beam_offset_m).norm(), 50e-6);
  EXPECT_LE(std::abs(s.g - 0.8), kMaxAbsErrorG);

  // tau free with a Gaussian prior around a shadow-map value that is 30 % off.
  PhaseFitOptions options;
  options.tau = 0.39;
  options.tau_free = true;
  options.tau_prior_sigma = 0.1;
  PhaseFitSummary free_tau;
  std::vector<LaserRing> rings;
  ASSERT_TRUE(FitPhasePipeline(dir / "offset", dir / "offset_free", options, LaserLobePreparationOptions(), false, "# test\n", &free_tau, &rings).ok());
  ASSERT_TRUE(free_tau.IsUsable()) << free_tau.message;
  std::printf("tau free (prior 0.39 +- 0.1): tau = %.3f +- %.3f, g = %.4f +- %.4f\n", free_tau.tau, free_tau.sigma_tau,
              free_tau.g, free_tau.sigma_g);
  EXPECT_GT(free_tau.sigma_tau, 0);
  EXPECT_LE(std::abs(free_tau.g - 0.8), kMaxAbsErrorG);
}

// Issue #24 section 2: a photon-starved lobe as a renderer writes it (one linear float exposure
// per light state, no read noise: most pixels exactly 0, the rest counts of a few photons). The
// ring value must not depend on how many camera pixels a board pixel averages. With the ring
// median (before 2026-12-05) the CLI capture `sim laser S --g 0.5 --linear-float-frames true
// --read-noise-e 0 --exposures-us 200 --photons 50000 --camera-width-px 800 --camera-height-px
// 600` failed at 0.2 mm (median 0 beyond ~50 degrees: g 0.98 +- 4e7) and gave 0.4995 at 0.4 mm;
// with the ring mean 0.4893 +- 0.026 and 0.4872 +- 0.027. Here (seed 6, no clean glass):
// 0.4917 +- 0.019 and 0.4905 +- 0.024.
TEST(LaserLobe, PhotonStarvedLobeGivesTheSameGAtEveryBoardPitch) {
  TempDir dir;
  SyntheticLaserSessionOptions sim = TestRig(0.5, 6);
  sim.rig.camera_width_px = 800;
  sim.rig.camera_height_px = 600;
  sim.rig.monte_carlo.num_photons = 50000;
  sim.rig.sensor.linear_float_frames = true;
  sim.rig.sensor.read_noise_e = 0;
  sim.session.exposure_times_us = {200};
  const std::string session = dir / "starved";
  ASSERT_TRUE(SynthesizeLaserLobeSession(sim, session).ok());
  PhaseFitOptions options;
  options.max_theta_auto = false;
  options.max_theta_deg = 60;
  std::vector<PhaseFitSummary> fits;
  for (double pitch_m : {0.2e-3, 0.4e-3}) {
    LaserLobePreparationOptions preparation;
    preparation.board_pitch_m = pitch_m;
    PhaseFitSummary s;
    std::vector<LaserRing> rings;
    const Status fit = FitPhasePipeline(session, dir / ("fit_" + std::to_string(fits.size())), options, preparation,
                                        false, "# test\n", &s, &rings);
    ASSERT_TRUE(fit.ok()) << fit.message();
    ASSERT_TRUE(s.IsUsable()) << s.message;
    // Starved: the outermost ring's mean is below 0.5 photo-electrons per camera pixel (frame
    // values are electrons), so over 60 % of its pixels are 0 and their median is 0.
    EXPECT_LT(rings.back().intensity * 200, 0.5) << pitch_m;
    std::printf("pitch %.1f mm: g = %.4f +- %.4f, %d rings, chi2/dof %.2f\n", pitch_m * 1e3, s.g, s.sigma_g,
                s.num_rings, s.chi2_reduced);
    EXPECT_LE(std::abs(s.g - 0.5), kMaxAbsErrorG);
    EXPECT_LE(std::abs(s.g - 0.5), 2 * s.sigma_g);
    fits.push_back(s);
  }
  // The same light at two pitches: g agrees far inside either sigma_g (whose multiple-scattering
  // term is shared, not independent noise).
  EXPECT_LE(std::abs(fits[0].g - fits[1].g), 0.01);
}

// Issue #24 section 2 ("an isolated bright pixel enters its ring's mean"): a glint on the board
// (stray light, a shiny speck), 3 x 3 camera pixels at 100x the local lobe in every laser frame,
// inside the rings the fit keeps, does not move g: the ring's sector-cluster standard error grows
// with the glint's sector and the Huber loss weighs the ring down. Measured by hand on a 480 x 360
// rig (`sim laser`, the glint added to the PNG frames): the two rings it falls in (19 and 20
// degrees) read 70-90x their clean means with standard errors 5e4x theirs, and g moved by 4e-5
// (sigma_g 0.006), also at 10 000x the local lobe.
TEST(LaserLobe, AGlintOnTheBoardDoesNotMoveG) {
  TempDir dir;
  SyntheticLaserSessionOptions sim = TestRig(0.8, 8);
  sim.rig.camera_width_px = 480;
  sim.rig.camera_height_px = 360;
  const std::string clean = dir / "clean", glint = dir / "glint";
  ASSERT_TRUE(SynthesizeLaserLobeSession(sim, clean).ok());
  std::filesystem::copy(clean, glint, std::filesystem::copy_options::recursive);
  Session session;
  ASSERT_TRUE(ReadSession(glint, &session).ok());
  std::vector<const FrameRecord*> laser;
  for (const FrameRecord& f : session.frames) {
    if (f.kind == "laser" && f.sample_state == "contaminated") laser.push_back(&f);
  }
  ASSERT_GE(laser.size(), 4u);
  // The spot (brightest pixel of the 2 ms frame) and the lobe's rate beside it (20 ms frame).
  const cv::Mat spot_frame = cv::imread(glint + "/" + laser[2]->file, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(spot_frame.empty());
  cv::Point spot;
  cv::minMaxLoc(spot_frame, nullptr, nullptr, nullptr, &spot);
  const cv::Rect patch(spot.x + 40 - 1, spot.y - 15 - 1, 3, 3);
  const cv::Mat lobe_frame = cv::imread(glint + "/" + laser[3]->file, cv::IMREAD_UNCHANGED);
  const double black = session.rig.cameras[0].black_level_dn, saturation = session.rig.cameras[0].saturation_dn;
  const double lobe_rate = (cv::mean(lobe_frame(patch))[0] - black) / laser[3]->exposure_time_us;
  ASSERT_GT(lobe_rate, 0);
  for (const FrameRecord* f : laser) {
    const std::string path = glint + "/" + f->file;
    cv::Mat frame = cv::imread(path, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(frame.type(), CV_16UC1) << path;
    cv::Mat region = frame(patch);
    for (int y = 0; y < region.rows; ++y) {
      for (int x = 0; x < region.cols; ++x) {
        const double v = region.at<uint16_t>(y, x) + 100 * lobe_rate * f->exposure_time_us;
        region.at<uint16_t>(y, x) = static_cast<uint16_t>(std::min(v, saturation));
      }
    }
    ASSERT_TRUE(cv::imwrite(path, frame)) << path;
  }
  std::vector<PhaseFitSummary> fits;
  for (const std::string& capture : {clean, glint}) {
    PhaseFitSummary s;
    std::vector<LaserRing> rings;
    const Status fit = FitPhasePipeline(capture, capture + "/fit/phase", PhaseFitOptions(),
                                        LaserLobePreparationOptions(), false, "# test\n", &s, &rings);
    ASSERT_TRUE(fit.ok()) << fit.message();
    ASSERT_TRUE(s.IsUsable()) << s.message;
    std::printf("%s: g = %.5f +- %.5f, outermost ring %.0f deg\n", capture.c_str(), s.g, s.sigma_g, s.max_theta_deg);
    fits.push_back(s);
  }
  // The glint lies inside the kept rings (it would test nothing beyond them).
  const double board_mm_per_px = 70.0 / 480;  // About: the imaged board is 70 mm wide.
  EXPECT_LT(std::atan(42.7 * board_mm_per_px / 20) * 180 / M_PI, fits[1].max_theta_deg);
  EXPECT_LE(std::abs(fits[1].g - fits[0].g), 0.25 * fits[0].sigma_g);
  EXPECT_LE(std::abs(fits[1].g - 0.8), kMaxAbsErrorG);
}

// Issue #24 section 2: few rings. Wide rings out to 30 degrees leave 5: the jackknife is
// delete-one (not 0), the angle-range term says it is not measured, and the ladder holds each
// ring out in turn; with so few held-out rings its paired test cannot reject the isotropic slab
// (measured: chosen rung 1 although rung 1 misses by 4.8e5 per ring against 22), so the fit of all
// rings (g 66 sigma_g from 0) decides, and `fit tau --phase` reads rung 2 with that g.
TEST(LaserLobe, FewRingsStillGiveJackknifeLadderAndLayerChoice) {
  TempDir dir;
  const std::string session = dir / "few";
  ASSERT_TRUE(SynthesizeLaserLobeSession(TestRig(0.5, 7), session).ok());
  PhaseFitOptions options;
  options.max_theta_auto = false;
  options.max_theta_deg = 30;
  options.ring_width_px = 10;
  PhaseFitSummary s;
  std::vector<LaserRing> rings;
  LaserLadderResult ladder;
  const std::string out = dir / "few_fit";
  ASSERT_TRUE(
      FitPhasePipeline(session, out, options, LaserLobePreparationOptions(), false, "# test\n", &s, &rings, &ladder).ok());
  ASSERT_TRUE(s.IsUsable()) << s.message;
  ASSERT_LT(s.num_rings, 10);
  std::printf("%d rings: g = %.4f +- %.4f (jackknife %.4f, %s), ladder rung %d (held-out choice %d)\n", s.num_rings,
              s.g, s.sigma_g, s.sigma_g_jackknife, s.jackknife_method.c_str(), ladder.chosen_rung,
              ladder.overruled_rung);
  EXPECT_GT(s.sigma_g_jackknife, 0);
  EXPECT_EQ(s.jackknife_method, "delete-one over " + std::to_string(s.num_rings) + " rings");
  EXPECT_FALSE(s.range_term_available);
  EXPECT_LE(std::abs(s.g - 0.5), 2 * s.sigma_g);
  std::string text;
  ASSERT_TRUE(ReadFileToString(out + "/summary.json", &text).ok());
  const nlohmann::json summary = nlohmann::json::parse(text, nullptr, false);
  EXPECT_TRUE(summary["sigma_g_range"].is_null());
  ASSERT_TRUE(std::filesystem::exists(out + "/ladder.json"));
  ASSERT_TRUE(ReadFileToString(out + "/ladder.json", &text).ok());
  EXPECT_EQ(nlohmann::json::parse(text, nullptr, false)["split"], "leave-one-out");
  EXPECT_EQ(ladder.held_out_rings, s.num_rings);
  EXPECT_EQ(ladder.chosen_rung, 2);
  PhaseLayerChoice choice;
  ASSERT_TRUE(ReadPhaseLayerChoice(out, &choice).ok());
  EXPECT_EQ(choice.rung, 2);
  EXPECT_DOUBLE_EQ(choice.g, s.g);
}

// A thick, bright layer: Eq. 8 (single scattering) misses the multiply scattered light by far
// more than the rings' noise, and the fit says so; a nearly black layer (albedo 0.01, single
// scattering only) does not get the warning (threshold chi2/dof 4, fit/phase_fit.cc). Measured
// chi2/dof: 5226 (g 0.711 +- 0.104 for 0.8) and 2.96 (g 0.7999 +- 0.0009).
TEST(LaserLobe, ModelMismatchIsWarnedWhenChiSquareIsFarFromOne) {
  TempDir dir;
  SyntheticLaserSessionOptions thick = TestRig(0.8, 8);
  thick.rig.layer_tau = 1.5;
  thick.rig.layer_albedo = 0.9;
  const PhaseFitSummary s = SimulateAndFit(thick, dir, "thick");
  ASSERT_EQ(s.result, PhaseFitSummary::Result::kSuccess) << s.message;
  std::printf("tau 1.5, albedo 0.9: g = %.4f +- %.4f (second-order term %.4f), chi2/dof %.1f\n", s.g, s.sigma_g,
              s.sigma_g_multiple, s.chi2_reduced);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("model mismatch"), std::string::npos) << s.warnings[0];
  std::string text;
  ASSERT_TRUE(ReadFileToString(dir / "thick/fit/phase/summary.json", &text).ok());
  EXPECT_EQ(nlohmann::json::parse(text, nullptr, false)["warnings"].size(), 1u);
  EXPECT_LE(std::abs(s.g - 0.8), 2 * s.sigma_g);

  SyntheticLaserSessionOptions dark = TestRig(0.8, 9);
  dark.rig.layer_albedo = 0.01;
  const PhaseFitSummary single = SimulateAndFit(dark, dir, "single");
  ASSERT_TRUE(single.IsUsable()) << single.message;
  std::printf("albedo 0.01: g = %.4f +- %.4f, chi2/dof %.2f\n", single.g, single.sigma_g, single.chi2_reduced);
  EXPECT_TRUE(single.warnings.empty()) << single.warnings[0];
  EXPECT_LE(std::abs(single.g - 0.8), 2 * single.sigma_g);
}

// A camera that integrates 3 ms longer than it reports: the fit's own HDR merge names the
// exposures it did not apply in summary.json, as `calib hdr` does. The lobe is well exposed in
// neighbouring frames from 20000 us on (the shorter frames see little more than the spike), so
// 20000 us is the shortest exposure measured: 23000 us integrated, x1.148 relative to the longest.
TEST(LaserLobe, FitNamesExposuresTheCameraDidNotApply) {
  TempDir dir;
  SyntheticLaserSessionOptions sim = TestRig(0.5, 5);
  sim.rig.sensor.exposure_offset_us = 3000;
  SimulateAndFit(sim, dir, "exposure_offset");
  std::string text;
  ASSERT_TRUE(ReadFileToString(dir / "exposure_offset/fit/phase/summary.json", &text).ok());
  const nlohmann::json check = nlohmann::json::parse(text, nullptr, false)["exposure_check"];
  const std::string warning = check["warning"];
  std::printf("exposure offset 3000 us: largest deviation %.4f; %s\n", check["max_deviation"].get<double>(),
              warning.c_str());
  const std::vector<double> reported = check["reported_us"], factor = check["measured_over_reported"];
  const auto it = std::find(reported.begin(), reported.end(), 20000.0);
  ASSERT_NE(it, reported.end());
  EXPECT_NEAR(factor[it - reported.begin()], 23000.0 / 20000 / (2003000.0 / 2000000), 0.02);
  EXPECT_NE(warning.find("20000 us reported"), std::string::npos) << warning;
}

}  // namespace
}  // namespace thinslab
