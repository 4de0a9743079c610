// SPDX-License-Identifier: Apache-2.0
// Bad input through the real `thinslab` binary: each case must exit non-zero with one line
// naming the file and field, and must leave no output (complete or partial) behind.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session_io.h"
#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

int CountLines(const std::string& text) {
  int lines = 0;
  for (char c : text) lines += c == '\n';
  return lines;
}

class CliBadInputTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    // A small valid capture: 40x40 layer, 320x240 camera, 2 frames per state.
    ASSERT_EQ(RunThinslab("sim pattern " + *dir_ / "small.exr" + " --width-px 40 --height-px 40").exit_code, 0);
    const RunResult sim = RunThinslab("sim shadow-maps " + *dir_ / "base" + " --tau " + *dir_ / "small.exr" +
                                      " --camera-width-px 320 --camera-height-px 240 --photons 20000 --frames 2"
                                      " --dark-frames 1");
    ASSERT_EQ(sim.exit_code, 0) << sim.output;
  }
  static void TearDownTestSuite() { delete dir_; }

  // A fresh copy of the valid capture.
  std::string CopyBase(const std::string& name) {
    const std::string target = *dir_ / name;
    fs::copy(*dir_ / "base", target, fs::copy_options::recursive);
    return target;
  }

  static nlohmann::json ReadManifest(const std::string& session) {
    std::ifstream in(session + "/session.json");
    return nlohmann::json::parse(in);
  }
  static void WriteManifest(const std::string& session, const nlohmann::json& j) {
    std::ofstream(session + "/session.json") << j.dump(2);
  }
  static std::string FirstFrameOfKind(const nlohmann::json& manifest, const std::string& kind) {
    for (const auto& f : manifest["frames"]) {
      if (f["kind"] == kind) return f["file"].get<std::string>();
    }
    return "";
  }

  // Runs `fit tau` and checks: non-zero exit, one line, naming every expected piece, no output.
  void ExpectFitFails(const std::string& session, const std::vector<std::string>& expected_in_message) {
    const RunResult result = RunThinslab("fit tau " + session);
    EXPECT_NE(result.exit_code, 0) << result.output;
    EXPECT_EQ(CountLines(result.output), 1) << result.output;
    EXPECT_EQ(result.output.rfind("error: ", 0), 0u) << result.output;
    for (const auto& piece : expected_in_message) {
      EXPECT_NE(result.output.find(piece), std::string::npos) << "'" << piece << "' not in: " << result.output;
    }
    EXPECT_FALSE(fs::exists(session + "/fit/tau")) << "output left behind";
    if (fs::exists(session + "/fit")) {
      for (const auto& entry : fs::directory_iterator(session + "/fit")) {
        ADD_FAILURE() << "partial output left behind: " << entry.path();
      }
    }
  }

  static TempDir* dir_;
};

TempDir* CliBadInputTest::dir_ = nullptr;

TEST_F(CliBadInputTest, ValidCaptureFitsAndInfoValidates) {
  const std::string session = CopyBase("valid");
  const RunResult info = RunThinslab("info " + session);
  EXPECT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("valid: yes"), std::string::npos);
  const RunResult fit = RunThinslab("fit tau " + session);
  EXPECT_EQ(fit.exit_code, 0) << fit.output;
  EXPECT_TRUE(fs::exists(session + "/fit/tau/tau.exr"));
  EXPECT_TRUE(fs::exists(session + "/fit/tau/tau_falsecolor.png"));
  EXPECT_GT(fs::file_size(session + "/fit/tau/tau_falsecolor.png"), 1000u);
  EXPECT_TRUE(fs::exists(session + "/fit/tau/summary.json"));
  EXPECT_TRUE(fs::exists(session + "/fit/tau/options.ini"));
}

