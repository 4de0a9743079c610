// SPDX-License-Identifier: Apache-2.0
// `thinslab acquire dot-scan --exposures-us auto` (issue #28, item 2) on the simulated rig with
// the sample in the light path: the probe's plan and its reasons go into the manifest, its
// shortest exposure keeps the brightest state (the all-dots frame) unsaturated where a fixed
// bracket that starts too long does not, and a resumed run takes the plan of the run it continues.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <set>

#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/session_recovery.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

bool Has(const std::string& text, const std::string& piece) { return text.find(piece) != std::string::npos; }

constexpr char kScan[] =
    "acquire dot-scan --quiet --grid-nx 4 --grid-ny 4 --camera-width-px 96 --camera-height-px 72 --sim-sample"
    " --sim-photons-k 10 --seed 5 --max-exposure-us 9411765 ";

TEST(CliExposurePlan, TheProbesPlanIsInTheManifestAndKeepsTheBrightestStateUnsaturated) {
  TempDir dir;
  // A fixed bracket starting at 40 refresh periods saturates the all-dots frame.
  RunResult r = RunThinslab(std::string(kScan) + "--exposures-us 470588,9411765 " + dir / "fixed");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [saturation]: 'all_dots, none'")) << r.output;

  r = RunThinslab(std::string(kScan) + "--exposures-us auto " + dir / "planned");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "exposure plan: planned-exposures-us = ")) << r.output;
  EXPECT_FALSE(Has(r.output, "[saturation]")) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: good") || Has(r.output, "verdict: usable")) << r.output;
  Session session;
  ASSERT_TRUE(ReadSession(dir / "planned", &session).ok());
  const std::string& plan = session.acquisition.plan;
  EXPECT_TRUE(Has(plan, "exposures-us = auto")) << plan;
  EXPECT_TRUE(Has(plan, "planned-exposures-us = ")) << plan;
  EXPECT_TRUE(Has(plan, "exposure-plan = shortest ")) << plan;
  EXPECT_TRUE(Has(plan, "the all-dots frame without the sample peaks at")) << plan;
  // The frames have the planned exposures, whole refresh periods of the 85 Hz display, the
  // shortest one period or more, the longest within the cap.
  std::set<double> exposures;
  for (const FrameRecord& f : session.frames) exposures.insert(f.exposure_time_us);
  ASSERT_GE(exposures.size(), 2u);
  // (The simulated camera applies whole microseconds.)
  for (double t : exposures) EXPECT_NEAR(t, std::round(t * 85e-6) / 85e-6, 1.0) << t;
  EXPECT_LE(*exposures.rbegin(), 9411765 * (1 + 1e-9));
  EXPECT_LT(*exposures.begin(), 470588);

  // A resume of the planned run takes its plan (no second probe, which could plan otherwise).
  r = RunThinslab(std::string(kScan) + "--exposures-us auto --resume " + dir / "planned");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "already complete")) << r.output;
  r = RunThinslab(std::string(kScan) + "--exposures-us auto --resume " + dir / "fixed");
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "not planned with --exposures-us auto")) << r.output;
}

// The test of the plan (#28, item 2): on the simulated display whose black glows (0.2 %
// of full light at drive 0), the planned session fits about as many points right as a fixed
// bracket on a black display; the same fixed bracket on the glowing display does not. What the
// plan adds there is frames at the longest exposure (the glow's shot noise falls as 1/sqrt(N));
// a longer exposure would saturate the glow. 10 x 10 dots of the nine-region sample, a 4 mm map
// with every other dot held out, seed 5 (docs/acquisition.md, "Exposure planning").
// Summed over the regions of comparison.json: "ok" (status ok or interpolated) or "correct".
int CountPoints(const std::string& capture, const std::string& key) {
  std::ifstream in(fs::path(capture) / "fit" / "dmf" / "comparison.json");
  const nlohmann::json comparison = nlohmann::json::parse(in);
  int count = 0;
  for (const nlohmann::json& region : comparison.at("regions")) count += region.value(key, 0);
  return count;
}

// A glowing display's scans fitted at a 4 mm map with every other dot held out: the counts of
// points with status ok and of correct points.
struct GlowScanCounts {
  int ok = 0, correct = 0;
};
GlowScanCounts AcquireAndFit(const std::string& scan, const std::string& options, const std::string& capture) {
  RunResult r = RunThinslab(scan + options + " " + capture);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = RunThinslab("fit dmf --quiet --pitch-mm 4 --hold-out true " + capture);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return {CountPoints(capture, "ok"), CountPoints(capture, "correct")};
}

