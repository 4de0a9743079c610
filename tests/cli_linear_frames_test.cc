// SPDX-License-Identifier: Apache-2.0
// Issue #23 sections 1-2 through the binary: captures written as another program writes them
// (linear float EXR frames, one exposure per light state, no gain in the manifest, no dark
// frames) run through every fit without a faked bracket, the noise is estimated from the frames
// and recorded in summary.json, and one capture written at value scale 1 and 1000 gives the
// same statuses, ladder rungs and maps (values up to the scale).
//
// The frames come from the simulated rigs (Monte Carlo light transport, Poisson shot noise and
// Gaussian read noise per pixel) written as linear floats: electrons times --value-scale.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "thinslab/core/exr_io.h"
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

// The noise records of the two scales: same method and levels, floor x scale^2, slope x scale.
void ExpectNoiseScales(const nlohmann::json& small, const nlohmann::json& large, double scale) {
  ASSERT_TRUE(small.contains("noise")) << small.dump();
  const nlohmann::json& a = small["noise"];
  const nlohmann::json& b = large["noise"];
  EXPECT_EQ(a["method"], b["method"]);
  EXPECT_TRUE(a["method"] == "single_frame_residual" || a["method"] == "repeated_frames") << a.dump();
  EXPECT_EQ(a["levels"], b["levels"]);
  EXPECT_NEAR(b["variance_floor"].get<double>() / a["variance_floor"].get<double>(), scale * scale,
              1e-3 * scale * scale);
  EXPECT_NEAR(b["variance_per_value"].get<double>() / a["variance_per_value"].get<double>(), scale, 1e-3 * scale);
}

// Fraction of pixels where channel `name` of the two images differs by more than `tolerance`
// (relative to `scale` times the first image's value, plus `tolerance` absolute).
double FractionDiffering(const Image& a, const Image& b, const std::string& name, double scale, double tolerance) {
  const int ca = a.ChannelIndex(name), cb = b.ChannelIndex(name);
  EXPECT_GE(ca, 0) << name;
  EXPECT_GE(cb, 0) << name;
  EXPECT_EQ(a.width(), b.width());
  EXPECT_EQ(a.height(), b.height());
  if (ca < 0 || cb < 0 || a.width() != b.width() || a.height() != b.height()) return 1;
  int differing = 0;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      const double va = scale * a.at(x, y, ca), vb = b.at(x, y, cb);
      if (!(std::abs(va - vb) <= tolerance * (1 + std::abs(va)))) ++differing;
    }
  }
  return static_cast<double>(differing) / (a.width() * a.height());
}

constexpr double kScale = 1000;

TEST(LinearFrames, ShadowMapFitIsInvariantToTheValueScale) {
  TempDir dir;
  nlohmann::json summary[2];
  Image maps[2];
  for (int k = 0; k < 2; ++k) {
    const std::string capture = dir / ("capture" + std::to_string(k));
    RunOk("sim shadow-maps " + capture + " --linear-float-frames true --value-scale " + (k ? "1000" : "1") +
        " --camera-width-px 320 --camera-height-px 240 --photons 20000 --frames 1 --dark-frames 0");
    const RunResult info = RunThinslab("info " + capture);
    EXPECT_EQ(info.exit_code, 0) << info.output;
    EXPECT_EQ(info.output.find("warning"), std::string::npos) << info.output;  // Linear: nothing clips.
    RunOk("fit tau " + capture + " --out " + (dir / ("tau" + std::to_string(k))));
    summary[k] = ReadJsonFile(dir / ("tau" + std::to_string(k)) + "/summary.json");
    ASSERT_TRUE(ReadExr(dir / ("tau" + std::to_string(k)) + "/tau.exr", &maps[k]).ok());
  }
  EXPECT_EQ(summary[0]["result"], "success");
  EXPECT_EQ(summary[0]["result"], summary[1]["result"]);
  EXPECT_EQ(summary[0]["noise"]["method"], "single_frame_residual");  // One frame per state.
  ExpectNoiseScales(summary[0], summary[1], kScale);
  EXPECT_EQ(FractionDiffering(maps[0], maps[1], "status", 1, 0), 0);
  EXPECT_EQ(FractionDiffering(maps[0], maps[1], "tau", 1, 1e-4), 0);
  EXPECT_EQ(FractionDiffering(maps[0], maps[1], "sigma_tau", 1, 1e-3), 0);
}