// Issue #22: the comparison with a simulated capture's ground truth is optional; when it cannot
// be made, the fit is still written (with a warning), not thrown away after a full fit.
TEST_F(CliBadInputTest, FitIsWrittenWhenTheGroundTruthComparisonFails) {
  const std::string session = CopyBase("bad_truth");
  Image other(4, 4, {"tau"});  // A truth of another grid than the fit's.
  ASSERT_TRUE(WriteExr(session + "/ground_truth/tau.exr", other).ok());
  const RunResult fit = RunThinslab("fit tau " + session);
  EXPECT_EQ(fit.exit_code, 0) << fit.output;
  EXPECT_NE(fit.output.find("warning: the fit is written without the ground-truth comparison"), std::string::npos)
      << fit.output;
  EXPECT_NE(fit.output.find("ground_truth/tau.exr"), std::string::npos) << fit.output;
  EXPECT_TRUE(fs::exists(session + "/fit/tau/tau.exr"));
  EXPECT_TRUE(fs::exists(session + "/fit/tau/summary.json"));
  EXPECT_FALSE(fs::exists(session + "/fit/tau/comparison.json"));
  EXPECT_FALSE(fs::exists(session + "/fit/tau/error_falsecolor.png"));
}

// Issue #22: a second fit replaces the first (its own stamped output), and the staging folder
// a killed fit left beside it is removed.
TEST_F(CliBadInputTest, RefitReplacesItsOwnOutputAndClearsAKilledRunsStaging) {
  const std::string session = CopyBase("refit");
  ASSERT_EQ(RunThinslab("fit tau " + session).exit_code, 0);
  const std::string stale = session + "/fit/tau.partial-999999999";  // No such process.
  fs::create_directories(stale);
  std::ofstream(stale + "/tau.exr") << "half-written";
  const RunResult again = RunThinslab("fit tau " + session + " --albedo 0.5");
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_FALSE(fs::exists(stale));
  std::ifstream ini(session + "/fit/tau/options.ini");
  const std::string options((std::istreambuf_iterator<char>(ini)), std::istreambuf_iterator<char>());
  EXPECT_NE(options.find("albedo = 0.5"), std::string::npos) << options;
  EXPECT_TRUE(fs::exists(session + "/fit/tau/.thinslab-output"));
}

// Issue #23 section 5: summary.json says which clean reference the fit used and, for 'auto',
// how many pixels it judged clean.
TEST_F(CliBadInputTest, SummaryRecordsTheReferenceAndThePixelsJudgedClean) {
  const std::string session = CopyBase("reference_summary");
  ASSERT_EQ(RunThinslab("fit tau " + session + " --out " + session + "/fit/frame").exit_code, 0);
  const RunResult automatic = RunThinslab("fit tau " + session + " --reference auto --out " + session + "/fit/auto");
  ASSERT_EQ(automatic.exit_code, 0) << automatic.output;
  auto summary = [&](const std::string& name) {
    std::ifstream in(session + "/fit/" + name + "/summary.json");
    return nlohmann::json::parse(in);
  };
  const nlohmann::json frame = summary("frame"), autos = summary("auto");
  EXPECT_EQ(frame["reference"]["mode"], "frame");
  EXPECT_TRUE(frame["reference"]["pixels_judged_clean"].is_null());
  EXPECT_EQ(autos["reference"]["mode"], "auto");
  const int64_t clean = autos["reference"]["pixels_judged_clean"].get<int64_t>();
  EXPECT_GT(clean, 0);
  EXPECT_LE(clean, autos["pixels"]["total"].get<int64_t>() - autos["pixels"]["outside"].get<int64_t>());
}

TEST_F(CliBadInputTest, MissingFrameFile) {
  const std::string session = CopyBase("missing_frame");
  const std::string file = FirstFrameOfKind(ReadManifest(session), "shadow");
  fs::remove(session + "/" + file);
  ExpectFitFails(session, {file});
  EXPECT_NE(RunThinslab("info " + session).exit_code, 0);
}

