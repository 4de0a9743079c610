// SPDX-License-Identifier: Apache-2.0
// System test: simulate a shadow-map capture (Monte Carlo layer with all scattering orders,
// perspective camera, vignetting, projector falloff, shot/read noise, 12-bit quantisation),
// run the unchanged calibration and fit stages, compare with ground truth.
#include <gtest/gtest.h>

#include <cstdio>

#include "thinslab/app/commands.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/manifest_io.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

struct Case {
  double board_distance_mm;
};

class DirtyGlassTauTest : public ::testing::TestWithParam<Case> {};

// Defaults of the simulated rig: albedo 0.3, g 0.8, 4 frames per state.
TEST_P(DirtyGlassTauTest, RefinementMeetsAccuracyAndBeatsPlainEq7) {
  TempDir dir;
  SyntheticShadowSessionOptions sim;
  sim.rig.board_distance_m = GetParam().board_distance_mm * 1e-3;
  Image tau;
  ASSERT_TRUE(LoadOrGenerateTau("", sim.rig.seed, &tau).ok());
  const std::string session = dir / "session";
  const Status synth = SynthesizeShadowMapSession(sim, tau, session);
  ASSERT_TRUE(synth.ok()) << synth.message();

  FitTauRun run;
  run.fit.layer_albedo = sim.rig.layer_albedo;
  run.fit.layer_g = sim.rig.layer_g;
  TauFitSummary summary;
  TauComparison cmp;
  bool has_truth = false;
  const Status fit = FitTauPipeline(session, dir / "fit", run, &summary, &cmp, &has_truth);
  ASSERT_TRUE(fit.ok()) << fit.message();
  ASSERT_TRUE(has_truth);
  std::printf("board %.0f mm: plain Eq. 7 RMS rel %.2f %% (bias %+.2f %%), refined RMS rel %.2f %% (bias %+.2f %%), "
              "%lld px\n",
              GetParam().board_distance_mm, 100 * cmp.plain.rms_relative, 100 * cmp.plain.mean_relative_bias,
              100 * cmp.refined.rms_relative, 100 * cmp.refined.mean_relative_bias,
              static_cast<long long>(cmp.refined.pixels));
  ASSERT_GT(cmp.refined.pixels, 5000);
  // The plain estimate reads low: forward-scattered light lands near the unscattered light.
  EXPECT_LT(cmp.plain.mean_relative_bias, -0.03);
  const double max_rms_relative_error = 0.03;
  EXPECT_LE(cmp.refined.rms_relative, max_rms_relative_error);
  const double min_error_reduction = 3.0;
  EXPECT_GE(cmp.plain.rms_relative / cmp.refined.rms_relative, min_error_reduction);
  EXPECT_EQ(summary.pixels_dark + summary.pixels_saturated + summary.pixels_outside, 0);

  // The Ceres variant with the edge-preserving smoothness prior meets the same tolerance.
  FitTauRun with_prior = run;
  with_prior.fit.smoothness_sigma_tau = 0.1;
  TauComparison cmp_prior;
  ASSERT_TRUE(FitTauPipeline(session, dir / "fit_prior", with_prior, &summary, &cmp_prior, &has_truth).ok());
  std::printf("board %.0f mm, smoothness prior 0.1: refined RMS rel %.2f %%\n", GetParam().board_distance_mm,
              100 * cmp_prior.refined.rms_relative);
  EXPECT_LE(cmp_prior.refined.rms_relative, max_rms_relative_error);

  // The written map carries the documented channels and provenance.
  Image written;
  ASSERT_TRUE(ReadExr(dir / "fit/tau.exr", &written).ok());
  EXPECT_GE(written.ChannelIndex("tau"), 0);
  EXPECT_GE(written.ChannelIndex("status"), 0);
  EXPECT_EQ(written.attributes().count("options_digest"), 1u);
  EXPECT_EQ(written.attributes()["format_version"], kOutputFormatVersion);
  EXPECT_EQ(written.attributes()["primary_channel"], "tau");
  // The camera pose as OpenEXR's worldToCamera: the capture's own cam_from_sample.
  Session capture;
  ASSERT_TRUE(ReadSession(session, &capture).ok());
  Rigid3d pose;
  ASSERT_TRUE(GetWorldToCamera(written, &pose));
  EXPECT_LT((pose.translation - capture.rig.cameras[0].cam_from_sample.translation).norm(), 1e-6);
  EXPECT_GT(std::abs(pose.rotation.dot(capture.rig.cameras[0].cam_from_sample.rotation)), 1 - 1e-6);
}

INSTANTIATE_TEST_SUITE_P(BoardDistances, DirtyGlassTauTest, ::testing::Values(Case{1.0}, Case{10.0}),
                         [](const auto& param_info) {
                           return "board_" + std::to_string(static_cast<int>(param_info.param.board_distance_mm)) +
                                  "mm";
                         });

}  // namespace
}  // namespace thinslab
