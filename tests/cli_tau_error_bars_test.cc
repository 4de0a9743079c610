// SPDX-License-Identifier: Apache-2.0
// Issue #24 section 1 through the binary: sigma_tau that covers the error on captures made
// harder than the simulator's defaults (texture finer than the camera, one linear float frame
// with no gain known, the board 10 mm away, the clean reference judged from the shadow), the
// camera footprint per map pixel with a warning when the map is finer than the camera resolves,
// a mixed-pixel status, and the split-half consistency figure, which must also fail when the
// manifest declares a wrong gain.
//
// The frames come from the simulated shadow-map rig (Monte Carlo light transport of every
// scattering order, Poisson shot noise and read noise per pixel, 12-bit quantisation or linear
// floats), rendered through an oblique camera; the fit models single scattering (Gu Eq. 6).
#include <gtest/gtest.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "thinslab/core/file.h"
#include "tests/testing/json_file.h"
#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

void RunOk(const std::string& args) {
  const RunResult run = RunThinslab(args);
  ASSERT_EQ(run.exit_code, 0) << "thinslab " << args << "\n" << run.output;
}

// Simulates a capture with `sim_options`, fits it with `fit_options`, returns the fit's
// summary.json with its comparison.json (the sim's ground truth) under "comparison".
nlohmann::json SimulateAndFit(const TempDir& dir, const std::string& name, const std::string& sim_options,
                              const std::string& fit_options = "") {
  const std::string capture = dir / name;
  RunOk("sim shadow-maps " + capture + " " + sim_options);
  RunOk("fit tau " + capture + " " + fit_options);
  nlohmann::json summary = ReadJsonFile(capture + "/fit/tau/summary.json");
  summary["comparison"] = ReadJsonFile(capture + "/fit/tau/comparison.json");
  return summary;
}

// The coverage goal of issue #24 section 4 on status-ok pixels with tau_true in [0.05, 1.5].
void ExpectCoverage(const nlohmann::json& summary, const std::string& name) {
  const nlohmann::json& refined = summary["comparison"]["refined"];
  const double within_1 = refined["within_1_sigma"], within_2 = refined["within_2_sigma"];
  const double ok = refined["ok_fraction"];
  std::printf("%s: within 1 sigma %.3f, 2 sigma %.3f, ok %.3f, rms relative %.3f, sigma parts %s, split-half %s\n",
              name.c_str(), within_1, within_2, ok, refined["rms_relative"].get<double>(),
              summary["sigma_tau_parts_median"].dump().c_str(), summary["consistency"].dump().c_str());
  EXPECT_GE(within_1, 0.6) << name;
  EXPECT_GE(within_2, 0.9) << name;
  EXPECT_GE(ok, 0.5) << name;
}

constexpr const char* kSmallCamera = "--camera-width-px 200 --camera-height-px 150 --photons 50000";

// Texture finer than the camera: the 0.08 mm map under a camera pixel covering 0.14 mm of the
// board. The footprint is reported, the fit warns, the resolution term carries the error, and
// steep edges are mixed. A camera pixel of 0.014 mm gives no warning.
TEST(TauErrorBars, FinerThanTheCameraIsReportedAndCovered) {
  TempDir dir;
  const nlohmann::json fine =
      SimulateAndFit(dir, "fine", "--camera-width-px 160 --camera-height-px 120 --photons 50000");
  const nlohmann::json& resolution = fine["resolution"];
  const double footprint = resolution["camera_footprint_m"]["median"];
  EXPECT_NEAR(resolution["map_pitch_m"].get<double>(), 8e-5, 1e-12);
  EXPECT_GT(footprint, 1.5 * 8e-5);
  EXPECT_LT(resolution["camera_pixels_per_map_pixel"].get<double>(), 0.5);
  ASSERT_FALSE(fine["warnings"].empty());
  EXPECT_NE(fine["warnings"][0].get<std::string>().find("finer than the camera resolves"), std::string::npos);
  EXPECT_GT(fine["pixels"]["mixed"].get<int>(), 0);
  EXPECT_GT(fine["sigma_tau_parts_median"]["resolution"].get<double>(), 0);
  ExpectCoverage(fine, "camera pixel 0.14 mm, map 0.08 mm");

  const nlohmann::json sharp =
      SimulateAndFit(dir, "sharp", "--camera-width-px 1600 --camera-height-px 1200 --photons 50000");
  EXPECT_LT(sharp["resolution"]["camera_footprint_m"]["median"].get<double>(), 8e-5);
  EXPECT_TRUE(sharp["warnings"].empty()) << sharp["warnings"].dump();
  // Issue #29: the memory estimate the budget is checked against bounds the measured peak (here
  // the 1600 x 1200 camera's frames), without being far above it; the default budget is 2 GiB.
  const nlohmann::json& memory = sharp["memory"];
  const double estimated = memory["estimated_bytes"], peak = memory["peak_resident_bytes"];
  EXPECT_EQ(memory["budget_bytes"].get<double>(), 2.0 * (1u << 30));
  EXPECT_GE(estimated, peak) << memory.dump();
  EXPECT_LE(estimated, 2 * peak) << memory.dump();
}