TEST_F(CliBadInputTest, TruncatedFramePng) {
  const std::string session = CopyBase("truncated_png");
  const std::string file = FirstFrameOfKind(ReadManifest(session), "shadow");
  fs::resize_file(session + "/" + file, 100);
  ExpectFitFails(session, {file, "corrupt or truncated"});
}

TEST_F(CliBadInputTest, TruncatedExrTexture) {
  const std::string exr = *dir_ / "truncated.exr";
  fs::copy_file(*dir_ / "small.exr", exr, fs::copy_options::overwrite_existing);
  fs::resize_file(exr, fs::file_size(exr) / 2);
  const RunResult result = RunThinslab("sim shadow-maps " + *dir_ / "from_truncated" + " --tau " + exr);
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(CountLines(result.output), 1) << result.output;
  EXPECT_NE(result.output.find("truncated.exr"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(*dir_ / "from_truncated"));
}

TEST_F(CliBadInputTest, SimulationNeverOverwritesACapture) {
  const std::string session = CopyBase("existing");
  const auto before = fs::last_write_time(session + "/session.json");
  const RunResult result = RunThinslab("sim shadow-maps " + session + " --tau " + *dir_ / "small.exr");
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.output.find("exists and is not empty"), std::string::npos) << result.output;
  EXPECT_EQ(fs::last_write_time(session + "/session.json"), before);
}

TEST_F(CliBadInputTest, FramesOfDifferentSizes) {
  const std::string session = CopyBase("different_sizes");
  const std::string file = FirstFrameOfKind(ReadManifest(session), "reference");
  ASSERT_TRUE(WriteRawFrame(session + "/" + file, Image(100, 80, 500.0f), 12).ok());
  ExpectFitFails(session, {file, "100x80", "320x240"});
}

TEST_F(CliBadInputTest, UnknownFormatVersion) {
  const std::string session = CopyBase("version");
  nlohmann::json j = ReadManifest(session);
  j["format_version"] = "2.0";
  WriteManifest(session, j);
  ExpectFitFails(session, {"session.json", "format_version", "2.0"});
}

TEST_F(CliBadInputTest, WrongJsonType) {
  const std::string session = CopyBase("wrong_type");
  nlohmann::json j = ReadManifest(session);
  j["frames"][2]["exposure_time_us"] = "fast";
  WriteManifest(session, j);
  ExpectFitFails(session, {"session.json", "frames[2].exposure_time_us"});
}

TEST_F(CliBadInputTest, ZeroCameraWidth) {
  const std::string session = CopyBase("zero_width");
  nlohmann::json j = ReadManifest(session);
  j["rig"]["cameras"][0]["width_px"] = 0;
  WriteManifest(session, j);
  ExpectFitFails(session, {"session.json", "rig.cameras[0].width_px"});
}

TEST_F(CliBadInputTest, NegativePixelPitch) {
  const std::string session = CopyBase("negative_pitch");
  nlohmann::json j = ReadManifest(session);
  j["rig"]["sample"]["pixel_pitch_m"] = -1e-4;
  WriteManifest(session, j);
  ExpectFitFails(session, {"session.json", "rig.sample.pixel_pitch_m"});
}

// Shadow frames at zero DN (below the black level): nothing measurable, no NaN map.
TEST_F(CliBadInputTest, ZeroShadowFrames) {
  const std::string session = CopyBase("zero_shadow");
  const nlohmann::json manifest = ReadManifest(session);
  for (const auto& f : manifest["frames"]) {
    if (f["kind"] != "shadow") continue;
    ASSERT_TRUE(WriteRawFrame(session + "/" + f["file"].get<std::string>(), Image(320, 240, 0.0f), 12).ok());
  }
  ExpectFitFails(session, {session, "no pixel could be fitted"});
}

