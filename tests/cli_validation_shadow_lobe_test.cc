// SPDX-License-Identifier: Apache-2.0
// Issue #23 section 4 for shadow maps and laser lobes, through the binary: validation frames
// (frames[k].validation) are never fitted (the map is the same, bit for bit, without them);
// `fit tau` and `fit phase` report how well their result predicts them with the noise level
// beside it; `thinslab predict` predicts another capture of the same sample at another board
// distance, where the scattered light (Gu Eq. 6) and the lobe's geometry (Eq. 8) differ from
// the fitted capture's, so the prediction tests the model and not only repeatability. Every
// figure can fail: a map fitted without the scattering model, or a g off by 0.1, reads far
// worse. Captures of different seeds: frames of equal seeds share their noise.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"

namespace thinslab {
namespace {

constexpr const char* kSmallShadow = " --camera-width-px 320 --camera-height-px 240 --photons 20000 --frames 2";
constexpr const char* kSmallLaser = " --camera-width-px 400 --camera-height-px 300";

// What the capture's noise and the map's sigma_tau together allow.
double Expected(const nlohmann::json& region) {
  return std::hypot(region["noise_relative_rms"].get<double>(), region["sigma_tau_relative_rms"].get<double>());
}

TEST(CliValidationShadowLobe, TauMapsPredictValidationFramesAndOtherBoardDistances) {
  TempDir dir;
  const std::string a = dir / "a";
  RunThinslabOk("sim shadow-maps " + a + kSmallShadow + " --validation-frames 2 --board-distance-mm 1 --seed 1");
  const RunResult info = RunThinslabOk("info " + a);
  EXPECT_NE(info.output.find("validation frames (not fitted): 2"), std::string::npos) << info.output;
  RunThinslabOk("fit tau " + a);
  const nlohmann::json validation = ReadJsonFile(a + "/fit/tau/summary.json")["validation"];
  ASSERT_EQ(validation["frames"], 2) << validation.dump();
  // The same light state: the error is the frames' noise, which the noise model must describe
  // (neither more nor much less).
  for (const char* name : {"clean", "thin", "all"}) {
    const nlohmann::json& r = Region(validation["regions"], name);
    const double error = r["relative_rms"].get<double>(), noise = r["noise_relative_rms"].get<double>();
    std::printf("fit tau validation, %s: relative RMS %.4f, noise alone %.4f\n", name, error, noise);
    EXPECT_GT(r["pixels"].get<int>(), 500) << r.dump();
    EXPECT_LT(error, 1.3 * noise) << r.dump();
    EXPECT_GT(error, 0.7 * noise) << r.dump();
  }

  // Never fitted: the manifest without them gives the same map.
  const std::string without = dir / "without";
  ASSERT_EQ(std::system(("cp -r " + a + " " + without).c_str()), 0);
  std::filesystem::remove_all(without + "/fit");
  nlohmann::json session = ReadJsonFile(without + "/session.json");
  nlohmann::json kept = nlohmann::json::array();
  for (const nlohmann::json& f : session["frames"]) {
    if (!f.value("validation", false)) kept.push_back(f);
  }
  ASSERT_EQ(kept.size() + 2, session["frames"].size());
  session["frames"] = kept;
  ASSERT_TRUE(WriteFileAtomically(without + "/session.json", session.dump(2)).ok());
  RunThinslabOk("fit tau " + without);
  Image with_map, without_map;
  ASSERT_TRUE(ReadExr(a + "/fit/tau/tau.exr", &with_map).ok());
  ASSERT_TRUE(ReadExr(without + "/fit/tau/tau.exr", &without_map).ok());
  EXPECT_EQ(with_map.data(), without_map.data());
  EXPECT_TRUE(ReadJsonFile(without + "/fit/tau/summary.json")["validation"].is_null());

  // Another capture of the same layer with the board at 10 mm: the scattered light spreads ten
  // times wider. The refined map predicts it within what noise and sigma_tau allow; plain Eq. 7
  // (no scattered light) and a map fitted without the scattering model cannot.
  const std::string b = dir / "b";
  RunThinslabOk("sim shadow-maps " + b + kSmallShadow + " --board-distance-mm 10 --seed 7");
  RunThinslabOk("predict " + b + " --fit " + a + "/fit/tau --out " + (dir / "predict"));
  const nlohmann::json predicted = ReadJsonFile(dir / "predict/summary.json");
  EXPECT_EQ(predicted["kind"], "shadow");
  EXPECT_EQ(predicted["measured_frames"], "fitted");
  EXPECT_NEAR(predicted["board_distance_m"].get<double>(), 0.01, 1e-12);
  for (const char* name : {"thin", "thick", "all"}) {
    const nlohmann::json& r = Region(predicted["regions"], name);
    const double error = r["relative_rms"].get<double>(), plain = r["plain_relative_rms"].get<double>();
    std::printf("predict at 10 mm, %s: relative RMS %.4f (plain Eq. 7 %.4f), noise and sigma_tau allow %.4f\n", name,
                error, plain, Expected(r));
    EXPECT_GT(r["pixels"].get<int>(), 100) << r.dump();
    EXPECT_LT(error, 1.5 * Expected(r)) << r.dump();
    EXPECT_GT(plain, 2 * error) << r.dump();
  }
  Image shadow;
  ASSERT_TRUE(ReadExr(dir / "predict/shadow.exr", &shadow).ok());
  EXPECT_GE(shadow.ChannelIndex("predicted"), 0);
  EXPECT_GE(shadow.ChannelIndex("measured"), 0);
  // The same in the capture's camera pixels (each the mean over its footprint): the map's pitch
  // adds its own error, and plain Eq. 7 still reads clearly worse.
  Image camera_shadow;
  ASSERT_TRUE(ReadExr(dir / "predict/shadow_camera.exr", &camera_shadow).ok());
  EXPECT_EQ(camera_shadow.width(), 320);
  EXPECT_GE(camera_shadow.ChannelIndex("valid"), 0);
  for (const char* name : {"thin", "thick"}) {
    const nlohmann::json& r = Region(predicted["camera_regions"], name);
    std::printf("predict at 10 mm in camera pixels, %s: relative RMS %.4f (plain Eq. 7 %.4f)\n", name,
                r["relative_rms"].get<double>(), r["plain_relative_rms"].get<double>());
    EXPECT_GT(r["pixels"].get<int>(), 100) << r.dump();
    EXPECT_GT(r["plain_relative_rms"].get<double>(), 1.5 * r["relative_rms"].get<double>()) << r.dump();
  }

  // A map fitted without Eq. 6 misses by more than its own error bars allow and by far more
  // than the refined map. (Before sigma_tau had its resolution term, 2026-12-05, its allowance
  // was 0.0197 and the test asked for 3x; the resolution term, which the fitted and the
  // predicted capture share through the same camera, now allows 0.055 for an error of 0.104.)
  RunThinslabOk("fit tau " + a + " --refine false --out " + (dir / "plain_fit"));
  RunThinslabOk("predict " + b + " --fit " + (dir / "plain_fit") + " --out " + (dir / "predict_plain"));
  const nlohmann::json plain_summary = ReadJsonFile(dir / "predict_plain/summary.json");
  const nlohmann::json& thick = Region(plain_summary["regions"], "thick");
  std::printf("predict at 10 mm from a map fitted without Eq. 6: thick relative RMS %.4f, allowed %.4f\n",
              thick["relative_rms"].get<double>(), Expected(thick));
  EXPECT_GT(thick["relative_rms"].get<double>(), Expected(thick)) << thick.dump();
  EXPECT_GT(thick["relative_rms"].get<double>(),
            5 * Region(predicted["regions"], "thick")["relative_rms"].get<double>())
      << thick.dump();
}

TEST(CliValidationShadowLobe, LobeFitsPredictValidationBracketsAndOtherBoardDistances) {
  TempDir dir;
  const std::string a = dir / "a";
  RunThinslabOk("sim laser " + a + kSmallLaser + " --capture-validation true --board-distance-mm 20 --seed 3");
  RunThinslabOk("fit phase " + a);
  const nlohmann::json summary = ReadJsonFile(a + "/fit/phase/summary.json");
  ASSERT_EQ(summary["result"], "success") << summary.dump();
  const nlohmann::json& validation = summary["validation"];
  ASSERT_GT(validation["frames"].get<int>(), 1) << validation.dump();
  const nlohmann::json& all = validation["bands"].back();
  ASSERT_EQ(all["theta_range_deg"][1], 90) << validation.dump();
  std::printf("fit phase validation: relative RMS %.4f, noise alone %.4f over %d rings\n",
              all["relative_rms"].get<double>(), all["noise_relative_rms"].get<double>(), all["rings"].get<int>());
  EXPECT_GE(all["rings"].get<int>(), 10);
  EXPECT_LT(all["relative_rms"].get<double>(), 1.5 * all["noise_relative_rms"].get<double>()) << all.dump();
  EXPECT_NEAR(validation["scale_ratio"].get<double>(), 1, 0.05) << validation.dump();

  // The board at 30 mm: the same angles fall on wider rings and beta scales as 1 / d^2.
  const std::string b = dir / "b";
  RunThinslabOk("sim laser " + b + kSmallLaser + " --board-distance-mm 30 --seed 11");
  RunThinslabOk("predict " + b + " --fit " + a + "/fit/phase --out " + (dir / "predict"));
  const nlohmann::json predicted = ReadJsonFile(dir / "predict/summary.json");
  EXPECT_EQ(predicted["kind"], "lobe");
  const nlohmann::json& lobe = predicted["lobe"];
  const double error = lobe["bands"].back()["relative_rms"].get<double>();
  std::printf("predict at 30 mm: relative RMS %.4f (noise alone %.4f), scale ratio %.3f\n", error,
              lobe["bands"].back()["noise_relative_rms"].get<double>(), lobe["scale_ratio"].get<double>());
  EXPECT_NEAR(lobe["scale_ratio"].get<double>(), 1, 0.1) << lobe.dump();
  // Eq. 8 is single scattering and the simulated lobe is not: 0.009 measured (docs/models/laser_lobe_g.md).
  EXPECT_LT(error, 0.03) << lobe.dump();
  EXPECT_TRUE(FileExists(dir / "predict/lobe_rings.csv"));
  // The same lobe imaged in the camera's pixels (flat and clean glass put back), per pixel.
  const nlohmann::json& camera = predicted["lobe_camera"];
  std::printf("predict at 30 mm in camera pixels: relative RMS %.4f (noise alone %.4f) over %d px\n",
              camera["relative_rms"].get<double>(), camera["noise_relative_rms"].get<double>(),
              camera["pixels"].get<int>());
  EXPECT_GT(camera["pixels"].get<int>(), 1000) << camera.dump();
  EXPECT_LT(camera["relative_rms"].get<double>(), 2 * camera["noise_relative_rms"].get<double>()) << camera.dump();
  Image lobe_camera;
  ASSERT_TRUE(ReadExr(dir / "predict/lobe_camera.exr", &lobe_camera).ok());
  EXPECT_EQ(lobe_camera.width(), 400);

  // Able to fail: the same fit with g 0.1 lower.
  const std::string wrong = dir / "wrong";
  ASSERT_EQ(std::system(("cp -r " + a + "/fit/phase " + wrong).c_str()), 0);
  nlohmann::json edited = ReadJsonFile(wrong + "/summary.json");
  edited["g"] = edited["g"].get<double>() - 0.1;
  ASSERT_TRUE(WriteFileAtomically(wrong + "/summary.json", edited.dump(2)).ok());
  RunThinslabOk("predict " + b + " --fit " + wrong + " --out " + (dir / "predict_wrong"));
  const nlohmann::json wrong_summary = ReadJsonFile(dir / "predict_wrong/summary.json");
  const double wrong_error = wrong_summary["lobe"]["bands"].back()["relative_rms"].get<double>();
  const double wrong_camera = wrong_summary["lobe_camera"]["relative_rms"].get<double>();
  std::printf("predict at 30 mm with g 0.1 lower: relative RMS %.4f, in camera pixels %.4f\n", wrong_error,
              wrong_camera);
  EXPECT_GT(wrong_error, 5 * error);
  EXPECT_GT(wrong_camera, 5 * camera["relative_rms"].get<double>());
}

}  // namespace
}  // namespace thinslab