TEST(CliExposurePlanGlow, PlannedFramesFitAsManyPointsAsABlackDisplay) {
  TempDir dir;
  const std::string scan =
      "acquire dot-scan --quiet --sim-sample true --sim-photons-k 100 --camera-width-px 240 --camera-height-px 180 "
      "--grid-nx 10 --grid-ny 10 --sim-display-transfer linear --seed 5 ";
  auto acquire_and_fit = [&](const std::string& name, const std::string& options) {
    return AcquireAndFit(scan, options, dir / name).correct;
  };
  const int black = acquire_and_fit("black", "--exposures-us 11765,9411765 --sim-display-black 0");
  const int glow_fixed = acquire_and_fit("glow_fixed", "--exposures-us 11765,9411765");
  const int glow_planned = acquire_and_fit("glow_planned", "--exposures-us auto --max-exposure-us 9411765");
  // Measured 2026-12-07: black 101, glow fixed 81, glow planned 113 (4 frames at 9.4 s).
  std::cout << "correct points: black " << black << ", glow fixed " << glow_fixed << ", glow planned " << glow_planned
            << "\n";
  EXPECT_GE(glow_planned, 0.9 * black) << "black " << black << ", glow fixed " << glow_fixed;
  EXPECT_GE(glow_planned, 1.1 * glow_fixed) << "black " << black << ", glow fixed " << glow_fixed;
  Session session;
  ASSERT_TRUE(ReadSession(dir / "glow_planned", &session).ok());
  EXPECT_TRUE(Has(session.acquisition.plan, "planned-longest-exposure-frames = 4")) << session.acquisition.plan;
  EXPECT_TRUE(Has(session.acquisition.plan, "frames there, averaged")) << session.acquisition.plan;
  // A resume takes the planned frames, and the plan and a fixed count are not both accepted.
  RunResult r = RunThinslab(scan + "--exposures-us auto --max-exposure-us 9411765 --resume " + dir / "glow_planned");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "already complete")) << r.output;
  r = RunThinslab(scan + "--exposures-us auto --longest-exposure-frames 2 " + dir / "both");
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "--longest-exposure-frames")) << r.output;
}

// The goal counts points fitted with status ok. At 10 x 10 dots (above) it is not met:
// that density is the dot-scan fit's sparse boundary (docs/stability.md, "Sparse lights"),
// where the measured-fraction flag (status 7) sits inside one continuum of right points and the
// glow's 0.02-0.04 lower fractions move some across it. At 20 x 20 dots over the same monitor
// the planned scan on the glowing display fits as many points with status ok as the fixed
// bracket on the black display, and as many right; the fixed bracket on the glowing display
// fewer. Measured 2026-12-07 over seeds 5-8 (docs/acquisition.md): ok 150.0 black, 150.5 planned,
// 142.0 glow fixed (planned / black 0.993-1.020 per seed); correct 154.0, 154.25, 149.25.
TEST(CliExposurePlanGlow, PlannedFramesFitAsManyPointsOkAsABlackDisplayAt20x20Dots) {
  TempDir dir;
  const std::string scan =
      "acquire dot-scan --quiet --sim-sample true --sim-photons-k 100 --camera-width-px 240 --camera-height-px 180 "
      "--grid-nx 20 --grid-ny 20 --sim-display-transfer linear --seed 5 ";
  const GlowScanCounts black = AcquireAndFit(scan, "--exposures-us 11765,9411765 --sim-display-black 0", dir / "black");
  const GlowScanCounts fixed = AcquireAndFit(scan, "--exposures-us 11765,9411765", dir / "glow_fixed");
  const GlowScanCounts planned =
      AcquireAndFit(scan, "--exposures-us auto --max-exposure-us 9411765", dir / "glow_planned");
  // Seed 5, 2026-12-07: ok 150 / 137 / 150, correct 154 / 147 / 154.
  std::cout << "ok points: black " << black.ok << ", glow fixed " << fixed.ok << ", glow planned " << planned.ok
            << "; correct: " << black.correct << ", " << fixed.correct << ", " << planned.correct << "\n";
  EXPECT_GE(planned.ok, 0.98 * black.ok);
  EXPECT_GE(planned.correct, 0.95 * black.correct);
  EXPECT_GT(planned.ok, fixed.ok);
}