TEST_F(CliBadInputTest, AllSaturatedReference) {
  const std::string session = CopyBase("saturated_reference");
  const nlohmann::json manifest = ReadManifest(session);
  for (const auto& f : manifest["frames"]) {
    if (f["kind"] != "reference") continue;
    ASSERT_TRUE(WriteRawFrame(session + "/" + f["file"].get<std::string>(), Image(320, 240, 4095.0f), 12).ok());
  }
  ExpectFitFails(session, {session, "saturated", "exposure_time_us"});
}

TEST_F(CliBadInputTest, BadOptionValue) {
  const std::string session = CopyBase("bad_option");
  const RunResult result = RunThinslab("fit tau " + session + " --albedo 1.7");
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.output.find("TauFitOptions::layer_albedo"), std::string::npos) << result.output;
  const RunResult typo = RunThinslab("fit tau " + session + " --albdo 0.3");
  EXPECT_NE(typo.exit_code, 0);
  EXPECT_NE(typo.output.find("--albdo"), std::string::npos) << typo.output;
  EXPECT_FALSE(fs::exists(session + "/fit/tau"));
}

// Laser-lobe captures (`thinslab fit phase`).
class LaserCliTest : public CliBadInputTest {
 protected:
  static void SetUpTestSuite() {
    laser_dir_ = new TempDir();
    const std::string small = " --camera-width-px 640 --camera-height-px 480 --capture-clean false";
    ASSERT_EQ(RunThinslab("sim laser " + *laser_dir_ / "base" + small).exit_code, 0);
    ASSERT_EQ(RunThinslab("sim laser " + *laser_dir_ / "one_exposure" + small + " --exposures-us 2000").exit_code, 0);
    ASSERT_EQ(RunThinslab("sim laser " + *laser_dir_ / "no_beam" + small + " --spike-fill 1e-9").exit_code, 0);
  }
  static void TearDownTestSuite() { delete laser_dir_; }

  void ExpectPhaseFails(const std::string& session, const std::vector<std::string>& expected_in_message) {
    const RunResult result = RunThinslab("fit phase " + session);
    EXPECT_NE(result.exit_code, 0) << result.output;
    EXPECT_EQ(CountLines(result.output), 1) << result.output;
    for (const auto& piece : expected_in_message) {
      EXPECT_NE(result.output.find(piece), std::string::npos) << "'" << piece << "' not in: " << result.output;
    }
    EXPECT_FALSE(fs::exists(session + "/fit/phase")) << "output left behind";
  }

  static TempDir* laser_dir_;
};

TempDir* LaserCliTest::laser_dir_ = nullptr;

TEST_F(LaserCliTest, ValidCaptureFitsAndWritesReport) {
  const std::string session = *laser_dir_ / "valid";
  fs::copy(*laser_dir_ / "base", session, fs::copy_options::recursive);
  const RunResult result = RunThinslab("fit phase " + session + " --tau 0.3");
  EXPECT_EQ(result.exit_code, 0) << result.output;
  for (const char* file : {"summary.json", "summary.txt", "rings.csv", "lobe_plot.png", "options.ini"}) {
    EXPECT_TRUE(fs::exists(session + "/fit/phase/" + file)) << file;
  }
}

TEST_F(LaserCliTest, NoExposureBracket) {
  ExpectPhaseFails(*laser_dir_ / "one_exposure", {"session.json", "single exposure_time_us", "bracket"});
}

TEST_F(LaserCliTest, BeamNotFound) { ExpectPhaseFails(*laser_dir_ / "no_beam", {"no_beam", "beam not found"}); }

TEST_F(LaserCliTest, BoardGeometryMissing) {
  const std::string session = *laser_dir_ / "no_board";
  fs::copy(*laser_dir_ / "base", session, fs::copy_options::recursive);
  nlohmann::json j = ReadManifest(session);
  j["rig"].erase("board");
  WriteManifest(session, j);
  ExpectPhaseFails(session, {"session.json", "rig.board"});
}

