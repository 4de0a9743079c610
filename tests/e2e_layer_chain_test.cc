// SPDX-License-Identifier: Apache-2.0
// System test of the laser-lobe -> shadow-map chain of the model ladder (issue #8,
// docs/models/model_ladder.md): `thinslab fit tau --phase DIR` takes the layer model that
// `thinslab fit phase` chose on a lobe of the same layer (rung 0: plain Eq. 7; rung 1: g = 0;
// rung 2: the fitted g), and records where it came from.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "thinslab/app/commands.h"
#include "thinslab/app/stability_cases.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

constexpr double kLayerG = 0.5;

nlohmann::json ReadJson(const std::string& path) {
  std::string text;
  EXPECT_TRUE(ReadFileToString(path, &text).ok()) << path;
  return nlohmann::json::parse(text, nullptr, false);
}

// A small shadow-map capture of a layer with g = kLayerG (albedo 0.3).
std::string ShadowSession(const TempDir& dir) {
  SyntheticShadowSessionOptions sim = SmallShadowMapRig(8);
  sim.rig.layer_g = kLayerG;
  const double patch_taus[4] = {0.3, 0.8, 0.5, 1.2};
  const std::string session = dir / "shadow";
  EXPECT_TRUE(SynthesizeShadowMapSession(sim, PatchTau(48, 48, patch_taus, 0.05), session).ok());
  return session;
}

void WritePhaseDir(const std::string& dir, const std::string& result, double g, int ladder_rung) {
  std::filesystem::create_directories(dir);
  nlohmann::json summary = {{"format", "thinslab-fit-summary"},
                            {"model", "gu2007_eq8"},
                            {"result", result},
                            {"message", "test"},
                            {"g", g},
                            {"sigma_g", 0.01}};
  ASSERT_TRUE(WriteFileAtomically(dir + "/summary.json", summary.dump()).ok());
  if (ladder_rung >= 0) {
    ASSERT_TRUE(WriteFileAtomically(dir + "/ladder.json", nlohmann::json({{"chosen_rung", ladder_rung}}).dump()).ok());
  }
}

TEST(LayerChain, FitTauTakesGFromTheLaserLobeFit) {
  TempDir dir;
  const std::string lobe = dir / "lobe";
  ASSERT_TRUE(SynthesizeLaserLobeSession(SmallLaserLobeRig(0.3, kLayerG, 4), lobe).ok());
  PhaseFitOptions phase_options;
  phase_options.tau = 0.3;
  PhaseFitSummary phase;
  std::vector<LaserRing> rings;
  LaserLadderResult ladder;
  ASSERT_TRUE(FitPhasePipeline(lobe, dir / "phase", phase_options, LaserLobePreparationOptions(), false, "# test\n", &phase,
                               &rings, &ladder)
                  .ok());
  ASSERT_EQ(ladder.chosen_rung, 2);

  const std::string shadow = ShadowSession(dir);
  const RunResult chained =
      RunThinslab("fit tau " + shadow + " --out " + (dir / "chained") + " --phase " + (dir / "phase"));
  ASSERT_EQ(chained.exit_code, 0) << chained.output;
  const RunResult given =
      RunThinslab("fit tau " + shadow + " --out " + (dir / "given") + " --g " + std::to_string(kLayerG));
  ASSERT_EQ(given.exit_code, 0) << given.output;
  const RunResult wrong = RunThinslab("fit tau " + shadow + " --out " + (dir / "wrong") + " --g 0.9");
  ASSERT_EQ(wrong.exit_code, 0) << wrong.output;

  const nlohmann::json layer = ReadJson(dir / "chained/summary.json")["layer"];
  EXPECT_EQ(layer["g"].get<double>(), phase.g);
  EXPECT_EQ(layer["phase_ladder_rung"].get<int>(), 2);
  EXPECT_EQ(layer["source"].get<std::string>(), dir / "phase/summary.json");
  auto rms = [&](const std::string& name) {
    return ReadJson(dir / (name + "/comparison.json"))["refined"]["rms_relative"].get<double>();
  };
  std::printf(
      "lobe fit g = %.4f +- %.4f (true %.1f); tau RMS relative: with --phase %.4f, true g given %.4f, "
      "g 0.9 given %.4f\n",
      phase.g, phase.sigma_g, kLayerG, rms("chained"), rms("given"), rms("wrong"));
  EXPECT_LT(rms("chained"), 1.1 * rms("given"));
  EXPECT_GT(rms("wrong"), rms("chained"));
}

TEST(LayerChain, LadderRungSetsTheTauModel) {
  TempDir dir;
  const std::string shadow = ShadowSession(dir);
  WritePhaseDir(dir / "rung0", "success", 0.4, 0);
  WritePhaseDir(dir / "rung1", "success", 0.4, 1);
  WritePhaseDir(dir / "clean", "no_measurable_scattering", 0, -1);
  for (const char* name : {"rung0", "rung1", "clean"}) {
    const RunResult r = RunThinslab("fit tau " + shadow + " --out " + (dir / (std::string(name) + "_fit")) +
                                    " --phase " + (dir / name));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  const nlohmann::json rung0 = ReadJson(dir / "rung0_fit/summary.json")["layer"];
  EXPECT_FALSE(rung0["refine_scattering"].get<bool>());
  Image tau;
  ASSERT_TRUE(ReadExr(dir / "rung0_fit/tau.exr", &tau).ok());
  EXPECT_EQ(tau.attributes()["model"], "gu2007_eq7");
  const nlohmann::json rung1 = ReadJson(dir / "rung1_fit/summary.json")["layer"];
  EXPECT_TRUE(rung1["refine_scattering"].get<bool>());
  EXPECT_EQ(rung1["g"].get<double>(), 0.0);
  EXPECT_FALSE(ReadJson(dir / "clean_fit/summary.json")["layer"]["refine_scattering"].get<bool>());

  WritePhaseDir(dir / "failed", "failure", 0.4, -1);
  RunResult r = RunThinslab("fit tau " + shadow + " --out " + (dir / "failed_fit") + " --phase " + (dir / "failed"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("failed/summary.json: result is \"failure\""), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "failed_fit"));
  r = RunThinslab("fit tau " + shadow + " --phase " + (dir / "rung1") + " --g 0.3");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("either --phase or --g/--refine"), std::string::npos) << r.output;
  r = RunThinslab("fit tau " + shadow + " --phase " + (dir / "nothing"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("nothing/summary.json: not found"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace thinslab
