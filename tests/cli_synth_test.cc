// SPDX-License-Identifier: Apache-2.0
// `thinslab synth layer` through the real binary (Gu et al. 2007, Sec. 5.3; docs/cli.md): the
// documented run writes the four-channel layer EXR of the requested size with its previews,
// a seed fixes the EXR byte for byte and another seed changes it, and bad input (an unknown
// prototype, an impossible size, a bad spec file) exits non-zero with one line naming the
// option or file, leaving no output behind. Small sizes: the whole test takes seconds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

constexpr char kLayers[] = "--prototypes dust_specks_a,water_streak_a,fingerprint_a";
constexpr int kWidthPx = 160, kHeightPx = 120;

std::string LayerArgs(const std::string& out, uint64_t seed) {
  return "synth layer " + out + " " + kLayers + " --width " + std::to_string(kWidthPx) + " --height " +
         std::to_string(kHeightPx) + " --seed " + std::to_string(seed) + " --preview-px 96";
}

std::string Bytes(const std::string& path) {
  std::string bytes;
  EXPECT_TRUE(ReadFileToString(path, &bytes).ok()) << path;
  return bytes;
}

// Width and height from a PNG's IHDR chunk; {0, 0} if it is not a PNG.
std::pair<uint32_t, uint32_t> PngSize(const std::string& path) {
  const std::string b = Bytes(path);
  if (b.size() < 24 || b.compare(0, 8, "\x89PNG\r\n\x1a\n") != 0 || b.compare(12, 4, "IHDR") != 0) return {0, 0};
  auto be32 = [&](size_t at) {
    uint32_t v = 0;
    for (size_t k = 0; k < 4; ++k) v = (v << 8) | static_cast<unsigned char>(b[at + k]);
    return v;
  };
  return {be32(16), be32(20)};
}

int CountLines(const std::string& text) {
  int n = 0;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) n += !line.empty();
  return n;
}

// Nothing named OUT or OUT.<anything> (a staging or old folder) is left in OUT's parent.
void ExpectNoOutput(const std::string& out) {
  EXPECT_FALSE(fs::exists(out)) << out;
  const std::string stem = fs::path(out).filename().string() + ".";
  for (const auto& entry : fs::directory_iterator(fs::path(out).parent_path())) {
    EXPECT_NE(entry.path().filename().string().rfind(stem, 0), 0u) << "left behind: " << entry.path();
  }
}

// One error line naming every piece, non-zero exit, no output.
void ExpectLayerFails(const std::string& args, const std::string& out, const std::vector<std::string>& pieces) {
  const RunResult result = RunThinslab(args);
  EXPECT_NE(result.exit_code, 0) << args << "\n" << result.output;
  EXPECT_EQ(CountLines(result.output), 1) << result.output;
  EXPECT_EQ(result.output.rfind("error: ", 0), 0u) << result.output;
  for (const auto& piece : pieces) {
    EXPECT_NE(result.output.find(piece), std::string::npos) << "'" << piece << "' not in: " << result.output;
  }
  ExpectNoOutput(out);
}