// A written PNG: the file exists, has the PNG signature and is more than a header.
void ExpectPng(const std::string& path) {
  ASSERT_TRUE(fs::exists(path)) << path;
  EXPECT_GT(fs::file_size(path), 1000u) << path;
  std::ifstream in(path, std::ios::binary);
  std::array<char, 8> signature{};
  in.read(signature.data(), signature.size());
  EXPECT_EQ(std::string(signature.data(), signature.size()), std::string("\x89PNG\r\n\x1a\n", 8)) << path;
}

// `thinslab fit dmf` on a capture it must refuse: non-zero exit, exactly one line "error: ..."
// naming every expected piece (file, field), and no output folder, complete or partial.
void ExpectDmfFitFails(const std::string& session, const std::vector<std::string>& expected_in_message) {
  const RunResult result = RunThinslab("fit dmf " + session + " --pitch-mm 8");
  EXPECT_EQ(result.exit_code, 1) << result.output;
  EXPECT_EQ(CountLines(result.output), 1) << result.output;
  EXPECT_EQ(result.output.rfind("error: ", 0), 0u) << result.output;
  for (const auto& piece : expected_in_message) {
    EXPECT_NE(result.output.find(piece), std::string::npos) << "'" << piece << "' not in: " << result.output;
  }
  EXPECT_FALSE(fs::exists(session + "/fit")) << "output left behind in " << session;
}

// A copy of a dot scan (without its fit outputs) whose manifest `edit` changes.
template <typename Edit>
std::string EditedDotScan(const std::string& scan, const std::string& target, const Edit& edit) {
  fs::copy(scan, target, fs::copy_options::recursive);
  fs::remove_all(target + "/fit");
  std::ifstream in(target + "/session.json");
  nlohmann::json j = nlohmann::json::parse(in);
  in.close();
  edit(j);
  std::ofstream(target + "/session.json") << j.dump(1);
  return target;
}

