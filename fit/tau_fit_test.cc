// SPDX-License-Identifier: Apache-2.0
// Unit tests of FitTau on hand-made rectified data. Accuracy against a more complete forward
// model lives in tests/e2e_dirty_glass_test.cc; here: round trips, solver self-consistency,
// masks, and that no NaN escapes.
#include "thinslab/fit/tau_fit.h"

#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/shadow_map_model.h"

namespace thinslab {
namespace {

RectifiedShadowMaps MakeData(int w, int h) {
  RectifiedShadowMaps data;
  data.shadow = Image(w, h);
  data.reference = Image(w, h, 100.0f);
  data.shadow_variance = Image(w, h, 1e-4f);
  data.reference_variance = Image(w, h, 1e-4f);
  data.saturated = Image(w, h);
  data.outside = Image(w, h);
  data.pixel_pitch_m = 100e-6;
  data.board_distance_m = 1e-3;
  return data;
}

Image RingTau(int w, int h) {
  Image tau(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double r = std::hypot(x - w / 2.0, y - h / 2.0);
      tau.at(x, y) = static_cast<float>(r < w / 3.0 ? 0.6 + 0.5 * std::cos(r / 2.0) : 0.0);
    }
  }
  return tau;
}

// Gu Eq. 7 round trip: tau -> I = I_clean e^{-tau} -> tau.
TEST(FitTau, PlainEq7RoundTrip) {
  const int w = 32, h = 24;
  RectifiedShadowMaps data = MakeData(w, h);
  const Image tau = RingTau(w, h);
  for (size_t i = 0; i < tau.data().size(); ++i) data.shadow.data()[i] = 100.0f * std::exp(-tau.data()[i]);
  TauFitOptions options;
  options.refine_scattering = false;
  TauMaps maps;
  TauFitSummary summary;
  ASSERT_TRUE(FitTau(options, data, &maps, &summary).ok());
  EXPECT_TRUE(summary.IsUsable());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) EXPECT_NEAR(maps.tau.at(x, y, 0), tau.at(x, y), 1e-5);
  }
}

// Solver self-consistency: data made by the fit's own single-scattering model is inverted
// (checks the fixed point and the Ceres step, not physical accuracy).
TEST(FitTau, RefinementInvertsItsOwnForwardModel) {
  const int w = 40, h = 40;
  RectifiedShadowMaps data = MakeData(w, h);
  const Image tau = RingTau(w, h);
  const double albedo = 0.4, g = 0.7;
  BoardGeometry geometry;
  geometry.distance_m = data.board_distance_m;
  geometry.pixel_pitch_m = data.pixel_pitch_m;
  geometry.max_angle_deg = 80;
  geometry.max_radius_px = 60;
  const ScatterKernelBank bank(ScatterKernelBank::DefaultNodes(0.5), [&](double t, double mu) {
    if (t < 1e-9) return albedo * HenyeyGreenstein(mu, g) / mu;
    return LayerSingleScatterRadiance(t, mu, albedo, g) / t;
  }, geometry);
  const Image scattered = bank.Scattered(data.reference, tau);
  for (size_t i = 0; i < tau.data().size(); ++i) {
    data.shadow.data()[i] = 100.0f * std::exp(-tau.data()[i]) + scattered.data()[i];
  }
  for (double smoothness : {0.0, 0.1}) {
    TauFitOptions options;
    options.layer_albedo = albedo;
    options.layer_g = g;
    options.smoothness_sigma_tau = smoothness;
    TauMaps maps;
    TauFitSummary summary;
    ASSERT_TRUE(FitTau(options, data, &maps, &summary).ok());
    double max_err = 0, max_plain_err = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        max_err = std::max(max_err, static_cast<double>(std::abs(maps.tau.at(x, y, 0) - tau.at(x, y))));
        max_plain_err = std::max(max_plain_err, static_cast<double>(std::abs(maps.tau.at(x, y, 1) - tau.at(x, y))));
      }
    }
    EXPECT_LT(max_err, 0.01) << "smoothness " << smoothness;  // Node interpolation differs (0.5 vs 1 spacing).
    EXPECT_GT(max_plain_err, 0.05);
    EXPECT_LT(summary.final_max_update_tau, options.outer_tolerance_tau);
  }
}