TEST(CliSynthTest, LayerWritesTheDocumentedFilesAndTheSeedFixesTheBytes) {
  TempDir dir;
  const std::string out = dir / "layer_a";
  RunResult result = RunThinslab(LayerArgs(out, 4));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  for (const char* name :
       {"layer.exr", "layer_preview.png", "pane_preview.png", "pane_preview.json", "summary.json", "options.ini"}) {
    EXPECT_TRUE(fs::is_regular_file(out + "/" + name)) << name;
  }
  Image layer;
  ASSERT_TRUE(ReadExr(out + "/layer.exr", &layer).ok());
  EXPECT_EQ(layer.width(), kWidthPx);
  EXPECT_EQ(layer.height(), kHeightPx);
  std::vector<std::string> channels = layer.channel_names();
  std::sort(channels.begin(), channels.end());
  EXPECT_EQ(channels, (std::vector<std::string>{"albedo", "g", "n2", "tau"}));
  const int tau_c = layer.ChannelIndex("tau"), g_c = layer.ChannelIndex("g"), albedo_c = layer.ChannelIndex("albedo"),
            n2_c = layer.ChannelIndex("n2");
  ASSERT_TRUE(tau_c >= 0 && g_c >= 0 && albedo_c >= 0 && n2_c >= 0);
  EXPECT_EQ(layer.attributes()["seed"], "4");
  EXPECT_EQ(layer.attributes()["prototypes"], "dust_specks_a,water_streak_a,fingerprint_a");
  int64_t covered = 0;
  for (int y = 0; y < kHeightPx; ++y) {
    for (int x = 0; x < kWidthPx; ++x) {
      const float tau = layer.at(x, y, tau_c);
      ASSERT_GE(tau, 0.0f);
      covered += tau > 0;
      if (tau == 0) {  // Clean glass: the documented no-layer values.
        ASSERT_EQ(layer.at(x, y, g_c), 0.0f);
        ASSERT_EQ(layer.at(x, y, albedo_c), 0.0f);
        ASSERT_EQ(layer.at(x, y, n2_c), 1.0f);
      }
    }
  }
  EXPECT_GT(covered, 0);
  EXPECT_LT(covered, static_cast<int64_t>(kWidthPx) * kHeightPx) << "some glass stays clean";
  const auto layer_png = PngSize(out + "/layer_preview.png");
  EXPECT_GE(layer_png.first, static_cast<uint32_t>(kWidthPx)) << "false colour, at least full size below 256 px";
  const auto pane_png = PngSize(out + "/pane_preview.png");
  EXPECT_GT(pane_png.first, 0u) << "pane_preview.png is not a PNG";
  EXPECT_GT(pane_png.first, pane_png.second) << "three panels side by side";
  const auto panes = nlohmann::json::parse(Bytes(out + "/pane_preview.json"), nullptr, false);
  ASSERT_FALSE(panes.is_discarded());
  ASSERT_EQ(panes["scenes"].size(), 3u);
  EXPECT_EQ(panes["scenes"][0]["scene"], "daylight_window");
  EXPECT_EQ(panes["scenes"][1]["scene"], "night_window");
  EXPECT_EQ(panes["scenes"][2]["scene"], "side_light");
  const auto summary = nlohmann::json::parse(Bytes(out + "/summary.json"), nullptr, false);
  ASSERT_FALSE(summary.is_discarded());
  ASSERT_EQ(summary["layers"].size(), 3u);
  EXPECT_EQ(summary["layers"][0]["method"], "quilting");
  EXPECT_EQ(summary["layers"][1]["method"], "placement");

  // Same command, same seed: the same EXR, byte for byte (the second run replaces the first).
  const std::string first = Bytes(out + "/layer.exr");
  result = RunThinslab(LayerArgs(out, 4));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(Bytes(out + "/layer.exr") == first) << "same seed, other bytes";
  ExpectNoOutput(dir / "nothing");  // No staging or old folders left beside it.
  // Another seed: another layer. (Another OUT with the same seed gives the same pixels; the
  // header's options_digest covers the OUT path of options.ini.)
  const std::string other = dir / "layer_b";
  result = RunThinslab(LayerArgs(other, 5));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  Image layer_b;
  ASSERT_TRUE(ReadExr(other + "/layer.exr", &layer_b).ok());
  EXPECT_NE(layer_b.data(), layer.data()) << "seed 5 gave the layer of seed 4";
  const std::string same_seed = dir / "layer_c";
  result = RunThinslab(LayerArgs(same_seed, 4));
  ASSERT_EQ(result.exit_code, 0) << result.output;
  Image layer_c;
  ASSERT_TRUE(ReadExr(same_seed + "/layer.exr", &layer_c).ok());
  EXPECT_EQ(layer_c.data(), layer.data());
}