// A single exposure of linear frames is a complete laser-lobe capture; the same single
// exposure of raw integer frames is refused with a message naming the way out.
TEST(LinearFrames, LaserLobeFromOneLinearExposureIsInvariantToTheValueScale) {
  TempDir dir;
  nlohmann::json summary[2], ladder[2];
  for (int k = 0; k < 2; ++k) {
    const std::string capture = dir / ("capture" + std::to_string(k));
    RunOk("sim laser " + capture + " --linear-float-frames true --value-scale " + (k ? "1000" : "1") +
        " --exposures-us 20000 --camera-width-px 480 --camera-height-px 360 --photons 60000");
    const std::string out = dir / ("phase" + std::to_string(k));
    RunOk("fit phase " + capture + " --out " + out);
    summary[k] = ReadJsonFile(out + "/summary.json");
    ladder[k] = ReadJsonFile(out + "/ladder.json");
  }
  ASSERT_EQ(summary[0]["result"], "success");
  EXPECT_EQ(summary[1]["result"], "success");
  ExpectNoiseScales(summary[0], summary[1], kScale);
  // The estimate recovers the simulated sensor: 6 e- read noise, one value per electron.
  EXPECT_NEAR(std::sqrt(summary[0]["noise"]["variance_floor"].get<double>()), 6.0, 0.6);
  EXPECT_NEAR(summary[0]["noise"]["variance_per_value"].get<double>(), 1.0, 0.15);
  EXPECT_NEAR(summary[0]["g"].get<double>(), summary[1]["g"].get<double>(), 1e-5);
  EXPECT_NEAR(summary[0]["sigma_g"].get<double>(), summary[1]["sigma_g"].get<double>(), 1e-5);
  EXPECT_NEAR(summary[0]["chi2_reduced"].get<double>(), summary[1]["chi2_reduced"].get<double>(),
              1e-4 * summary[0]["chi2_reduced"].get<double>());
  EXPECT_EQ(summary[0]["rings"], summary[1]["rings"]);
  EXPECT_EQ(ladder[0]["chosen_rung"], ladder[1]["chosen_rung"]);
  EXPECT_NEAR(summary[0]["g"].get<double>(), 0.8, 0.03);  // The simulated layer's g.

  const std::string raw = dir / "raw";
  RunOk("sim laser " + raw + " --exposures-us 20000 --camera-width-px 240 --camera-height-px 180 --photons 20000");
  const RunResult info = RunThinslab("info " + raw);
  EXPECT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("warning: cam0 'laser': 2 light state(s) have a single exposure and saturated pixels"),
            std::string::npos)
      << info.output;
  const RunResult refused = RunThinslab("fit phase " + raw + " --out " + (dir / "raw_phase"));
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.output.find("single exposure_time_us"), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find("frame_values \"linear\""), std::string::npos) << refused.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "raw_phase/summary.json"));
}

// The manifest's declaration wins over any estimate: gain and read noise written by hand into
// a linear capture's session.json, as a lab's own capture script would.
TEST(LinearFrames, DeclaredNoiseIsUsedAndRecorded) {
  TempDir dir;
  const std::string capture = dir / "capture";
  RunOk("sim laser " + capture +
      " --linear-float-frames true --value-scale 1000 --exposures-us 20000 --camera-width-px 240 "
      "--camera-height-px 180 --photons 20000");
  nlohmann::json manifest = ReadJsonFile(capture + "/session.json");
  nlohmann::json& camera = manifest["rig"]["cameras"][0];
  EXPECT_EQ(camera["frame_values"], "linear");
  EXPECT_FALSE(camera.contains("saturation_dn"));  // Nothing saturates in linear frames.
  camera["gain_e_per_dn"] = 1.0 / kScale;
  camera["read_noise_dn"] = 6.0 * kScale;
  ASSERT_TRUE(WriteFileAtomically(capture + "/session.json", manifest.dump(2)).ok());
  const RunResult info = RunThinslab("info " + capture);
  ASSERT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("read noise 6000"), std::string::npos) << info.output;
  RunOk("fit phase " + capture + " --out " + (dir / "phase"));
  const nlohmann::json summary = ReadJsonFile(dir / "phase/summary.json");
  EXPECT_EQ(summary["noise"]["method"], "declared");
  EXPECT_NEAR(summary["noise"]["variance_floor"].get<double>(), 36e6, 1);
  EXPECT_NEAR(summary["noise"]["variance_per_value"].get<double>(), kScale, 1e-9);
}

