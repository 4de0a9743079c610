// SPDX-License-Identifier: Apache-2.0
// Display gamma measured, not assumed (issue #7, part 2), through the real binary:
// `acquire gamma --camera sim` + `calib gamma` recover the simulated display's emission curve
// (power 2.2 of an 8-bit drive, with light at drive 0; the frames come from the sim camera's
// sensor model with shot/read noise and 12-bit quantisation, and the fit knows nothing of the
// curve), and the table given back to the display through --gamma-table makes a requested level
// of 0.25 emit a quarter of full light, where without it the display emits ~0.25^2.2. Bad input:
// missing or invalid tables, and sessions `calib gamma` cannot fit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/calib/response_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/drivers/display_gamma.h"
#include "thinslab/sim/sensor_model.h"
#include "thinslab/sim/sim_display_transfer.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCamera = " --quiet --camera-width-px 80 --camera-height-px 60 ";

// Per pixel: mean of the frames of `kind` minus the mean of the "dark" frames (DN, black level
// removed), all frames of the session having one exposure.
std::vector<double> DarkSubtractedMean(const std::string& dir, const std::string& kind) {
  Session s;
  EXPECT_TRUE(ReadSession(dir, &s).ok()) << dir;
  std::vector<double> lit, dark;
  auto accumulate = [&](const std::string& k, std::vector<double>* sum) {
    const auto frames = s.UsableFrames(k);
    EXPECT_FALSE(frames.empty()) << dir << " has no " << k << " frame";
    for (const FrameRecord* f : frames) {
      Image image;
      EXPECT_TRUE(LoadFrame(dir, s, *f, &image).ok()) << f->file;
      sum->resize(image.num_pixels(), 0.0);
      for (size_t i = 0; i < image.num_pixels(); ++i) (*sum)[i] += image.data()[i] / frames.size();
    }
  };
  accumulate(kind, &lit);
  accumulate("dark", &dark);
  for (size_t i = 0; i < lit.size(); ++i) lit[i] -= dark[i];
  return lit;
}

double RegionMean(const std::vector<double>& image, const std::vector<size_t>& region) {
  double sum = 0;
  for (size_t i : region) sum += image[i];
  return sum / region.size();
}

class CliGammaTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    gamma_session_ = *dir_ / "gamma";
    acquire_ = RunThinslab("acquire gamma" + std::string(kCamera) + "--seed 3 " + gamma_session_);
    calib_ = RunThinslab("calib gamma " + gamma_session_);
  }
  static void TearDownTestSuite() { delete dir_; }

  static std::string Table() { return gamma_session_ + "/calib/display_gamma.txt"; }

  // A one-exposure bracket session of `pattern` (flat:1 fills ~31 % of full well).
  static std::string Bracket(const std::string& name, const std::string& pattern, const std::string& extra) {
    const std::string out = *dir_ / name;
    const RunResult r = RunThinslab("acquire bracket" + std::string(kCamera) +
                                    "--exposures-us 94118 --frames-per-exposure 2 --seed 4 --pattern " + pattern + " " +
                                    extra + " " + out);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return out;
  }

  static TempDir* dir_;
  static std::string gamma_session_;
  static RunResult acquire_, calib_;
};

TempDir* CliGammaTest::dir_ = nullptr;
std::string CliGammaTest::gamma_session_;
RunResult CliGammaTest::acquire_, CliGammaTest::calib_;

TEST_F(CliGammaTest, CalibGammaRecoversTheSimulatedDisplayCurve) {
  ASSERT_EQ(acquire_.exit_code, 0) << acquire_.output;
  ASSERT_EQ(calib_.exit_code, 0) << calib_.output;
  Session s;
  ASSERT_TRUE(ReadSession(gamma_session_, &s).ok());
  EXPECT_EQ(s.kind, "display_gamma");
  EXPECT_EQ(s.acquisition.state, "complete");
  GammaTable table;
  ASSERT_TRUE(ReadGammaTable(Table(), &table).ok());
  ASSERT_EQ(table.drive_to_light.size(), 17u);
  EXPECT_TRUE(fs::exists(gamma_session_ + "/calib/display_gamma_summary.json"));
  // The sim's own curve (app/acquire_commands.cc default), as emitted light above black.
  SimDisplayTransfer truth;
  ASSERT_TRUE(ParseSimDisplayTransfer("power:2.2/8bit", "t", &truth).ok());
  double worst = 0;
  for (const auto& [drive, light] : table.drive_to_light) {
    const double expected = truth.LightForLevel(drive, IdentityGammaTable());
    worst = std::max(worst, std::abs(light - expected));
    // Measured worst 0.0002 (seeds 3 and 9: 0.00021, 0.00028).
    EXPECT_NEAR(light, expected, /*max_light_abs_error=*/0.002) << "drive " << drive;
  }
  std::printf("worst |fitted - true| light over the 17 levels: %.5f of full light\n", worst);
}