// The whole loop of Gu Sec. 5.3 through the binary: a simulated shadow-map capture, `fit tau`,
// `synth add-prototype` of the fitted map into a new library, `synth list`, `synth layer` from
// that library, and `synth preview` of the layer, whose Fig. 8 contrasts reverse between the
// daylight window (darker against the sky) and the night window (brighter).
TEST(CliSynthTest, AFittedTauMapBecomesAPrototypeThatSynthesizesAndPreviews) {
  TempDir dir;
  ASSERT_EQ(RunThinslab("sim pattern " + dir / "pattern.exr" + " --width-px 40 --height-px 40").exit_code, 0);
  RunResult result = RunThinslab("sim shadow-maps " + dir / "capture" + " --tau " + dir / "pattern.exr" +
                                 " --camera-width-px 320 --camera-height-px 240 --photons 20000 --frames 2"
                                 " --dark-frames 1");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  result = RunThinslab("fit tau " + dir / "capture");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const std::string fit = dir / "capture/fit/tau";
  const std::string library = dir / "library";
  const std::string add = "synth add-prototype " + library + " --fit-tau " + fit + " --name measured_dust --category dust";
  result = RunThinslab(add);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("added prototype measured_dust (dust, 40x40 px"), std::string::npos) << result.output;
  // The prototype is the fitted map with the noise floor (0.02) cleaned to exactly 0.
  Image fitted, prototype;
  ASSERT_TRUE(ReadExr(fit + "/tau.exr", &fitted).ok());
  ASSERT_TRUE(ReadExr(library + "/measured_dust/tau.exr", &prototype).ok());
  ASSERT_EQ(prototype.width(), fitted.width());
  ASSERT_EQ(prototype.height(), fitted.height());
  const int fitted_tau = fitted.ChannelIndex("tau"), status = fitted.ChannelIndex("status");
  ASSERT_GE(fitted_tau, 0);
  ASSERT_GE(status, 0);
  int compared = 0;
  for (int y = 0; y < fitted.height(); ++y) {
    for (int x = 0; x < fitted.width(); ++x) {
      if (fitted.at(x, y, status) != 0) continue;
      const float tau = fitted.at(x, y, fitted_tau);
      EXPECT_FLOAT_EQ(prototype.at(x, y, 0), tau < 0.02f ? 0.0f : tau) << x << "," << y;
      ++compared;
    }
  }
  EXPECT_GT(compared, fitted.width() * fitted.height() / 2);
  // Adding it again is refused unless --overwrite.
  result = RunThinslab(add);
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.output.find("already exists"), std::string::npos) << result.output;
  result = RunThinslab("synth list " + library);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_EQ(result.output.rfind("measured_dust  dust  40x40 px", 0), 0u) << result.output;

  const std::string out = dir / "layer";
  result = RunThinslab("synth layer " + out + " --library " + library +
                       " --prototypes measured_dust --width 96 --height 64 --seed 3 --preview false");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  Image layer;
  ASSERT_TRUE(ReadExr(out + "/layer.exr", &layer).ok());
  EXPECT_EQ(layer.width(), 96);
  EXPECT_EQ(layer.height(), 64);
  EXPECT_EQ(layer.attributes()["prototypes"], "measured_dust");
  EXPECT_FALSE(fs::exists(out + "/pane_preview.png")) << "--preview false";
  result = RunThinslab("synth preview " + out + "/layer.exr --out " + dir / "pane.png --max-size-px 64");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_GT(PngSize(dir / "pane.png").first, 0u);
  const auto panes = nlohmann::json::parse(Bytes(dir / "pane.json"), nullptr, false);
  ASSERT_FALSE(panes.is_discarded());
  ASSERT_EQ(panes["scenes"].size(), 3u);
  ASSERT_EQ(panes["scenes"][0]["scene"], "daylight_window");
  ASSERT_EQ(panes["scenes"][1]["scene"], "night_window");
  // Measured 0.65 and 1.61 (dust: g 0.65, albedo 0.5, the category defaults).
  EXPECT_LT(panes["scenes"][0]["contrast_bright_background"].get<double>(), 0.9);
  EXPECT_GT(panes["scenes"][1]["contrast_bright_background"].get<double>(), 1.1);
  // A layer file that is not a contamination layer is refused by name.
  result = RunThinslab("synth preview " + fit + "/tau.exr --out " + dir / "bad.png");
  EXPECT_NE(result.exit_code, 0);
  EXPECT_EQ(CountLines(result.output), 1) << result.output;
  EXPECT_NE(result.output.find(fit + "/tau.exr"), std::string::npos) << result.output;
  EXPECT_FALSE(fs::exists(dir / "bad.png"));
}