TEST(FitTau, MasksAndNeverNaN) {
  const int w = 10, h = 10;
  RectifiedShadowMaps data = MakeData(w, h);
  for (auto& v : data.shadow.data()) v = 50.0f;
  data.outside.at(0, 0) = 1;
  data.saturated.at(1, 0) = 1;
  data.reference.at(2, 0) = 0.0f;   // Dark reference.
  data.shadow.at(3, 0) = -5.0f;     // Below the dark level.
  data.shadow.at(4, 0) = 1e-6f;     // Beyond tau_max.
  data.shadow_variance.at(3, 0) = 100.0f;
  data.shadow_variance.at(4, 0) = 1e-14f;  // Significantly above zero, below e^{-tau_max}.
  TauFitOptions options;
  TauMaps maps;
  TauFitSummary summary;
  ASSERT_TRUE(FitTau(options, data, &maps, &summary).ok());
  EXPECT_EQ(maps.tau.at(0, 0, 2), static_cast<float>(TauPixelStatus::kOutside));
  EXPECT_EQ(maps.tau.at(1, 0, 2), static_cast<float>(TauPixelStatus::kSaturated));
  EXPECT_EQ(maps.tau.at(2, 0, 2), static_cast<float>(TauPixelStatus::kDark));
  EXPECT_EQ(maps.tau.at(3, 0, 2), static_cast<float>(TauPixelStatus::kDark));
  EXPECT_EQ(maps.tau.at(4, 0, 2), static_cast<float>(TauPixelStatus::kClamped));
  EXPECT_EQ(maps.tau.at(4, 0, 0), static_cast<float>(options.tau_max));
  // The clamped pixel's measurable 8-neighbours are lower bounds only (status 5).
  for (const auto& [x, y] : {std::pair{5, 0}, {3, 1}, {4, 1}, {5, 1}}) {
    EXPECT_EQ(maps.tau.at(x, y, 2), static_cast<float>(TauPixelStatus::kNextToClamped)) << x << "," << y;
  }
  for (float v : maps.tau.data()) EXPECT_TRUE(std::isfinite(v));
  EXPECT_EQ(summary.pixels_outside, 1);
  EXPECT_EQ(summary.pixels_saturated, 1);
  EXPECT_EQ(summary.pixels_dark, 2);
  EXPECT_EQ(summary.pixels_clamped, 1);
  EXPECT_EQ(summary.pixels_next_to_clamped, 4);
  EXPECT_EQ(summary.pixels_fitted, 91);
}

// sigma_tau is the propagated frame noise (Gu Eq. 5: sigma_tau = sigma_m / e^{-tau} without
// scattered light), and a pixel whose noise exceeds max_sigma_tau is dark, not fitted.
TEST(FitTau, NoisyPixelsAreDarkWithTheirSigma) {
  const int w = 8, h = 8;
  RectifiedShadowMaps data = MakeData(w, h);
  for (auto& v : data.shadow.data()) v = 50.0f;
  data.shadow_variance.at(2, 2) = 100.0f;  // sigma_m = 0.1, sigma_tau = 0.2.
  TauFitOptions options;
  options.refine_scattering = false;
  TauMaps maps;
  TauFitSummary summary;
  ASSERT_TRUE(FitTau(options, data, &maps, &summary).ok());
  EXPECT_EQ(maps.tau.at(2, 2, 2), static_cast<float>(TauPixelStatus::kDark));
  EXPECT_EQ(summary.pixels_dark_noise, 1);
  // m = 0.5: var_m = (1e-4 + 0.25e-4) / 100^2, sigma_tau = sqrt(var_m) / 0.5.
  EXPECT_NEAR(maps.tau.at(0, 0, 3), std::sqrt(1.25e-4) / 100 / 0.5, 1e-6);
  options.max_sigma_tau = 0.5;
  ASSERT_TRUE(FitTau(options, data, &maps, &summary).ok());
  EXPECT_EQ(maps.tau.at(2, 2, 2), static_cast<float>(TauPixelStatus::kOk));
  EXPECT_NEAR(maps.tau.at(2, 2, 3), 0.2, 1e-3);
  options.max_sigma_tau = 0;
  EXPECT_FALSE(FitTau(options, data, &maps, &summary).ok());
}

// Auto reference: a quadratic illumination and half the pane clean.
TEST(FitTau, AutoReferenceFromCleanRegions) {
  const int w = 48, h = 40;
  RectifiedShadowMaps data = MakeData(w, h);
  data.reference = Image();
  Image tau(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double u = (x + 0.5) / w - 0.5, v = (y + 0.5) / h - 0.5;
      const double e0 = 100.0 * (1.0 - 0.3 * u * u - 0.2 * v * v + 0.1 * u);
      tau.at(x, y) = x > w / 2 ? static_cast<float>(0.3 + 0.2 * std::sin(y * 0.7)) : 0.0f;
      data.shadow.at(x, y) = static_cast<float>(e0 * std::exp(-tau.at(x, y)));
    }
  }
  TauFitOptions options;
  options.reference = "auto";
  options.refine_scattering = false;
  TauMaps maps;
  TauFitSummary summary;
  ASSERT_TRUE(FitTau(options, data, &maps, &summary).ok()) << summary.message;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) EXPECT_NEAR(maps.tau.at(x, y, 0), tau.at(x, y), 0.01);
  }
  options.reference = "frame";
  const Status missing = FitTau(options, data, &maps, &summary);
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("reference"), std::string::npos);
}

TEST(FitTau, OptionErrorsNameTheField) {
  RectifiedShadowMaps data = MakeData(4, 4);
  TauMaps maps;
  TauFitSummary summary;
  TauFitOptions options;
  options.layer_g = 1.0;
  Status status = FitTau(options, data, &maps, &summary);
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("TauFitOptions::layer_g"), std::string::npos);
  options = TauFitOptions();
  options.reference = "clean";
  status = FitTau(options, data, &maps, &summary);
  EXPECT_NE(status.message().find("TauFitOptions::reference"), std::string::npos);
  EXPECT_EQ(TauFitSummary().message, "FitTau was not called.");
}

}  // namespace
}  // namespace thinslab
