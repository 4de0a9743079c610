// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/cost_functions/shadow_attenuation_cost.h"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

namespace thinslab {
namespace {

TEST(ShadowAttenuationCost, ZeroAtTrueTauAndGradientMatchesFiniteDifferences) {
  const double tau_true = 0.7;
  const double ratio = std::exp(-tau_true);
  std::unique_ptr<ceres::CostFunction> cost(ShadowAttenuationCost::Create(&ratio, 0.01));
  double tau = tau_true;
  double* params[] = {&tau};
  double residual = 1;
  ASSERT_TRUE(cost->Evaluate(params, &residual, nullptr));
  EXPECT_NEAR(residual, 0.0, 1e-12);

  tau = 0.3;
  ceres::NumericDiffOptions numeric_options;
  const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
  ceres::GradientChecker checker(cost.get(), no_manifolds, numeric_options);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params, 1e-7, &results)) << results.error_log;
}

TEST(TauSmoothnessCost, ResidualIsScaledDifference) {
  std::unique_ptr<ceres::CostFunction> cost(TauSmoothnessCost::Create(0.05));
  double a = 0.4, b = 0.3;
  double* params[] = {&a, &b};
  double residual = 0;
  ASSERT_TRUE(cost->Evaluate(params, &residual, nullptr));
  EXPECT_NEAR(residual, 2.0, 1e-12);
}

}  // namespace
}  // namespace thinslab
