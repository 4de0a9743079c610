// SPDX-License-Identifier: Apache-2.0
// Issue #26 item 1: every output folder's files are what other programs read. Each command that
// writes maps runs once on a small simulated capture; then every EXR in every output folder is
// checked as a user's program would open it (OpenEXR's channel list and types, cv::imread) and
// for the provenance that core/provenance.h stamps, and every summary.json for the same
// provenance, whose options digest is that of the folder's options.ini.
#include <ImfChannelList.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStringAttribute.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/provenance.h"
#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSmallShadow = " --camera-width-px 240 --camera-height-px 180 --photons 20000 --frames 2";
constexpr const char* kSmallLaser = " --camera-width-px 320 --camera-height-px 240";
constexpr const char* kSmallDots =
    " --grid-nx 6 --grid-ny 6 --validation-dots 2 --photons-k 4 --camera-width-px 160 --camera-height-px 120 "
    "--table-bins 16";

std::string StringAttribute(const Imf::Header& header, const char* key) {
  const auto* a = header.findTypedAttribute<Imf::StringAttribute>(key);
  return a == nullptr ? "" : a->value();
}

// One output EXR as other programs see it; returns its thinslab_command and options_digest.
void CheckExr(const std::string& path, std::string* command, std::string* digest) {
  SCOPED_TRACE(path);
  Imf::InputFile file(path.c_str());
  const Imf::Header& header = file.header();
  EXPECT_EQ(StringAttribute(header, "format_version"), kOutputFormatVersion);
  for (const char* key : {"thinslab_version", "git_hash", "thinslab_command", "options_digest", "source_session",
                          "primary_channel", "comments"}) {
    EXPECT_FALSE(StringAttribute(header, key).empty()) << "attribute " << key;
  }
  *command = StringAttribute(header, "thinslab_command");
  *digest = StringAttribute(header, "options_digest");
  const std::string primary = StringAttribute(header, "primary_channel");
  EXPECT_NE(header.channels().findChannel("Y"), nullptr) << "no default-layer Y";
  EXPECT_NE(header.channels().findChannel(primary + ".Y"), nullptr) << "no layer " << primary;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    const std::string name = it.name();
    EXPECT_TRUE(name == "Y" || (name.size() > 2 && name.substr(name.size() - 2) == ".Y")) << name;
    if (name == "status.Y" || name == "valid.Y" || name == "saturated.Y") {
      EXPECT_EQ(it.channel().type, Imf::UINT) << name << " is an integer channel";
    }
  }
  const cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(image.empty()) << "cv::imread cannot read it";
  EXPECT_EQ(image.type(), CV_32FC1);
  const Imath::Box2i window = header.dataWindow();
  EXPECT_EQ(image.cols, window.max.x - window.min.x + 1);
  EXPECT_EQ(image.rows, window.max.y - window.min.y + 1);
}

// Every EXR and summary.json under `folder`: the same command, and the digest of options.ini.
void CheckOutputFolder(const std::string& folder, const std::string& expected_command, int min_exr_files) {
  SCOPED_TRACE(folder);
  std::string options_digest;
  std::string ini;
  if (ReadFileToString(JoinPath(folder, "options.ini"), &ini).ok()) options_digest = OptionsDigest(ini);
  int exr_files = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (entry.path().extension() != ".exr") continue;
    ++exr_files;
    std::string command, digest;
    CheckExr(entry.path(), &command, &digest);
    EXPECT_EQ(command, expected_command) << entry.path();
    if (!options_digest.empty()) {
      EXPECT_EQ(digest, options_digest) << entry.path();
    }
  }
  EXPECT_GE(exr_files, min_exr_files);
  if (!FileExists(JoinPath(folder, "summary.json"))) return;
  const nlohmann::json provenance = ReadJsonFile(JoinPath(folder, "summary.json"))["provenance"];
  ASSERT_TRUE(provenance.is_object()) << folder << "/summary.json has no provenance";
  EXPECT_EQ(provenance["command"], expected_command);
  EXPECT_EQ(provenance["format_version"], kOutputFormatVersion);
  EXPECT_FALSE(provenance["git_hash"].get<std::string>().empty());
  if (!options_digest.empty()) {
    EXPECT_EQ(provenance["options_digest"], options_digest);
  }
}

