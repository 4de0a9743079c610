// SPDX-License-Identifier: Apache-2.0
// Flat field (calib/flat_field) and the three radiometric commands end to end on a simulated
// bracket session: nonlinear 12-bit camera, ambient light seen by the dark frames, noise,
// quantisation and saturation.
#include "thinslab/calib/flat_field.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "thinslab/app/commands.h"
#include "thinslab/calib/response_io.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/sim/exposure_bracket_sim.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

int RunCommand(int (*command)(int, char**), std::vector<std::string> args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return command(static_cast<int>(argv.size()), argv.data());
}

// A smooth illumination (quadratic fall-off, 30 % at the corners) with noise of known variance
// and a block of saturated pixels: the flat is the field over its median, within the smoothed
// noise, and the saturated block is flagged invalid.
TEST(FlatField, NormalisesSmoothsAndFlags) {
  const int w = 160, h = 120;
  Image radiance(w, h), variance(w, h), saturated(w, h);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal(0, 1);
  auto field = [&](int x, int y) {
    const double u = (x + 0.5) / w - 0.5, v = (y + 0.5) / h - 0.5;
    return 1.0 - 0.6 * (u * u + v * v);
  };
  const double scale = 40, sigma = 0.02 * scale;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      radiance.at(x, y) = static_cast<float>(scale * field(x, y) + sigma * normal(rng));
      variance.at(x, y) = static_cast<float>(sigma * sigma);
      if (x >= 10 && x < 20 && y >= 10 && y < 20) saturated.at(x, y) = 1;
    }
  }
  FlatFieldOptions options;
  options.smoothing_sigma_px = 4;
  Image flat;
  FlatFieldSummary summary;
  ASSERT_TRUE(ComputeFlatField(radiance, variance, saturated, options, &flat, &summary).ok());
  ASSERT_EQ(flat.channel_names(), (std::vector<std::string>{"flat", "variance", "valid"}));
  std::vector<double> truth;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) truth.push_back(field(x, y));
  }
  std::nth_element(truth.begin(), truth.begin() + truth.size() / 2, truth.end());
  const double median = truth[truth.size() / 2];
  double sum_z2 = 0;
  int n = 0;
  for (int y = 8; y < h - 8; ++y) {
    for (int x = 8; x < w - 8; ++x) {
      if (x >= 6 && x < 24 && y >= 6 && y < 24) continue;
      const double expected = field(x, y) / median;
      // Smoothing a quadratic adds sigma^2 * laplacian / 2 of bias: 4^2 * 2 * 0.6 / w^2 ~ 1e-3.
      EXPECT_NEAR(flat.at(x, y, 0), expected, 0.01) << x << "," << y;
      sum_z2 += std::pow(flat.at(x, y, 0) - expected, 2) / flat.at(x, y, 1);
      ++n;
    }
  }
  // The variance channel carries the smoothing's noise reduction (within a factor 2: the
  // median's own noise and the curvature bias add to the residual).
  EXPECT_GT(sum_z2 / n, 0.5);
  EXPECT_LT(sum_z2 / n, 2.0);
  EXPECT_EQ(flat.at(15, 15, 2), 1.0f);  // Surrounded by valid pixels within the kernel: filled in.
  EXPECT_EQ(summary.pixels_invalid, 0);
  for (int y = 10; y < 20; ++y) {
    for (int x = 10; x < 20; ++x) EXPECT_NEAR(flat.at(x, y, 0), field(x, y) / median, 0.02);
  }
  options.smoothing_sigma_px = 0;
  ASSERT_TRUE(ComputeFlatField(radiance, variance, saturated, options, &flat, &summary).ok());
  EXPECT_EQ(flat.at(15, 15, 2), 0.0f);  // Without smoothing a saturated pixel stays invalid.
  EXPECT_EQ(summary.pixels_invalid, 100);
  options.smoothing_sigma_px = -1;
  EXPECT_NE(ComputeFlatField(radiance, variance, saturated, options, &flat, &summary).message().find(
                "FlatFieldOptions::smoothing_sigma_px"),
            std::string::npos);
}