// Worst |table light - true emitted light| over the table's levels.
double WorstTableError(const std::string& table_path) {
  GammaTable table;
  EXPECT_TRUE(ReadGammaTable(table_path, &table).ok()) << table_path;
  SimDisplayTransfer truth;
  EXPECT_TRUE(ParseSimDisplayTransfer("power:2.2/8bit", "t", &truth).ok());
  double worst = 0;
  for (const auto& [drive, light] : table.drive_to_light) {
    worst = std::max(worst, std::abs(light - truth.LightForLevel(drive, IdentityGammaTable())));
  }
  return worst;
}

// Through a camera with a tone curve (the sim sensor's "gamma" response), `calib gamma
// --response` linearises the frames before the merge: with the camera's true inverse response
// the display curve is recovered; without it, it is not.
TEST_F(CliGammaTest, CalibGammaLinearisesThroughTheCameraResponse) {
  const std::string session = *dir_ / "tone_curve";
  RunResult r = RunThinslab("acquire gamma" + std::string(kCamera) + "--seed 3 --sensor-response gamma " + session);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  Session s;
  ASSERT_TRUE(ReadSession(session, &s).ok());
  const CameraInfo& cam = s.rig.cameras[0];
  // The sim's inverse response in the response.json form (L itself, as Robertson's method
  // stores it): L(z) = range f^-1(z / range), range = saturation - black.
  SimSensorOptions sensor;
  sensor.response = SimResponseCurve::kGamma;
  const double range = cam.saturation_dn - cam.black_level_dn;
  CameraResponse response;
  response.method = "robertson";
  response.camera_id = cam.id;
  response.bit_depth = cam.bit_depth;
  response.black_level_dn = cam.black_level_dn;
  response.saturation_dn = cam.saturation_dn;
  for (double z = 0; z <= range; z += 1) {
    response.knots_dn.push_back(z);
    response.linear_dn.push_back(range * sensor.InverseResponseCurve(z / range));
  }
  response.reference_dn = range;
  ASSERT_TRUE(WriteResponse(*dir_ / "true_response.json", response).ok());
  r = RunThinslab("calib gamma " + session + " --response " + *dir_ / "true_response.json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const double with_response = WorstTableError(session + "/calib/display_gamma.txt");
  r = RunThinslab("calib gamma " + session + " --response linear -o " + *dir_ / "tone_curve_linear.txt");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const double without = WorstTableError(*dir_ / "tone_curve_linear.txt");
  std::printf("worst |fitted - true| light through a gamma camera: %.5f with its response, %.5f without\n",
              with_response, without);
  EXPECT_LT(with_response, /*max_light_abs_error=*/0.002);
  EXPECT_GT(without, 0.1);
}

TEST_F(CliGammaTest, GammaTableLinearisesTheDisplayAndWithoutItTheDisplayIsFarFromLinear) {
  ASSERT_EQ(calib_.exit_code, 0) << calib_.output;
  const std::vector<double> full = DarkSubtractedMean(Bracket("full", "flat:1", ""), "bracket");
  const std::vector<double> corrected =
      DarkSubtractedMean(Bracket("quarter_table", "flat:0.25", "--gamma-table " + Table()), "bracket");
  const std::vector<double> raw = DarkSubtractedMean(Bracket("quarter_raw", "flat:0.25", ""), "bracket");
  // The lit region: above half the 99th percentile of the full-level signal.
  std::vector<double> sorted = full;
  std::sort(sorted.begin(), sorted.end());
  const double threshold = 0.5 * sorted[static_cast<size_t>(0.99 * (sorted.size() - 1))];
  std::vector<size_t> region;
  for (size_t i = 0; i < full.size(); ++i) {
    if (full[i] > threshold) region.push_back(i);
  }
  ASSERT_GT(region.size(), 100u);
  const double with_table = RegionMean(corrected, region) / RegionMean(full, region);
  const double without = RegionMean(raw, region) / RegionMean(full, region);
  std::printf("light at level 0.25 / level 1: %.4f with the table, %.4f without (0.25^2.2 = %.4f)\n", with_table,
              without, std::pow(0.25, 2.2));
  // What the method leaves at 0.25: the table's chord between its nodes 0.5 and 0.5625 (up to
  // -0.0011 of light on a 2.2 curve) and the 8-bit drive rounding (+-0.0022); measured 0.2507.
  EXPECT_NEAR(with_table, 0.25, /*max_ratio_abs_error=*/0.006);
  EXPECT_NEAR(without, std::pow(0.25, 2.2), 0.006);
  // The plan records the table that drove the display.
  Session s;
  ASSERT_TRUE(ReadSession(*dir_ / "quarter_table", &s).ok());
  EXPECT_NE(s.acquisition.plan.find("gamma-table = " + Table()), std::string::npos) << s.acquisition.plan;
  EXPECT_NE(s.acquisition.plan.find("gamma-table-entries = 0:0,0.0625:"), std::string::npos) << s.acquisition.plan;
}

TEST_F(CliGammaTest, MissingOrInvalidTableIsNamedAndLeavesNoSession) {
  RunResult r = RunThinslab("acquire bracket" + std::string(kCamera) + "--gamma-table " + *dir_ / "nope.txt" + " " +
                            *dir_ / "no1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("nope.txt"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(*dir_ / "no1"));
  ASSERT_TRUE(WriteFileAtomically(*dir_ / "bad.txt", "# drive light\n0 0\n0.5 0.6\n0.7 0.5\n1 1\n").ok());
  r = RunThinslab("acquire dot-scan" + std::string(kCamera) + "--gamma-table " + *dir_ / "bad.txt" + " " + *dir_ / "no2");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("bad.txt:4"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(*dir_ / "no2"));
  // The measurement itself drives the display through the identity table.
  r = RunThinslab("acquire gamma" + std::string(kCamera) + "--gamma-table " + Table() + " " + *dir_ / "no3");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--gamma-table"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(*dir_ / "no3"));
}

// Copies the gamma session with its manifest edited by `edit`.
std::string EditedCopy(const std::string& from, const std::string& to, void (*edit)(Session*)) {
  fs::copy(from, to, fs::copy_options::recursive);
  fs::remove(fs::path(to) / "journal.log");  // The edited manifest is the record.
  fs::remove_all(fs::path(to) / "calib");     // The original's fitted table.
  Session s;
  EXPECT_TRUE(ReadSession(from, &s).ok());
  edit(&s);
  for (size_t i = 0; i < s.frames.size(); ++i) s.frames[i].index = static_cast<int>(i);
  EXPECT_TRUE(WriteSession(to, s).ok());
  return to;
}

TEST_F(CliGammaTest, CalibGammaRefusesSessionsItCannotFit) {
  ASSERT_EQ(acquire_.exit_code, 0) << acquire_.output;
  // No level-1 frame.
  const std::string no_full = EditedCopy(gamma_session_, *dir_ / "no_full", [](Session* s) {
    s->frames.erase(std::remove_if(s->frames.begin(), s->frames.end(),
                                   [](const FrameRecord& f) { return f.light.projector_pattern == "flat:1"; }),
                    s->frames.end());
  });
  RunResult r = RunThinslab("calib gamma " + no_full);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("flat:1"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(no_full + "/calib/display_gamma.txt"));
  // Two levels only.
  const std::string two = EditedCopy(gamma_session_, *dir_ / "two_levels", [](Session* s) {
    s->frames.erase(std::remove_if(s->frames.begin(), s->frames.end(),
                                   [](const FrameRecord& f) {
                                     return f.kind == "level" && f.light.projector_pattern != "flat:1" &&
                                            f.light.projector_pattern != "flat:0";
                                   }),
                    s->frames.end());
  });
  r = RunThinslab("calib gamma " + two);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("at least 3"), std::string::npos) << r.output;
  // A display that never lit: the level-1 frames are the dark frames of their exposure.
  const std::string dark = EditedCopy(gamma_session_, *dir_ / "never_lit", [](Session* s) {
    for (FrameRecord& f : s->frames) {
      if (f.light.projector_pattern != "flat:1") continue;
      for (const FrameRecord& d : s->frames) {
        if (d.kind == "dark" && d.exposure_time_us == f.exposure_time_us) f.file = d.file;
      }
    }
  });
  r = RunThinslab("calib gamma " + dark);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("never lit"), std::string::npos) << r.output;
  // Every exposure saturates the lit display (170 refresh periods).
  const std::string saturated = *dir_ / "saturated";
  r = RunThinslab("acquire gamma" + std::string(kCamera) + "--steps 2 --repeats 1 --dark-frames 1 --exposures-us 2000000 " +
                  saturated);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunThinslab("calib gamma " + saturated);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("saturated"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("frames/"), std::string::npos) << "the message names the frame: " << r.output;
  // Not a gamma session: no frame of kind "level".
  const std::string other = EditedCopy(gamma_session_, *dir_ / "other_kind", [](Session* s) {
    for (FrameRecord& f : s->frames) {
      if (f.kind == "level") f.kind = "bracket";
    }
  });
  r = RunThinslab("calib gamma " + other);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("'level'"), std::string::npos) << r.output;
}