// Issue #26 item 5: the folder's report.html, loaded by headless Chromium (Debian `chromium`),
// shows every picture of the folder and raises no script error.
void CheckReportInChromium(const std::string& folder) {
  SCOPED_TRACE(folder + "/report.html");
  int pictures = 0;
  for (const auto& entry : fs::directory_iterator(folder)) pictures += entry.path().extension() == ".png";
  const std::string log = folder + "_chromium.log";
  const std::string command = "chromium --headless --no-sandbox --disable-gpu --virtual-time-budget=10000 "
                              "--enable-logging=stderr --v=0 --dump-dom 'file://" + folder + "/report.html' 2>'" + log + "'";
  std::string dom;
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  char buffer[65536];
  while (fgets(buffer, sizeof(buffer), pipe) != nullptr) dom += buffer;
  EXPECT_EQ(pclose(pipe), 0) << "chromium failed; its log: " << log;
  const std::string shown = "data-images-shown=\"" + std::to_string(pictures) + "/" + std::to_string(pictures) + "\"";
  EXPECT_NE(dom.find(shown), std::string::npos) << "expected " << shown << " in the DOM of " << folder << "/report.html";
  std::string errors;
  ASSERT_TRUE(ReadFileToString(log, &errors).ok());
  EXPECT_EQ(errors.find("Uncaught"), std::string::npos) << errors;
  std::string html;
  ASSERT_TRUE(ReadFileToString(folder + "/report.html", &html).ok());
  for (const char* part : {"<h2>Warnings</h2>", "<h2>Provenance</h2>", "command_line"}) {
    EXPECT_NE(html.find(part), std::string::npos) << part;
  }
  // The command that repeats the run, where the folder has its options.ini.
  EXPECT_EQ(html.find("Repeat this run exactly") != std::string::npos, FileExists(folder + "/options.ini"));
}

// Issue #26 item 2: `thinslab COMMAND --config FOLDER/options.ini` repeats the run exactly: the
// same options.ini (so the same digest) and the same map, value for value.
void RerunFromOptionsIni(const TempDir& dir, const std::string& command, const std::string& folder,
                         const std::string& map_file) {
  SCOPED_TRACE(command + " --config " + folder + "/options.ini");
  std::string ini;
  ASSERT_TRUE(ReadFileToString(JoinPath(folder, "options.ini"), &ini).ok());
  const std::string copy = dir / "rerun_options.ini";  // The rerun replaces the folder.
  ASSERT_TRUE(WriteFileAtomically(copy, ini).ok());
  Image before, after;
  ASSERT_TRUE(ReadExr(JoinPath(folder, map_file), &before).ok());
  RunThinslabOk(command + " --config " + copy);
  std::string ini_after;
  ASSERT_TRUE(ReadFileToString(JoinPath(folder, "options.ini"), &ini_after).ok());
  EXPECT_EQ(ini_after, ini);
  ASSERT_TRUE(ReadExr(JoinPath(folder, map_file), &after).ok());
  EXPECT_EQ(after.attributes().at("options_digest"), before.attributes().at("options_digest"));
  EXPECT_EQ(after.attributes().at("options_digest"), OptionsDigest(ini));
  EXPECT_EQ(after.channel_names(), before.channel_names());
  EXPECT_TRUE(after.data() == before.data()) << map_file << " differs after the rerun";
}