// `acquire laser --exposures-us auto`: a laser 30x brighter than the one the fixed bracket was
// made for saturates its spot in the fixed bracket's shortest exposure; the planned bracket
// keeps it unsaturated, measures the lobe's ring at 60 degrees in its longest, plans the flat
// field apart, and fits g (true 0.8) within the fit's own error bar. A resume takes the plan.
TEST(CliExposurePlan, TheLaserPlanKeepsTheSpotUnsaturatedAndMeasuresTheRing) {
  TempDir dir;
  const std::string laser =
      "acquire laser --quiet --camera sim --camera-width-px 200 --camera-height-px 150 --sim-laser-power 30 ";
  RunResult r = RunThinslab(laser + dir / "fixed");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [saturation]: 'laser, clean'")) << r.output;

  r = RunThinslab(laser + "--exposures-us auto " + dir / "planned");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(Has(r.output, "[saturation]")) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: good")) << r.output;
  Session session;
  ASSERT_TRUE(ReadSession(dir / "planned", &session).ok());
  const std::string& plan = session.acquisition.plan;
  EXPECT_TRUE(Has(plan, "planned-exposures-us = ")) << plan;
  EXPECT_TRUE(Has(plan, "planned-flat-exposures-us = ")) << plan;
  EXPECT_TRUE(Has(plan, "the lobe's ring at 60 degrees")) << plan;
  std::set<double> laser_exposures, flat_exposures;
  for (const FrameRecord& f : session.frames)
    (f.kind == "flat" ? flat_exposures : laser_exposures).insert(f.exposure_time_us);
  ASSERT_GE(laser_exposures.size(), 2u);
  EXPECT_LT(*laser_exposures.begin(), 20);  // Shorter than the fixed bracket's 20 us.
  EXPECT_EQ(flat_exposures.size(), 1u);

  r = RunThinslab("fit phase --quiet " + dir / "planned");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(fs::path(dir / "planned") / "fit" / "phase" / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  const double g = summary.at("g"), sigma_g = summary.at("sigma_g");
  EXPECT_LT(std::abs(g - 0.8), std::max(3 * sigma_g, 0.01)) << g << " +- " << sigma_g;

  r = RunThinslab(laser + "--exposures-us auto --resume " + dir / "planned");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "already complete")) << r.output;
}

// `acquire shadow-maps --exposure-us auto`: on a rig whose light saturates the fixed 20 ms
// exposure (the clean board at 1.6x the full well), the probe's exposure keeps the flat field
// below the range and `fit tau` maps the whole region; the fixed exposure is refused by both.
TEST(CliExposurePlan, TheShadowMapPlanKeepsTheFlatFieldInRange) {
  TempDir dir;
  const std::string shadow =
      "acquire shadow-maps --quiet --camera sim --camera-width-px 160 --camera-height-px 120 --reference-fill 1.6 ";
  RunResult r = RunThinslab(shadow + dir / "fixed");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "retake [saturation]: 'reference, clean'")) << r.output;
  r = RunThinslab("fit tau --quiet " + dir / "fixed");
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_TRUE(Has(r.output, "saturated")) << r.output;

  r = RunThinslab(shadow + "--exposure-us auto " + dir / "planned");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(Has(r.output, "[saturation]")) << r.output;
  EXPECT_TRUE(Has(r.output, "verdict: good")) << r.output;
  Session session;
  ASSERT_TRUE(ReadSession(dir / "planned", &session).ok());
  EXPECT_TRUE(Has(session.acquisition.plan, "exposure-plan = exposure ")) << session.acquisition.plan;
  std::set<double> exposures;
  for (const FrameRecord& f : session.frames) exposures.insert(f.exposure_time_us);
  ASSERT_EQ(exposures.size(), 1u);
  // 80 % of the range where 20 ms filled 1.6x the full well at the image centre.
  EXPECT_LT(*exposures.begin(), 20000 * 0.8 / 1.6 * 1.1);
  EXPECT_GT(*exposures.begin(), 20000 * 0.8 / 1.6 * 0.5);
  r = RunThinslab("fit tau --quiet " + dir / "planned");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(fs::path(dir / "planned") / "fit" / "tau" / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  EXPECT_EQ(summary.at("pixels").at("saturated"), 0) << summary.dump();
  EXPECT_GT(summary.at("pixels").at("fitted").get<double>(), 0.95 * summary.at("pixels").at("total").get<double>());
}

}  // namespace
}  // namespace thinslab
