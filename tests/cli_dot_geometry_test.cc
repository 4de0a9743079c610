// SPDX-License-Identifier: Apache-2.0
// Issue #23 section 3 through the binary: dot scans whose all-dots frame defeated the old
// detector run through `calib dots` and `fit dmf` with only the manifest's documented fields and
// no hand-made calib/rig.json:
//  - a dense grid, dots 1.3 diameters apart that touch in the image and light most of the frame;
//  - a grid that extends beyond the camera's view (dots it cannot see, dots the border cuts);
//  - the dot radius taken from rig.monitor.dot_radius_px (format 1.4), assumed with a warning
//    when the manifest lacks it, and --dot-radius-px over both.
// The captures come from the simulated rig (Monte Carlo BTDF tables, perspective camera with lens
// distortion and blur, shot and read noise, 12-bit quantisation).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

constexpr char kSmallTables[] = " --photons-k 20 --table-bins 32";

// Share of the shortest all-dots frame's pixels above 5 % of its brightest (black removed).
double LitFraction(const std::string& capture) {
  Session session;
  EXPECT_TRUE(ReadSession(capture, &session).ok());
  const FrameRecord* shortest = nullptr;
  for (const FrameRecord& f : session.frames) {
    if (f.kind == "all_dots" && (shortest == nullptr || f.exposure_time_us < shortest->exposure_time_us)) shortest = &f;
  }
  EXPECT_NE(shortest, nullptr);
  if (shortest == nullptr) return 0;
  Image frame;
  EXPECT_TRUE(LoadFrame(capture, session, *shortest, &frame).ok());
  const float brightest = *std::max_element(frame.data().begin(), frame.data().end());
  const auto lit = std::count_if(frame.data().begin(), frame.data().end(), [&](float v) { return v > 0.05f * brightest; });
  return static_cast<double>(lit) / frame.data().size();
}

// 20 x 20 dots about 20 monitor px apart, radius 7.7 px: 1.3 diameters apart, filling the view.
TEST(CliDotGeometry, DenseGridWhoseDotsTouchFitsWithoutHandMadeCalibration) {
  TempDir dir;
  const std::string capture = dir / "dense";
  RunThinslabOk("sim dot-scan " + capture + " --grid-nx 20 --grid-ny 20 --dot-radius-px 7.7 --camera-view-width-m 0.1" +
        kSmallTables);
  const double lit = LitFraction(capture);
  std::printf("dense grid: %.0f %% of the all-dots frame lit\n", 100 * lit);
  EXPECT_GT(lit, 0.5);

  const RunResult calib = RunThinslabOk("calib dots " + capture);
  EXPECT_NE(calib.output.find("displayed dots 400, blobs 400, matched 400"), std::string::npos) << calib.output;
  EXPECT_NE(calib.output.find("dot radius 7.7 monitor px (manifest)"), std::string::npos) << calib.output;
  EXPECT_EQ(calib.output.find("warning"), std::string::npos) << calib.output;

  const std::string out = dir / "dmf";
  const RunResult fit = RunThinslabOk("fit dmf " + capture + " --calibration none --pitch-mm 4 --out " + out);
  EXPECT_EQ(fit.output.find("warning"), std::string::npos) << fit.output;
  const nlohmann::json summary = ReadJsonFile(out + "/summary.json");
  EXPECT_EQ(summary["dot_positions"]["measured"], 400) << summary["dot_positions"].dump();
  EXPECT_EQ(summary["dot_positions"]["placed_from_geometry"], 0);
  EXPECT_EQ(summary["monitor_distance"]["warning"], "");
  EXPECT_LT(std::abs(summary["monitor_distance"]["error_m"].get<double>()), 0.25e-3);
  EXPECT_EQ(summary["dot_radius"]["source"], "manifest");
  EXPECT_DOUBLE_EQ(summary["dot_radius"]["monitor_px"].get<double>(), 7.7);
}

// A 60 mm view of a 96 mm grid: 244 of 400 dots outside it or cut by its border light the
// sample all the same and are placed from the fitted monitor geometry.
TEST(CliDotGeometry, GridBeyondTheViewFitsWithDotsPlacedFromTheGeometry) {
  TempDir dir;
  const std::string capture = dir / "wide";
  RunThinslabOk("sim dot-scan " + capture + " --grid-nx 20 --grid-ny 20 --camera-view-width-m 0.06" + kSmallTables);
  const std::string out = dir / "dmf";
  const RunResult fit = RunThinslabOk("fit dmf " + capture + " --pitch-mm 4 --out " + out);
  EXPECT_EQ(fit.output.find("was not found"), std::string::npos) << fit.output;
  EXPECT_EQ(fit.output.find("warning"), std::string::npos) << fit.output;
  const nlohmann::json summary = ReadJsonFile(out + "/summary.json");
  const nlohmann::json& dots = summary["dot_positions"];
  std::printf("grid beyond the view: %s\n", dots.dump().c_str());
  EXPECT_GT(dots["placed_from_geometry"].get<int>(), 100) << dots.dump();
  EXPECT_GT(dots["measured"].get<int>(), 100) << dots.dump();
  EXPECT_GT(dots["clipped_at_border"].get<int>(), 0) << dots.dump();
  EXPECT_EQ(summary["monitor_distance"]["warning"], "");
  EXPECT_GT(summary["status_counts"]["ok"].get<int>(), 0) << summary["status_counts"].dump();

  // The dot radius: assumed with a warning when the manifest lacks it, the option over both.
  const std::string manifest = capture + "/session.json";
  nlohmann::json session = ReadJsonFile(manifest);
  session["rig"]["monitor"].erase("dot_radius_px");
  ASSERT_TRUE(WriteFileAtomically(manifest, session.dump(2)).ok());
  const RunResult assumed = RunThinslabOk("fit dmf " + capture + " --pitch-mm 4 --out " + out);
  EXPECT_NE(assumed.output.find("warning: " + manifest + ": rig.monitor.dot_radius_px is not given; assuming 2"),
            std::string::npos)
      << assumed.output;
  EXPECT_EQ(ReadJsonFile(out + "/summary.json")["dot_radius"]["source"], "default");
  RunThinslabOk("fit dmf " + capture + " --pitch-mm 4 --dot-radius-px 2.5 --out " + out);
  const nlohmann::json given = ReadJsonFile(out + "/summary.json")["dot_radius"];
  EXPECT_EQ(given["source"], "option");
  EXPECT_DOUBLE_EQ(given["monitor_px"].get<double>(), 2.5);
}

}  // namespace
}  // namespace thinslab