TEST(CliOutputFiles, EveryOutputFolderIsReadableByOtherProgramsAndCarriesItsProvenance) {
  setenv("OPENCV_IO_ENABLE_OPENEXR", "1", 1);  // OpenCV reads EXR only when the user enables it.
  TempDir dir;
  const std::string shadow = dir / "shadow", lobe = dir / "lobe", dots = dir / "dots";
  RunThinslabOk("sim shadow-maps " + shadow + kSmallShadow);
  RunThinslabOk("fit tau " + shadow + " --split-half-check false --albedo 0.2718281828459045 --threads 1");
  RunThinslabOk("predict " + shadow + " --out " + (dir / "predict_shadow"));
  RunThinslabOk("calib hdr " + shadow + " --kind reference");
  RunThinslabOk("calib flat " + shadow);
  RunThinslabOk("sim laser " + lobe + kSmallLaser);
  // calib response: response.json carries the provenance object (and stays readable).
  RunThinslabOk("calib response " + lobe + " --out " + (dir / "response.json"));
  const nlohmann::json response = ReadJsonFile(dir / "response.json");
  EXPECT_EQ(response["provenance"]["command"], "calib response");
  EXPECT_EQ(response["provenance"]["format_version"], kOutputFormatVersion);
  EXPECT_EQ(response["provenance"]["options_digest"].get<std::string>().rfind("fnv1a64:", 0), 0u);
  RunThinslabOk("calib hdr " + lobe + " --response " + (dir / "response.json") + " --out " + (dir / "lobe_hdr"));
  RunThinslabOk("fit phase " + lobe);
  RunThinslabOk("predict " + lobe + " --out " + (dir / "predict_lobe"));
  RunThinslabOk("sim dot-scan " + dots + kSmallDots);
  RunThinslabOk("fit dmf " + dots + " --pitch-mm 4 --hold-out true --ladder");
  RunThinslabOk("predict " + dots + " --out " + (dir / "predict_dots"));
  RunThinslabOk("synth layer " + (dir / "layer") + " --prototypes dust_specks_a --width 64 --height 48 --preview false");

  CheckOutputFolder(shadow + "/fit/tau", "fit tau", 1);
  CheckOutputFolder(dir / "predict_shadow", "predict", 2);
  CheckOutputFolder(shadow + "/calib/hdr", "calib hdr", 1);
  CheckOutputFolder(lobe + "/fit/phase", "fit phase", 0);
  CheckOutputFolder(dir / "predict_lobe", "predict", 1);
  CheckOutputFolder(dots + "/fit/dmf", "fit dmf", 3);  // maps, ndf_atlas, ladder.
  CheckOutputFolder(dir / "predict_dots", "predict", 2);
  CheckOutputFolder(dir / "layer", "synth layer", 1);
  // predict writes its options.ini too (the digest checks above then compare against it).
  for (const char* folder : {"predict_shadow", "predict_lobe", "predict_dots"}) {
    EXPECT_TRUE(FileExists(JoinPath(dir / folder, "options.ini"))) << folder;
  }
  std::string command, digest;
  CheckExr(shadow + "/calib/flat_field.exr", &command, &digest);
  EXPECT_EQ(command, "calib flat");

  for (const std::string& folder : {shadow + "/fit/tau", lobe + "/fit/phase", dots + "/fit/dmf", dir / "predict_shadow",
                                    dir / "predict_lobe", dir / "predict_dots", shadow + "/calib/hdr", dir / "layer"}) {
    CheckReportInChromium(folder);
  }
  // The command line that made the folder, in its provenance.
  EXPECT_NE(ReadJsonFile(shadow + "/fit/tau/summary.json")["provenance"].value("command_line", "").find(
                "thinslab fit tau " + shadow + " --split-half-check false"),
            std::string::npos);

  // Issue #26 item 6: --pixel X,Y follows one map point through the fit, ending in the value
  // the map holds.
  // --pixel changes what is printed, not what is written: the same options digest without it.
  RunThinslabOk("fit tau " + shadow + " --out " + (dir / "traced"));
  Image untraced_map;
  ASSERT_TRUE(ReadExr(dir / "traced/tau.exr", &untraced_map).ok());
  const RunResult traced = RunThinslabOk("fit tau " + shadow + " --pixel 7,5 --out " + (dir / "traced"));
  Image traced_map;
  ASSERT_TRUE(ReadExr(dir / "traced/tau.exr", &traced_map).ok());
  EXPECT_EQ(traced_map.attributes().at("options_digest"), untraced_map.attributes().at("options_digest"));
  std::string traced_ini;
  ASSERT_TRUE(ReadFileToString(dir / "traced/options.ini", &traced_ini).ok());
  EXPECT_NE(traced_ini.find("# pixel = 7,5"), std::string::npos) << traced_ini;
  const size_t result = traced.output.find("  result: tau = ");
  ASSERT_NE(result, std::string::npos) << traced.output;
  EXPECT_NE(traced.output.find("pixel (7, 5): shadow "), std::string::npos);
  EXPECT_NE(traced.output.find("  iteration 1: scattered S/E0 = "), std::string::npos);
  EXPECT_EQ(traced.output.find("pixel (7, 5)", traced.output.find("pixel (7, 5)") + 1), std::string::npos)
      << "traced more than once (the split-half fits must not trace)";
  const double printed = std::stod(traced.output.substr(result + 16));
  EXPECT_NEAR(printed, traced_map.at(7, 5, traced_map.ChannelIndex("tau")), 1e-6);
  const RunResult traced_dmf = RunThinslabOk("fit dmf " + dots + " --pitch-mm 4 --pixel 2,3 --out " + (dir / "traced_dmf"));
  Image dmf_map;
  ASSERT_TRUE(ReadExr(dir / "traced_dmf/maps.exr", &dmf_map).ok());
  const size_t weight = traced_dmf.output.find(", top_face_weight ", traced_dmf.output.find("in the maps: status"));
  ASSERT_NE(weight, std::string::npos) << traced_dmf.output;
  EXPECT_NE(traced_dmf.output.find("point (2, 3)"), std::string::npos);
  EXPECT_NEAR(std::stod(traced_dmf.output.substr(weight + 18)), dmf_map.at(2, 3, dmf_map.ChannelIndex("top_face_weight")),
              1e-5);
  const RunResult outside = RunThinslab("fit tau " + shadow + " --pixel 7000,5 --out " + (dir / "traced_outside"));
  EXPECT_EQ(outside.exit_code, 1);
  EXPECT_NE(outside.output.find("--pixel (TauFitOptions::trace) 7000,5 is outside the"), std::string::npos)
      << outside.output;

  RerunFromOptionsIni(dir, "fit tau", shadow + "/fit/tau", "tau.exr");
  RerunFromOptionsIni(dir, "fit dmf", dots + "/fit/dmf", "maps.exr");
  RerunFromOptionsIni(dir, "calib hdr", shadow + "/calib/hdr", "reference_clean.exr");
  RerunFromOptionsIni(dir, "synth layer", dir / "layer", "layer.exr");
  // A changed option is a different run: another digest.
  std::string ini;
  ASSERT_TRUE(ReadFileToString(shadow + "/fit/tau/options.ini", &ini).ok());
  ASSERT_TRUE(WriteFileAtomically(dir / "tau.ini", ini).ok());
  RunThinslabOk("fit tau --config " + (dir / "tau.ini") + " --albedo 0.3 --out " + (dir / "changed"));
  Image changed;
  ASSERT_TRUE(ReadExr(dir / "changed/tau.exr", &changed).ok());
  EXPECT_NE(changed.attributes().at("options_digest"), OptionsDigest(ini));
}

}  // namespace
}  // namespace thinslab
