// SPDX-License-Identifier: Apache-2.0
// `thinslab check` (issue #28, item 3) on simulated captures, good and with the faults an operator
// must hear about before the sample leaves the rig: a frame where the sample moved, a frame where
// the light flickered, a saturated and an underexposed capture, a laser beam away from where the
// manifest puts it. The faults are made by editing a good capture's frames and manifest, so each
// test shows the check reacts to exactly that fault.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/frame_io.h"
#include "thinslab/core/session_io.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

constexpr int kRetake = 3;  // `thinslab check`'s exit status for the verdict "retake".

bool Has(const std::string& text, const std::string& piece) { return text.find(piece) != std::string::npos; }

// Rewrites frame `index` of `capture` through `edit` (raw DN with the black level).
template <typename Edit>
void EditFrame(const std::string& capture, int index, Edit edit) {
  Session session;
  ASSERT_TRUE(ReadSession(capture, &session).ok());
  const FrameRecord& frame = session.frames.at(index);
  const CameraInfo& camera = *session.FindCamera(frame.camera_id);
  Image image;
  ASSERT_TRUE(LoadFrame(capture, session, frame, &image).ok());
  Image edited = image;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x)
      edited.at(x, y) = static_cast<float>(edit(image, x, y) + camera.black_level_dn);
  }
  ASSERT_TRUE(WriteRawFrame((fs::path(capture) / frame.file).string(), edited, camera.bit_depth).ok());
}

// The index of the second frame of `kind` (the first has a neighbour before it in its state).
int SecondFrameOf(const std::string& capture, const std::string& kind) {
  Session session;
  EXPECT_TRUE(ReadSession(capture, &session).ok());
  int seen = 0;
  for (const FrameRecord& f : session.frames) {
    if (f.kind == kind && ++seen == 2) return f.index;
  }
  ADD_FAILURE() << "no second '" << kind << "' frame in " << capture;
  return 0;
}

class CliCheckTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    const RunResult pattern = RunThinslab("sim pattern " + *dir_ / "tau.exr" + " --width-px 32 --height-px 32");
    ASSERT_EQ(pattern.exit_code, 0) << pattern.output;
    const RunResult shadow = RunThinslab(ShadowArgs(*dir_ / "shadow", ""));
    ASSERT_EQ(shadow.exit_code, 0) << shadow.output;
  }
  static void TearDownTestSuite() { delete dir_; }

  static std::string ShadowArgs(const std::string& out, const std::string& extra) {
    return "sim shadow-maps " + out + " --tau " + *dir_ / "tau.exr" +
           " --camera-width-px 128 --camera-height-px 96 --photons 2000 --frames 3 --dark-frames 2 " + extra;
  }
  // A copy of the good shadow-map capture to break.
  static std::string CopyOfShadow(const std::string& name) {
    const std::string copy = *dir_ / name;
    fs::copy(*dir_ / "shadow", copy, fs::copy_options::recursive);
    return copy;
  }

  static TempDir* dir_;
};
TempDir* CliCheckTest::dir_ = nullptr;

TEST_F(CliCheckTest, AGoodShadowMapCaptureIsGood) {
  const std::string json = *dir_ / "shadow/calib/check.json";
  const RunResult r = RunThinslab("check " + *dir_ / "shadow" + " --json " + json);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: good")) << r.output;
  std::ifstream in(json);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("format"), "thinslab-capture-check");
  EXPECT_EQ(j.at("verdict"), "good");
  // Repeats of the shadow and reference states were compared.
  int pairs = 0;
  for (const auto& kind : j.at("kinds")) pairs += kind.at("frame_pairs").get<int>();
  EXPECT_GE(pairs, 4) << r.output;
}

TEST_F(CliCheckTest, AFrameWhereTheSampleMovedIsARetake) {
  const std::string capture = CopyOfShadow("moved");
  const int frame = SecondFrameOf(capture, "shadow");
  EditFrame(capture, frame, [](const Image& image, int x, int y) {  // Two pixels to the right.
    return image.at(std::max(0, x - 2), y);
  });
  const RunResult r = RunThinslab("check " + capture);
  EXPECT_EQ(r.exit_code, kRetake) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [moved]")) << r.output;
  EXPECT_TRUE(Has(r.output, "frames " + std::to_string(frame - 1) + " and " + std::to_string(frame))) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: retake")) << r.output;
}

TEST_F(CliCheckTest, AFrameWhereTheLightFlickeredIsARetake) {
  const std::string capture = CopyOfShadow("flicker");
  const int frame = SecondFrameOf(capture, "reference");
  EditFrame(capture, frame, [](const Image& image, int x, int y) { return 1.08 * image.at(x, y); });
  const RunResult r = RunThinslab("check " + capture);
  EXPECT_EQ(r.exit_code, kRetake) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [flicker]")) << r.output;
  EXPECT_FALSE(Has(r.output, "[moved]")) << "a brightness change is not motion:\n" << r.output;
}