// thinslab fit dmf end to end through the CLI: outputs written (maps, NDF pictures), every map
// value finite; bad captures (too few dots, dot positions missing, no all-dots frame, a
// saturated all-dots bracket, a capture that is not a dot scan) and an impossible option are
// refused with one line naming the file and field, leaving no output behind.
TEST(DmfCliTest, FitsADotScanAndRefusesBadInput) {
  TempDir dir;
  const std::string scan = dir / "scan";
  const RunResult sim = RunThinslab("sim dot-scan " + scan + " --grid-nx 8 --grid-ny 8 --photons-k 40");
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  const RunResult fit = RunThinslab("fit dmf " + scan + " --pitch-mm 8 --cluster-fraction 0.2");
  ASSERT_EQ(fit.exit_code, 0) << fit.output;
  for (const char* file : {"maps.exr", "ndf_atlas.exr", "top_face_weight_falsecolor.png", "status_falsecolor.png", "summary.json", "summary.txt",
                           "options.ini"}) {
    EXPECT_TRUE(std::filesystem::exists(scan + "/fit/dmf/" + file)) << file;
  }
  Image maps;
  ASSERT_TRUE(ReadExr(scan + "/fit/dmf/maps.exr", &maps).ok());
  EXPECT_EQ(maps.num_channels(), 13);
  for (const char* name : {"equivalent_roughness", "ndf_family", "rough_face", "sigma_top_face_weight",
                           "sigma_equivalent_roughness"}) {
    EXPECT_GE(maps.ChannelIndex(name), 0) << name;
  }
  // Pictures: the maps of k_s, rho_d and the Smith roughness, and (Dai Fig. 6) the NDFs at the
  // default points (k/4 of the map, k = 1..3: ndf_<col>_<row>.png), and no other NDF picture.
  for (const char* name : {"k_s", "rho_d", "smith_alpha"}) ExpectPng(scan + "/fit/dmf/" + name + "_falsecolor.png");
  int ndf_pictures = 0;
  for (int k = 1; k <= 3; ++k) {
    ExpectPng(scan + "/fit/dmf/ndf_" + std::to_string(k * maps.width() / 4) + "_" +
              std::to_string(k * maps.height() / 4) + ".png");
  }
  for (const auto& entry : fs::directory_iterator(scan + "/fit/dmf")) {
    const std::string name = entry.path().filename().string();
    ndf_pictures += name.rfind("ndf_", 0) == 0 && name.size() > 4 && std::isdigit(static_cast<unsigned char>(name[4])) &&
                    entry.path().extension() == ".png";
  }
  EXPECT_EQ(ndf_pictures, 3);
  EXPECT_GE(maps.ChannelIndex("measured_ndf_fraction"), 0);
  EXPECT_GE(maps.ChannelIndex("transmittance"), 0);
  for (float v : maps.data()) ASSERT_TRUE(std::isfinite(v));
  // The grid-scale check of the monitor distance: the simulated d is right, so no warning; with
  // --refine-monitor-distance the correction is recorded (small: d was right).
  std::string summary_text;
  ASSERT_TRUE(ReadFileToString(scan + "/fit/dmf/summary.json", &summary_text).ok());
  nlohmann::json summary = nlohmann::json::parse(summary_text);
  EXPECT_EQ(summary["monitor_distance"]["warning"], "");
  EXPECT_EQ(summary["monitor_distance"]["correction_m"], 0);
  EXPECT_LT(std::abs(summary["monitor_distance"]["error_m"].get<double>()), 0.25e-3);
  const RunResult refined =
      RunThinslab("fit dmf " + scan + " --pitch-mm 8 --refine-monitor-distance true --out " + (dir / "refined"));
  ASSERT_EQ(refined.exit_code, 0) << refined.output;
  ASSERT_TRUE(ReadFileToString(dir / "refined/summary.json", &summary_text).ok());
  summary = nlohmann::json::parse(summary_text);
  EXPECT_LT(std::abs(summary["monitor_distance"]["correction_m"].get<double>()), 0.25e-3);
  EXPECT_NE(summary["monitor_distance"]["correction_m"], 0);
  EXPECT_LT(std::abs(summary["monitor_distance"]["error_m"].get<double>()), 1e-6);

  // The model ladder needs held-out dots; with them it writes its rung map.
  const RunResult no_hold_out = RunThinslab("fit dmf " + scan + " --pitch-mm 8 --ladder true --out " + (dir / "l0"));
  EXPECT_EQ(no_hold_out.exit_code, 1);
  EXPECT_NE(no_hold_out.output.find("--hold-out"), std::string::npos) << no_hold_out.output;
  const RunResult ladder =
      RunThinslab("fit dmf " + scan + " --pitch-mm 8 --hold-out true --ladder true --out " + (dir / "l1"));
  ASSERT_EQ(ladder.exit_code, 0) << ladder.output;
  Image rungs;
  ASSERT_TRUE(ReadExr(dir / "l1" + "/ladder.exr", &rungs).ok());
  const int rung_channel = rungs.ChannelIndex("rung");
  ASSERT_GE(rung_channel, 0);
  // The choice takes effect in maps.exr: points on rung 3 (one rough face) hold alpha 0 or 1, and
  // the summary counts the points replaced by rungs 3 and 4.
  Image chosen_maps;
  ASSERT_TRUE(ReadExr(dir / "l1" + "/maps.exr", &chosen_maps).ok());
  EXPECT_EQ(chosen_maps.attributes().at("ladder_applied"), "true");
  int rung_3_or_4 = 0;
  for (int p = 0; p < rungs.width() * rungs.height(); ++p) {
    const float rung = rungs.data()[p * rungs.num_channels() + rung_channel];
    EXPECT_TRUE(rung == -1 || rung == 0 || rung == 3 || rung == 4 || rung == 5) << rung;
    const float alpha = chosen_maps.data()[p * chosen_maps.num_channels() + chosen_maps.ChannelIndex("top_face_weight")];
    if (rung == 3) {
      EXPECT_TRUE(alpha == 0 || alpha == 1) << "point " << p << " alpha " << alpha;
    }
    rung_3_or_4 += rung == 3 || rung == 4;
  }
  ASSERT_TRUE(ReadFileToString(dir / "l1" + "/summary.json", &summary_text).ok());
  summary = nlohmann::json::parse(summary_text);
  EXPECT_EQ(summary["ladder"]["criterion"], "held-out");
  EXPECT_GT(summary["ladder"]["points_replaced"].get<int>(), 0);
  EXPECT_LE(summary["ladder"]["points_replaced"].get<int>(), rung_3_or_4);
  // BIC as the criterion, and the tabulated fit kept everywhere with --ladder-apply false.
  const RunResult bic = RunThinslab("fit dmf " + scan +
                                    " --pitch-mm 8 --hold-out true --ladder true --ladder-criterion bic "
                                    "--ladder-apply false --out " + (dir / "l2"));
  ASSERT_EQ(bic.exit_code, 0) << bic.output;
  ASSERT_TRUE(ReadFileToString(dir / "l2" + "/summary.json", &summary_text).ok());
  summary = nlohmann::json::parse(summary_text);
  EXPECT_EQ(summary["ladder"]["criterion"], "bic");
  EXPECT_EQ(summary["ladder"]["points_replaced"], 0);
  Image kept_maps;
  ASSERT_TRUE(ReadExr(dir / "l2" + "/maps.exr", &kept_maps).ok());
  EXPECT_EQ(kept_maps.attributes().at("ladder_applied"), "false");
  const RunResult bad_criterion =
      RunThinslab("fit dmf " + scan + " --pitch-mm 8 --hold-out true --ladder true --ladder-criterion aic --out " +
                  (dir / "l3"));
  EXPECT_EQ(bad_criterion.exit_code, 1);
  EXPECT_NE(bad_criterion.output.find("--ladder-criterion"), std::string::npos) << bad_criterion.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "l3"));

  const RunResult bad_option = RunThinslab("fit dmf " + scan + " --ndf-resolution 2 --out " + (dir / "x"));
  EXPECT_EQ(bad_option.exit_code, 1);
  EXPECT_NE(bad_option.output.find("ndf_resolution"), std::string::npos) << bad_option.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x"));

  const RunResult missing = RunThinslab("fit dmf " + (dir / "nothing_here"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find("nothing_here"), std::string::npos) << missing.output;

  // Bad captures (Dai Sec. 4.1 needs a regular dot grid, each dot's position, and the dots
  // located without the sample).
  const std::string few = dir / "few_dots";
  ASSERT_EQ(RunThinslab("sim dot-scan " + few + " --grid-nx 3 --grid-ny 3 --photons-k 20").exit_code, 0);
  ExpectDmfFitFails(few, {few + "/session.json", "3 x 3 dots", "at least 4 x 4"});
  const std::string no_dot_px = EditedDotScan(scan, dir / "no_dot_px", [](nlohmann::json& j) {
    for (auto& f : j["frames"]) {
      if (f["kind"] == "dot") f["light"].erase("dot_px");
    }
  });
  ExpectDmfFitFails(no_dot_px, {no_dot_px + "/session.json", "frames/cam0/dot/", "light.dot_px"});
  const std::string no_all_dots = EditedDotScan(scan, dir / "no_all_dots", [](nlohmann::json& j) {
    nlohmann::json frames = nlohmann::json::array();
    for (auto& f : j["frames"]) {
      if (f["kind"] == "all_dots") continue;
      f["index"] = frames.size();  // Indices stay contiguous (docs/format.md).
      frames.push_back(f);
    }
    j["frames"] = frames;
  });
  ExpectDmfFitFails(no_all_dots, {no_all_dots + "/session.json", "'all_dots'", "sample_state 'none'"});
  const std::string saturated = dir / "saturated";
  ASSERT_EQ(RunThinslab("sim dot-scan " + saturated + " --grid-nx 6 --grid-ny 6 --photons-k 20 --dot-radiance 50")
                .exit_code,
            0);
  ExpectDmfFitFails(saturated, {"frames/cam0/all_dots/", "saturated"});
  // Not a dot scan: a shadow-map capture has no monitor, which the fit names (before looking
  // for 'dot' frames).
  const std::string shadow = dir / "shadow_maps";
  ASSERT_EQ(RunThinslab("sim pattern " + dir / "pattern.exr" + " --width-px 40 --height-px 40").exit_code, 0);
  ASSERT_EQ(RunThinslab("sim shadow-maps " + shadow + " --tau " + dir / "pattern.exr" +
                        " --camera-width-px 320 --camera-height-px 240 --photons 20000 --frames 2 --dark-frames 1")
                .exit_code,
            0);
  ExpectDmfFitFails(shadow, {shadow + "/session.json", "rig.monitor", "dot scan"});
  // A capture with a monitor but no 'dot' frames (e.g. only its all-dots calibration frames).
  const std::string only_all_dots = EditedDotScan(scan, dir / "only_all_dots", [](nlohmann::json& j) {
    nlohmann::json frames = nlohmann::json::array();
    for (auto& f : j["frames"]) {
      if (f["kind"] != "all_dots") continue;
      f["index"] = frames.size();
      frames.push_back(f);
    }
    j["frames"] = frames;
  });
  ExpectDmfFitFails(only_all_dots, {only_all_dots + "/session.json", "kind 'dot'", "not a dot scan"});
}