// thinslab calib response / hdr / flat on a simulated session: the response is recovered, the
// HDR radiance is proportional to the true scene (ambient removed by the dark frames), the flat
// is the scene over its median, everything lands in SESSION/calib/, and the frames are untouched.
TEST(RadiometryCommands, ResponseHdrFlatOnSimulatedSession) {
  TempDir dir;
  const std::string session_dir = dir / "bracket";
  BracketSimOptions sim;
  sim.width_px = 160;
  sim.height_px = 80;
  sim.min_e_per_us = 0.05;
  sim.max_e_per_us = 200;
  sim.ambient_e_per_us = 0.1;
  sim.dark_frames_per_exposure = 2;
  sim.sensor.response = SimResponseCurve::kGamma;
  sim.seed = 9;
  ASSERT_TRUE(SynthesizeBracketSession(sim, session_dir).ok());
  std::string frame_before;
  ASSERT_TRUE(ReadFileToString(JoinPath(session_dir, "frames/cam0/bracket/0000.png"), &frame_before).ok());

  ASSERT_EQ(RunCommand(RunCalibResponse, {session_dir, "--method", "robertson"}), 0);
  CameraResponse response;
  ASSERT_TRUE(ReadResponse(JoinPath(session_dir, "calib/response.json"), &response).ok());
  EXPECT_EQ(response.method, "robertson");
  EXPECT_EQ(response.camera_id, "cam0");
  EXPECT_EQ(response.exposures_us.size(), sim.exposures_us.size());

  ASSERT_EQ(RunCommand(RunCalibHdr, {session_dir}), 0);
  Image hdr;
  ASSERT_TRUE(ReadExr(JoinPath(session_dir, "calib/hdr/bracket.exr"), &hdr).ok());
  const int radiance_c = hdr.ChannelIndex("radiance"), variance_c = hdr.ChannelIndex("variance");
  ASSERT_GE(radiance_c, 0);
  ASSERT_GE(variance_c, 0);
  ASSERT_GE(hdr.ChannelIndex("saturated"), 0);
  EXPECT_TRUE(FileExists(JoinPath(session_dir, "calib/hdr/summary.json")));
  Image scene;
  ASSERT_TRUE(ReadExr(JoinPath(session_dir, "ground_truth/scene.exr"), &scene).ok());
  std::vector<double> ratios;
  for (int y = 0; y < scene.height(); ++y) {
    for (int x = 0; x < scene.width(); ++x) ratios.push_back(hdr.at(x, y, radiance_c) / scene.at(x, y));
  }
  std::sort(ratios.begin(), ratios.end());
  const double median_ratio = ratios[ratios.size() / 2];
  // Linear in the scene: 90 % of pixels within 5 % of the common scale, over 3.6 decades.
  const double low = ratios[ratios.size() / 20], high = ratios[ratios.size() * 19 / 20];
  EXPECT_GT(low / median_ratio, 0.95);
  EXPECT_LT(high / median_ratio, 1.05);

  ASSERT_EQ(RunCommand(RunCalibFlat, {session_dir, "--kind", "bracket", "--sigma-px", "0"}), 0);
  Image flat;
  ASSERT_TRUE(ReadExr(JoinPath(session_dir, "calib/flat_field.exr"), &flat).ok());
  const int flat_c = flat.ChannelIndex("flat");
  ASSERT_GE(flat_c, 0);
  std::vector<float> values = scene.data();
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  const double scene_median = values[values.size() / 2];
  int within = 0, total = 0;
  for (int y = 0; y < scene.height(); ++y) {
    for (int x = 0; x < scene.width(); ++x) {
      if (scene.at(x, y) < 0.2 * scene_median) continue;
      within += std::abs(flat.at(x, y, flat_c) / (scene.at(x, y) / scene_median) - 1) < 0.05;
      ++total;
    }
  }
  EXPECT_GT(within, 0.9 * total);

  std::string frame_after;
  ASSERT_TRUE(ReadFileToString(JoinPath(session_dir, "frames/cam0/bracket/0000.png"), &frame_after).ok());
  EXPECT_EQ(frame_before, frame_after);

  // Bad input: a frame file gone, an unknown method, a response of another camera.
  EXPECT_NE(RunCommand(RunCalibResponse, {session_dir, "--method", "mitsuba"}), 0);
  CameraResponse other = response;
  other.camera_id = "cam7";
  ASSERT_TRUE(WriteResponse(dir / "other.json", other).ok());
  EXPECT_NE(RunCommand(RunCalibHdr, {session_dir, "--response", dir / "other.json"}), 0);
  std::remove(JoinPath(session_dir, "frames/cam0/bracket/0002.png").c_str());
  EXPECT_NE(RunCommand(RunCalibResponse, {session_dir}), 0);
}