// The lab chain on the simulated rig: `acquire gamma` + `calib gamma` (the suite's table), then
// `acquire dot-scan --sim-sample` (the region sample of `sim dot-scan` in the light path, Monte
// Carlo through both faces, with ground truth) on the gamma 2.2 display driven through that
// table, and `fit dmf`: it fits as the same scan on an ideal linear display does (mean held-out
// error over the regions within 20 %, at least 80 % of its ok interior points). Measured: 10 vs 8
// ok interior points, mean held-out 0.266 vs 0.287 over 8 regions. Both displays have black 0;
// with the sim's default 0.2 % black level the whole screen's glow, seen through the sample,
// takes 44 % of the range at the 9.4 s exposure (lobes saturate, their tails drown in its shot
// noise), and `fit dmf` says so.
struct AcquiredFit {
  nlohmann::json comparison, summary;
  std::string fit_output;
};
AcquiredFit FitAcquiredDotScan(const std::string& out, const std::string& display) {
  const RunResult scan = RunThinslab("acquire dot-scan --quiet --sim-sample true --sim-photons-k 100"
                                     " --camera-width-px 240 --camera-height-px 180 --grid-nx 10 --grid-ny 10"
                                     " --exposures-us 11765,9411765 " + display + " " + out);
  EXPECT_EQ(scan.exit_code, 0) << scan.output;
  EXPECT_TRUE(fs::exists(out + "/ground_truth/truth.json"));
  AcquiredFit result;
  const RunResult fit = RunThinslab("fit dmf " + out + " --pitch-mm 8 --hold-out true");
  EXPECT_EQ(fit.exit_code, 0) << fit.output;
  result.fit_output = fit.output;
  std::string text;
  EXPECT_TRUE(ReadFileToString(out + "/fit/dmf/comparison.json", &text).ok());
  result.comparison = nlohmann::json::parse(text, nullptr, false);
  EXPECT_TRUE(ReadFileToString(out + "/fit/dmf/summary.json", &text).ok());
  result.summary = nlohmann::json::parse(text, nullptr, false);
  return result;
}

