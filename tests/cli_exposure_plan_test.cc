// SPDX-License-Identifier: Apache-2.0
// `thinslab acquire dot-scan --exposures-us auto` (issue #28, item 2) on the simulated rig with
// the sample in the light path: the probe's plan and its reasons go into the manifest, its
// shortest exposure keeps the brightest state (the all-dots frame) unsaturated where a fixed
// bracket that starts too long does not, and a resumed run takes the plan of the run it continues.
#include <gtest/gtest.h>

#include <filesystem>

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

}  // namespace
}  // namespace thinslab
