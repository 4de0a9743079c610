// SPDX-License-Identifier: Apache-2.0
// Issue #23 section 4 through the binary: validation frames (frames[k].validation, format 1.4)
// of dots between the grid's. They are never fitted (the fit is the same, bit for bit, with them
// removed from the manifest), `info` counts them, and `fit dmf` reports how well its maps
// predict them per region with the noise level beside it; the figure can fail: validation dots
// recorded at the wrong monitor position read several times worse.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "core/exr_io.h"
#include "core/file.h"
#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

// The manifest with its validation frames transformed by `edit` (return false to drop one).
template <typename Edit>
void EditValidationFrames(const std::string& capture, const Edit& edit) {
  const std::string manifest = capture + "/session.json";
  nlohmann::json session = ReadJsonFile(manifest);
  nlohmann::json frames = nlohmann::json::array();
  for (nlohmann::json& f : session["frames"]) {
    if (f.value("validation", false) && !edit(&f)) continue;
    frames.push_back(f);
  }
  session["frames"] = frames;
  ASSERT_TRUE(WriteFileAtomically(manifest, session.dump(2)).ok());
}

TEST(CliValidationDots, ReportedPerRegionNeverFittedAndAbleToFail) {
  TempDir dir;
  const std::string capture = dir / "capture";
  RunThinslabOk("sim dot-scan " + capture + " --grid-nx 20 --grid-ny 20 --validation-dots 40 --photons-k 100 --table-bins 48");
  const RunResult info = RunThinslabOk("info " + capture);
  EXPECT_NE(info.output.find("validation frames (not fitted): 80"), std::string::npos) << info.output;  // 2 exposures.

  const std::string fit = " --pitch-mm 4 --out ";
  RunThinslabOk("fit dmf " + capture + fit + (dir / "with"));
  const nlohmann::json summary = ReadJsonFile(dir / "with/summary.json");
  const nlohmann::json& validation = summary["validation"];
  ASSERT_EQ(validation["dots"], 40) << validation.dump();
  ASSERT_GE(validation["regions"].size(), 8u) << validation.dump();  // "all" and the rough regions.
  const nlohmann::json& all = validation["regions"][0];
  EXPECT_EQ(all["region"], "all");
  const double error = all["relative_rms"].get<double>(), noise = all["noise_relative_rms"].get<double>();
  std::printf("validation dots: in-lobe relative RMS %.3f (noise alone %.3f) over %d points\n", error, noise,
              all["points"].get<int>());
  EXPECT_GT(all["points"].get<int>(), 200);
  EXPECT_GT(error, noise);   // The model's own error is part of it.
  EXPECT_LT(error, 0.25);    // Held-out grid dots read 0.04-0.12 per region (docs/models/dual_microfacet_fit.md).
  EXPECT_GT(noise, 0);

  // Never fitted: without them, the same maps.
  const std::string without = dir / "without";
  ASSERT_EQ(std::system(("cp -r " + capture + " " + without).c_str()), 0);
  std::filesystem::remove_all(without + "/fit");
  EditValidationFrames(without, [](nlohmann::json*) { return false; });
  RunThinslabOk("fit dmf " + without + fit + (dir / "fit_without"));
  Image a, b;
  ASSERT_TRUE(ReadExr(dir / "with/maps.exr", &a).ok());
  ASSERT_TRUE(ReadExr(dir / "fit_without/maps.exr", &b).ok());
  EXPECT_EQ(a.data(), b.data());
  EXPECT_EQ(ReadJsonFile(dir / "fit_without/summary.json")["validation"]["dots"], 0);

  // Able to fail: validation dots recorded half a grid step (10 monitor px, 2.5 mm) off where they
  // were shown, as a lab script with the wrong grid origin would.
  EditValidationFrames(capture, [](nlohmann::json* f) {
    (*f)["light"]["dot_px"][0] = (*f)["light"]["dot_px"][0].get<double>() + 10;
    return true;
  });
  RunThinslabOk("fit dmf " + capture + fit + (dir / "shifted"));
  const double shifted = ReadJsonFile(dir / "shifted/summary.json")["validation"]["regions"][0]["relative_rms"];
  std::printf("validation dots recorded 2.5 mm off: %.3f\n", shifted);
  EXPECT_GT(shifted, 2 * error);
}

}  // namespace
}  // namespace thinslab