TEST_F(CliGammaTest, AcquiredDotScanThroughTheTableFitsAsOnALinearDisplay) {
  ASSERT_EQ(calib_.exit_code, 0) << calib_.output;
  const AcquiredFit linear_fit =
      FitAcquiredDotScan(*dir_ / "scan_linear", "--sim-display-transfer linear --sim-display-black 0");
  const AcquiredFit tabled_fit = FitAcquiredDotScan(*dir_ / "scan_table", "--sim-display-black 0 --gamma-table " + Table());
  const nlohmann::json& linear = linear_fit.comparison;
  const nlohmann::json& tabled = tabled_fit.comparison;
  ASSERT_TRUE(linear.is_object() && tabled.is_object());
  for (const AcquiredFit* f : {&linear_fit, &tabled_fit}) {
    EXPECT_LT(f->summary["dark_frame"]["median_fraction_of_range_at_sample_points"].get<double>(), 0.01);
    EXPECT_EQ(f->fit_output.find("warning: "), std::string::npos) << f->fit_output;
  }
  int ok_linear = 0, ok_tabled = 0, both = 0;
  double held_linear = 0, held_tabled = 0;
  for (size_t k = 0; k < linear["regions"].size(); ++k) {
    const nlohmann::json& a = linear["regions"][k];
    const nlohmann::json& b = tabled["regions"][k];
    ASSERT_EQ(a["name"], b["name"]);
    ok_linear += a["ok"].get<int>();
    ok_tabled += b["ok"].get<int>();
    const double ha = a["median_held_out_relative_rms"], hb = b["median_held_out_relative_rms"];
    if (ha < 0 || hb < 0) continue;
    held_linear += ha;
    held_tabled += hb;
    ++both;
  }
  ASSERT_GE(both, 5);
  std::printf("acquired dot scan: ok points %d (linear display) vs %d (gamma 2.2 display + table); mean held-out "
              "%.3f vs %.3f over %d regions\n",
              ok_linear, ok_tabled, held_linear / both, held_tabled / both, both);
  EXPECT_GE(ok_tabled, 0.8 * ok_linear);
  EXPECT_LE(held_tabled, 1.2 * held_linear);

  // The default 0.2 % black level: warned.
  const AcquiredFit glowing = FitAcquiredDotScan(*dir_ / "scan_glow", "--gamma-table " + Table());
  const double glow = glowing.summary["dark_frame"]["median_fraction_of_range_at_sample_points"];
  std::printf("0.2 %% display black: dark frame at the sample points %.3f of the range\n", glow);
  EXPECT_GT(glow, 0.2);
  EXPECT_NE(glowing.fit_output.find("display's black level"), std::string::npos) << glowing.fit_output;
  EXPECT_NE(glowing.summary["dark_frame"]["warning"].get<std::string>(), "");
}