TEST_F(CliCheckTest, SaturationAndUnderexposureAreRetakes) {
  const RunResult bright = RunThinslab(ShadowArgs(*dir_ / "bright", "--reference-fill 1.5 --frames 1"));
  ASSERT_EQ(bright.exit_code, 0) << bright.output;
  RunResult r = RunThinslab("check " + *dir_ / "bright");
  EXPECT_EQ(r.exit_code, kRetake) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [saturation]: 'reference, clean'")) << r.output;

  const RunResult dim = RunThinslab(ShadowArgs(*dir_ / "dim", "--reference-fill 0.0005 --frames 1"));
  ASSERT_EQ(dim.exit_code, 0) << dim.output;
  // A hot pixel, saturated in every frame and dark: it neither saturates nor lights a state.
  Session session;
  ASSERT_TRUE(ReadSession(*dir_ / "dim", &session).ok());
  for (const FrameRecord& f : session.frames) {
    EditFrame(*dir_ / "dim", f.index,
              [](const Image& image, int x, int y) { return x == 5 && y == 5 ? 1e6 : image.at(x, y); });
  }
  r = RunThinslab("check " + *dir_ / "dim");
  EXPECT_EQ(r.exit_code, kRetake) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [exposure]: 'reference, clean'")) << r.output;
  EXPECT_FALSE(Has(r.output, "[saturation]")) << r.output;
}

// The laser capture is good as simulated. With the manifest's beam moved 4 mm the spot is not
// where the manifest says (a warning: `fit phase` finds the spot itself); with the manifest's
// region moved off the spot, the fit could not use it (a re-take).
TEST_F(CliCheckTest, ALaserSpotAwayFromTheManifestsBeamOrRegionIsFound) {
  const std::string capture = *dir_ / "laser";
  const RunResult sim =
      RunThinslab("sim laser " + capture + " --camera-width-px 96 --camera-height-px 72 --photons 20000");
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  RunResult r = RunThinslab("check " + capture);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: good")) << r.output;

  const fs::path manifest_path = fs::path(capture) / "session.json";
  nlohmann::json manifest;
  {
    std::ifstream in(manifest_path);
    manifest = nlohmann::json::parse(in);
  }
  const nlohmann::json good = manifest;
  auto& origin = manifest.at("rig").at("laser").at("origin_in_sample");
  origin[0] = origin[0].get<double>() + 4e-3;
  std::ofstream(manifest_path) << manifest.dump(2);
  r = RunThinslab("check " + capture);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "warning [beam]")) << r.output;
  EXPECT_TRUE(Has(r.output, "4.0")) << "the offset in mm:\n" << r.output;

  manifest = good;
  manifest["rig"]["sample"]["region_min_m"] = {0.01, 0.01};
  std::ofstream(manifest_path) << manifest.dump(2);
  r = RunThinslab("check " + capture);
  EXPECT_EQ(r.exit_code, kRetake) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [beam]")) << r.output;
  EXPECT_TRUE(Has(r.output, "outside the region the fit uses")) << r.output;
}

// The manifest's sample region moved off the camera's view: the board the fit would rectify is
// not in the frames.
TEST_F(CliCheckTest, ABoardRegionOutOfViewIsARetake) {
  const std::string capture = CopyOfShadow("off_board");
  const fs::path manifest_path = fs::path(capture) / "session.json";
  nlohmann::json manifest;
  {
    std::ifstream in(manifest_path);
    manifest = nlohmann::json::parse(in);
  }
  manifest["rig"]["sample"]["region_min_m"] = {0.02, 0.02};
  manifest["rig"]["sample"]["region_max_m"] = {0.03, 0.03};
  std::ofstream(manifest_path) << manifest.dump(2);
  const RunResult r = RunThinslab("check " + capture);
  EXPECT_EQ(r.exit_code, kRetake) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [board]")) << r.output;
}

// The simulated display's default black level (0.2 % of full light) seen through the sample fills
// ~62 % of the range at the 9.4 s exposure (docs/known_gaps.md): the acquisition's own check
// says so; with a black display it does not.
TEST_F(CliCheckTest, AcquireChecksTheDotScanAndWarnsOfTheDisplaysBlackGlow) {
  const std::string args =
      "acquire dot-scan --quiet --grid-nx 4 --grid-ny 4 --camera-width-px 96 --camera-height-px 72"
      " --exposures-us 11765,9411765 --sim-sample --sim-photons-k 10 --seed 5 ";
  RunResult r = RunThinslab(args + *dir_ / "glow");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "warning [dark]: the dark frame at 9.412 s fills")) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: usable")) << r.output;
  EXPECT_TRUE(Has(r.output, "of the 16 dots in view found in frames/cam0/all_dots/")) << r.output;
  r = RunThinslab(args + "--sim-display-black 0 " + *dir_ / "black");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(Has(r.output, "[dark]")) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: good")) << r.output;
}

TEST_F(CliCheckTest, BadInputGetsAClearError) {
  RunResult r = RunThinslab("check " + *dir_ / "missing");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(Has(r.output, "missing")) << r.output;
  r = RunThinslab("check " + *dir_ / "shadow" + " --max-moved-fraction 2");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(Has(r.output, "max_moved_fraction")) << r.output;
  // The JSON report is an output: never inside the capture outside calib/ and fit/.
  r = RunThinslab("check " + *dir_ / "shadow" + " --json " + *dir_ / "shadow/session.json");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(fs::exists(*dir_ / "shadow/session.json"));
}

}  // namespace
}  // namespace thinslab