TEST(CliSynthTest, BadInputFailsWithOneLineNamingTheOptionOrFileAndWritesNothing) {
  TempDir dir;
  const std::string out = dir / "out";
  const std::string size = " --width 64 --height 48 --preview false";
  ExpectLayerFails("synth layer " + out + " --prototypes dust_specks_a,no_such_thing" + size, out,
                   {"--prototypes", "'no_such_thing' is not in the library", "dust_specks_a"});
  ExpectLayerFails("synth layer " + out + " " + kLayers + " --width 0 --height 48", out, {"--width 0", "impossible"});
  ExpectLayerFails("synth layer " + out + " " + kLayers + " --width 64 --height 100000", out,
                   {"--height 100000", "impossible"});
  ExpectLayerFails("synth layer " + out + " " + kLayers + " --width 10000 --height 10000", out,
                   {"--width 10000 --height 10000", "2^26"});
  ExpectLayerFails("synth layer " + out + " " + kLayers + " --width 64 --height 48 --preview-px 2", out,
                   {"--preview-px 2"});
  ExpectLayerFails("synth layer " + out + size, out, {"--spec", "--prototypes"});
  // Spec files: absent, not JSON, wrong format, an impossible size, an unknown prototype.
  const std::string missing = dir / "missing.json";
  ExpectLayerFails("synth layer " + out + " --spec " + missing, out, {missing, "not found"});
  auto spec = [&](const std::string& name, const std::string& text) {
    const std::string path = dir / name;
    EXPECT_TRUE(WriteFileAtomically(path, text).ok());
    return path;
  };
  const std::string garbage = spec("garbage.json", "{\"format\": ");
  ExpectLayerFails("synth layer " + out + " --spec " + garbage, out, {garbage, "not a JSON object"});
  const std::string header = R"({"format": "thinslab-synth-spec", "format_version": "1.0", )";
  const std::string wrong_format = spec("wrong_format.json", R"({"format": "thinslab-synth", "layers": []})");
  ExpectLayerFails("synth layer " + out + " --spec " + wrong_format, out, {wrong_format, "'format'"});
  const std::string zero_size =
      spec("zero.json", header + R"("width_px": 0, "layers": [{"prototype": "dust_specks_a"}]})");
  ExpectLayerFails("synth layer " + out + " --spec " + zero_size, out, {zero_size, "'width_px' = 0", "impossible"});
  const std::string unknown =
      spec("unknown.json", header + R"("width_px": 64, "height_px": 48, "layers": [{"prototype": "nope"}]})");
  ExpectLayerFails("synth layer " + out + " --spec " + unknown + " --preview false", out,
                   {unknown, "'nope' is not in the library"});
  const std::string bad_layer = spec("bad_layer.json", header + R"("layers": [{"prototype": 3}]})");
  ExpectLayerFails("synth layer " + out + " --spec " + bad_layer, out, {bad_layer, "layers[0].prototype"});

  // A failed run leaves an earlier output of the same folder as it was.
  ASSERT_EQ(RunThinslab("synth layer " + out + " " + kLayers + size).exit_code, 0);
  const std::string before = Bytes(out + "/layer.exr");
  const RunResult failed = RunThinslab("synth layer " + out + " --prototypes nope" + size);
  EXPECT_NE(failed.exit_code, 0);
  EXPECT_TRUE(Bytes(out + "/layer.exr") == before);
  EXPECT_FALSE(fs::exists(out + "/pane_preview.png")) << "--preview false wrote a pane preview";
}

}  // namespace
}  // namespace thinslab