// Issue #23 section 5: `fit phase --board-distance-m` replaces the manifest's distance (as in
// `fit tau`): a manifest with a wrong distance plus the option fits the same g, bit for bit, as
// the manifest with the right one; summary.json records the distance used.
TEST(FitPhaseCli, BoardDistanceOptionReplacesTheManifests) {
  TempDir dir;
  const std::string lobe = dir / "lobe";
  const RunResult sim = RunThinslab("sim laser " + lobe +
                                    " --camera-width-px 160 --camera-height-px 120 --capture-clean false --photons 20000");
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  const RunResult right = RunThinslab("fit phase " + lobe + " --out " + lobe + "/fit/right");
  ASSERT_EQ(right.exit_code, 0) << right.output;
  std::ifstream in(lobe + "/session.json");
  nlohmann::json manifest = nlohmann::json::parse(in);
  in.close();
  const double distance_m = manifest["rig"]["board"]["distance_m"].get<double>();
  manifest["rig"]["board"]["distance_m"] = 2 * distance_m;
  std::ofstream(lobe + "/session.json") << manifest.dump(2);
  const RunResult wrong = RunThinslab("fit phase " + lobe + " --out " + lobe + "/fit/wrong");
  std::ostringstream option;
  option.precision(17);
  option << distance_m;
  const RunResult fixed =
      RunThinslab("fit phase " + lobe + " --board-distance-m " + option.str() + " --out " + lobe + "/fit/fixed");
  ASSERT_EQ(fixed.exit_code, 0) << fixed.output;
  auto summary = [&](const std::string& name) {
    std::ifstream s(lobe + "/fit/" + name + "/summary.json");
    return nlohmann::json::parse(s);
  };
  const nlohmann::json r = summary("right"), f = summary("fixed");
  EXPECT_EQ(r["g"], f["g"]);
  EXPECT_EQ(r["sigma_g"], f["sigma_g"]);
  EXPECT_DOUBLE_EQ(f["board_distance_m"].get<double>(), distance_m);
  if (wrong.exit_code == 0) {  // The wrong distance moves g (or the fit fails).
    EXPECT_DOUBLE_EQ(summary("wrong")["board_distance_m"].get<double>(), 2 * distance_m);
    EXPECT_NE(summary("wrong")["g"], r["g"]);
  }
  const RunResult bad = RunThinslab("fit phase " + lobe + " --board-distance-m 1e308 --out " + lobe + "/fit/bad");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("--board-distance-m"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace thinslab