// One linear float frame per light state at value scale 1000, no gain in the manifest: the
// noise comes from the frame itself (the two dark frames alone cannot give the shot noise);
// no split-half check is possible, and the summary says why.
TEST(TauErrorBars, OneFloatFrameWithoutGainIsCovered) {
  TempDir dir;
  const nlohmann::json s = SimulateAndFit(
      dir, "float", std::string(kSmallCamera) + " --linear-float-frames true --frames 1 --value-scale 1000");
  EXPECT_EQ(s["noise"]["method"], "single_frame_residual");
  EXPECT_NEAR(s["noise"]["variance_per_value"].get<double>(), 1000, 100);  // Values per electron.
  EXPECT_NE(s["consistency"]["skipped"].get<std::string>().find("1 shadow frame"), std::string::npos);
  ExpectCoverage(s, "one float frame, value scale 1000");
}

TEST(TauErrorBars, FarBoardAndJudgedReferenceAreCovered) {
  TempDir dir;
  ExpectCoverage(SimulateAndFit(dir, "far", std::string(kSmallCamera) + " --board-distance-mm 10"), "board 10 mm");
  const nlohmann::json judged =
      SimulateAndFit(dir, "judged", std::string(kSmallCamera) + " --board-distance-mm 3", "--reference auto");
  EXPECT_GT(judged["sigma_tau_parts_median"]["reference"].get<double>(), 0);
  ExpectCoverage(judged, "reference auto, board 3 mm");
}

// The split-half figure holds on an honest capture (fits of the even and odd frames differ by
// what the noise part of sigma_tau says) and fails, with a warning, when the manifest declares
// a gain 16x too high (noise variance 16x too small).
TEST(TauErrorBars, SplitHalfConsistencyHoldsAndCanFail) {
  TempDir dir;
  const nlohmann::json honest = SimulateAndFit(dir, "honest", kSmallCamera);
  const double rms_z = honest["consistency"]["rms_z"];
  EXPECT_GT(honest["consistency"]["pixels"].get<int>(), 10000);
  EXPECT_GT(rms_z, 0.8);
  EXPECT_LT(rms_z, 1.25);
  EXPECT_NEAR(honest["consistency"]["within_1_sigma"].get<double>(), 0.68, 0.08);
  EXPECT_FALSE(honest.contains("rms_normalized_residual"));

  const std::string wrong = dir / "wrong_gain";
  RunOk("sim shadow-maps " + wrong + " " + kSmallCamera);
  const std::string manifest = wrong + "/session.json";
  nlohmann::json session = ReadJsonFile(manifest);
  nlohmann::json& camera = session["rig"]["cameras"][0];
  ASSERT_TRUE(camera.contains("gain_e_per_dn")) << camera.dump();
  camera["gain_e_per_dn"] = camera["gain_e_per_dn"].get<double>() * 16;
  if (camera.contains("read_noise_dn")) camera["read_noise_dn"] = camera["read_noise_dn"].get<double>() / 4;
  ASSERT_TRUE(WriteFileAtomically(manifest, session.dump(2)).ok());
  const RunResult run = RunThinslab("fit tau " + wrong);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json s = ReadJsonFile(wrong + "/fit/tau/summary.json");
  std::printf("gain declared 16x too high: split-half %s\n", s["consistency"].dump().c_str());
  EXPECT_GT(s["consistency"]["rms_z"].get<double>(), 2);
  EXPECT_NE(run.output.find("split-half consistency"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace thinslab