// `acquire gamma --exposures-us auto` (issue #28, item 2): on a display 100x dimmer than the
// fixed bracket was made for, the probe puts level 1 near half the range in the shortest exposure
// and lengthens the longest for the first level above black (up to the 10 s cap), the session
// check finds nothing to re-take and the table holds; a display so bright that level 1 saturates
// in one refresh period is refused before the session, with nothing written.
TEST_F(CliGammaTest, ThePlannedBracketFollowsTheDisplaysBrightness) {
  const std::string dim = *dir_ / "dim_planned";
  RunResult r =
      RunThinslab("acquire gamma" + std::string(kCamera) + "--seed 3 --dot-radiance 0.0005 --exposures-us auto " + dim);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("verdict: good"), std::string::npos) << r.output;
  Session s;
  ASSERT_TRUE(ReadSession(dim, &s).ok());
  EXPECT_NE(s.acquisition.plan.find("level 1/16 above black"), std::string::npos) << s.acquisition.plan;
  std::set<double> exposures;
  for (const FrameRecord& f : s.frames) exposures.insert(f.exposure_time_us);
  ASSERT_GE(exposures.size(), 2u);
  // The fixed bracket ends at 16 refresh periods (188 ms), where level 1 fills ~6 % of the range.
  EXPECT_GT(*exposures.begin(), 0.5e6);
  EXPECT_GT(*exposures.rbegin(), 5e6);
  r = RunThinslab("calib gamma " + dim);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Measured 0.0003 (the fixed bracket: 0.0005, and the check calls its noisy frames flicker).
  EXPECT_LT(WorstTableError(dim + "/calib/display_gamma.txt"), 0.002);

  const std::string bright = *dir_ / "bright_planned";
  r = RunThinslab("acquire gamma" + std::string(kCamera) + "--seed 3 --dot-radiance 0.5 --exposures-us auto " + bright);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("level 1 saturates even at 11.7"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("one refresh period of the display"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(bright)) << r.output;
}

}  // namespace
}  // namespace thinslab