// The dot-scan chain (HDR of one exposure, Eq. 12 slices, the dual-microfacet fit and the
// held-out ladder) on a 20 x 20 grid: every point's status and rung and every map agree.
TEST(LinearFramesDotScan, DmfFitAndLadderAreInvariantToTheValueScale) {
  TempDir dir;
  nlohmann::json summary[2];
  Image maps[2], rungs[2];
  for (int k = 0; k < 2; ++k) {
    const std::string capture = dir / ("capture" + std::to_string(k));
    RunOk("sim dot-scan " + capture + " --grid-nx 20 --grid-ny 20 --linear-float-frames true --value-scale " +
        (k ? "1000" : "1") + " --exposures-us 2000000");
    const std::string out = dir / ("dmf" + std::to_string(k));
    RunOk("fit dmf " + capture + " --out " + out +
        " --pitch-mm 4 --hold-out true --cluster-fraction 0 --ladder true --ladder-tile 2");
    summary[k] = ReadJsonFile(out + "/summary.json");
    ASSERT_TRUE(ReadExr(out + "/maps.exr", &maps[k]).ok());
    ASSERT_TRUE(ReadExr(out + "/ladder.exr", &rungs[k]).ok());
  }
  ExpectNoiseScales(summary[0], summary[1], kScale);
  EXPECT_NEAR(std::sqrt(summary[0]["noise"]["variance_floor"].get<double>()), 6.0, 0.6);
  // The sharp dot images behind the smooth regions are structure at the scale of a pixel, which
  // the single-frame estimate leaves out by its weak-texture selection (measured 1.01 for the true
  // 1; 1.43 when every sample counted, before 2026-12-06).
  EXPECT_NEAR(summary[0]["noise"]["variance_per_value"].get<double>(), 1.0, 0.1);
  EXPECT_EQ(summary[0]["status_counts"], summary[1]["status_counts"]);
  // The fitted family's tail beyond the measured cells (the default) on most direct fits, and on
  // the same ones at either scale.
  EXPECT_EQ(summary[0]["ndf_tail"]["mode"], "family");
  EXPECT_GT(summary[0]["ndf_tail"]["direct_fits_with_family_tail"].get<int>(),
            summary[0]["ndf_tail"]["direct_fits_with_ndf"].get<int>() / 2)
      << summary[0]["ndf_tail"].dump();
  EXPECT_EQ(summary[0]["ndf_tail"], summary[1]["ndf_tail"]);
  EXPECT_EQ(summary[0]["ladder"]["rung_counts"], summary[1]["ladder"]["rung_counts"]);
  // Measured: rungs 0 (36), 3 (180), 4 (128), 5 (56): the ladder uses more than one rung.
  EXPECT_GE(summary[0]["ladder"]["rung_counts"].size(), 3u) << summary[0]["ladder"].dump();
  EXPECT_EQ(FractionDiffering(rungs[0], rungs[1], "rung", 1, 0), 0);
  EXPECT_EQ(FractionDiffering(maps[0], maps[1], "status", 1, 0), 0);
  // Roughness and the interface weight are scale-free; k_s and rho_d are ratios of radiances.
  for (const char* channel : {"top_face_weight", "smith_alpha", "k_s", "rho_d"}) {
    EXPECT_LE(FractionDiffering(maps[0], maps[1], channel, 1, 1e-3), 0.01) << channel;
  }
}

}  // namespace
}  // namespace thinslab