// Two brackets with the same five exposures: a wide-range scene (kind "reference") and a nearly
// uniform one (kind "flat", which sorts first). Without --kind, `calib response` must use the
// wide one, whose values cover the DN range, and say why; asked for the flat one it warns.
TEST(RadiometryCommands, ResponsePrefersTheBracketSpanningTheDnRange) {
  TempDir dir;
  const std::string session_dir = dir / "two_brackets";
  BracketSimOptions wide;
  wide.width_px = 160;
  wide.height_px = 80;
  wide.sensor.response = SimResponseCurve::kGamma;
  wide.seed = 4;
  ASSERT_TRUE(SynthesizeBracketSession(wide, session_dir).ok());
  BracketSimOptions flat = wide;
  flat.min_e_per_us = 1.0;
  flat.max_e_per_us = 1.05;
  flat.texture_amplitude = 0;
  SimulatedBracket flat_frames;
  ASSERT_TRUE(SimulateBracket(flat, &flat_frames).ok());
  Session session;
  ASSERT_TRUE(ReadSession(session_dir, &session).ok());
  for (FrameRecord& f : session.frames) {
    if (f.kind == "bracket") f.kind = "reference";
  }
  const FrameRecord first = session.frames[0];
  ASSERT_TRUE(CreateDirectories(JoinPath(session_dir, "frames/cam0/flat")).ok());
  for (size_t k = 0; k < flat_frames.frames.size(); ++k) {
    FrameRecord f = first;
    f.index = static_cast<int>(session.frames.size());
    f.kind = "flat";
    f.file = "frames/cam0/flat/" + std::to_string(k) + ".png";
    f.exposure_time_us = flat_frames.frame_exposures_us[k];
    ASSERT_TRUE(WriteRawFrame(JoinPath(session_dir, f.file), flat_frames.frames[k], wide.sensor.bit_depth).ok());
    session.frames.push_back(f);
  }
  ASSERT_TRUE(WriteSession(session_dir, session).ok());

  auto response_of = [&](std::vector<std::string> args, std::string* stdout_text) {
    args.insert(args.begin(), session_dir);
    testing::internal::CaptureStdout();
    EXPECT_EQ(RunCommand(RunCalibResponse, args), 0);
    *stdout_text = testing::internal::GetCapturedStdout();
    CameraResponse r;
    EXPECT_TRUE(ReadResponse(args.back(), &r).ok()) << args.back();
    return r;
  };
  std::string automatic_out, reference_out, flat_out;
  const CameraResponse automatic = response_of({"--out", dir / "auto.json"}, &automatic_out);
  const CameraResponse reference =
      response_of({"--kind", "reference", "--out", dir / "reference.json"}, &reference_out);
  const CameraResponse from_flat = response_of({"--kind", "flat", "--out", dir / "flat.json"}, &flat_out);
  std::cout << automatic_out << flat_out;
  // The automatic choice is the reference bracket: the same curve, knot for knot.
  EXPECT_EQ(automatic.linear_dn, reference.linear_dn);
  EXPECT_NE(automatic.linear_dn, from_flat.linear_dn);
  EXPECT_NE(automatic_out.find("using 'reference'"), std::string::npos) << automatic_out;
  EXPECT_EQ(automatic_out.find("warning:"), std::string::npos) << automatic_out;
  EXPECT_NE(flat_out.find("warning: bracket 'flat' covers only"), std::string::npos) << flat_out;
}

}  // namespace
}  // namespace thinslab
