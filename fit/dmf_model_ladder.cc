// SPDX-License-Identifier: Apache-2.0
#include "fit/dmf_model_ladder.h"

#include "fit/ladder_choice.h"

#include <ceres/ceres.h>

#include <chrono>
#include <cmath>

#include "core/math.h"
#include "optics/dual_microfacet_btdf.h"
#include "optics/microfacet.h"

namespace thinslab {
namespace {

// The weight stays strictly inside (0, 1) where Eq. 11 is smooth.
constexpr double kMinWeight = 1e-3, kMaxWeight = 1 - 1e-3;

struct AnalyticDmfResidual {
  Eigen::Vector3d i, o;
  double log_value, eta;
  template <typename T>
  bool operator()(const T* log_alpha_ndf, const T* weight, const T* log_k, T* residual) const {
    using std::exp;
    using std::log;
    const GgxDistributionT<T> ggx(exp(log_alpha_ndf[0]));
    const DualMicrofacetBtdf<GgxDistributionT<T>> btdf(ggx, ggx, T(eta));
    const T rho = btdf.Eval(i.cast<T>(), o.cast<T>(), weight[0]);
    residual[0] = rho > T(0) ? T(log_value) - log_k[0] - log(rho) : T(10.0);
    return true;
  }
};

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

AnalyticDmfFit FitAnalyticDualMicrofacet(const DmfSlice& slice, const DmfPointFitOptions& options) {
  AnalyticDmfFit best;
  best.rho_d = slice.rho_d;
  const std::vector<int> used = UsableTrainingDots(slice, options);
  if (static_cast<int>(used.size()) < options.min_measurements) return best;
  double best_cost = 1e300;
  for (double start : {0.2, 0.5, 0.8}) {
    double log_alpha = std::log(0.2), weight = start, log_k = 0;
    ceres::Problem problem;
    for (int q : used) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<AnalyticDmfResidual, 1, 1, 1, 1>(new AnalyticDmfResidual{
                                   slice.i[q], slice.o, std::log(slice.value[q] - slice.rho_d), options.eta}),
                               nullptr, &log_alpha, &weight, &log_k);
    }
    problem.SetParameterLowerBound(&log_alpha, 0, std::log(kMinMicrofacetAlpha));
    problem.SetParameterUpperBound(&log_alpha, 0, std::log(kMaxMicrofacetAlpha));
    problem.SetParameterLowerBound(&weight, 0, kMinWeight);
    problem.SetParameterUpperBound(&weight, 0, kMaxWeight);
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.max_num_iterations = 50;
    solver.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    if (summary.final_cost < best_cost) {
      best_cost = summary.final_cost;
      best.ok = true;
      best.alpha_ndf = std::exp(log_alpha);
      best.alpha = weight;
      best.k_s = std::exp(log_k);
      best.log_rms_residual = std::sqrt(2 * summary.final_cost / used.size());
    }
  }
  return best;
}

double PredictAnalyticDualMicrofacet(const AnalyticDmfFit& fit, double eta, const Eigen::Vector3d& i,
                                     const Eigen::Vector3d& o) {
  if (!fit.ok) return fit.rho_d;
  const GgxDistribution ggx(fit.alpha_ndf);
  return fit.rho_d + fit.k_s * MakeDualMicrofacetBtdf(ggx, ggx, eta).Eval(i, o, fit.alpha);
}

const char* LadderRungName(int rung_index) {
  static const char* const kNames[kNumLadderRungs] = {"single_ggx", "dual_microfacet_analytic",
                                                      "dual_microfacet_tabulated"};
  return rung_index >= 0 && rung_index < kNumLadderRungs ? kNames[rung_index] : "none";
}

LadderResult FitLadder(const DmfSlice& slice, const DmfNdfGrid& grid, const LadderOptions& options) {
  LadderResult r;
  const double eta = options.point.eta;
  const DmfStatus precheck = PrecheckSlice(slice, options.point);
  if (precheck == DmfStatus::kSpecular || precheck == DmfStatus::kNoLobe) {
    r.specular = true;
    return r;
  }
  auto t = std::chrono::steady_clock::now();
  r.single = FitSingleInterfaceGgx(slice, options.point);
  r.seconds[0] = Seconds(t);
  t = std::chrono::steady_clock::now();
  r.analytic = FitAnalyticDualMicrofacet(slice, options.point);
  r.seconds[1] = Seconds(t);
  t = std::chrono::steady_clock::now();
  r.tabulated = FitDualMicrofacetPoint(slice, grid, options.point);
  r.seconds[2] = Seconds(t);
  r.parameters = {2, 3, grid.num_unknowns() + 3};

  const bool fitted[kNumLadderRungs] = {r.single.ok, r.analytic.ok, !r.tabulated.log_ndf.empty()};
  auto predict = [&](int rung, int q) {
    if (rung == 0) return PredictSingleInterfaceGgx(r.single, eta, slice.i[q], slice.o);
    if (rung == 1) return PredictAnalyticDualMicrofacet(r.analytic, eta, slice.i[q], slice.o);
    return PredictDualMicrofacet(r.tabulated, grid, eta, slice.i[q], slice.o);
  };

  // The scored dots: held out and in the lobe (as HeldOutRelativeRms), with each rung's squared
  // prediction error per dot.
  double peak = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (!slice.train[q]) peak = std::max(peak, slice.value[q] - slice.rho_d);
  }
  std::vector<int> scored;
  double noise = 0, signal = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (slice.train[q] || slice.value[q] - slice.rho_d < options.lobe_fraction * peak) continue;
    scored.push_back(q);
    noise += slice.sigma.empty() ? 0 : Sqr(slice.sigma[q]);
    signal += Sqr(slice.value[q] - slice.rho_d);
  }
  if (scored.empty() || !(signal > 0)) return r;
  r.noise_floor = std::sqrt(noise / signal);
  std::array<std::vector<double>, kNumLadderRungs>& sq = r.squared_errors;
  r.signal = signal;
  for (int k = 0; k < kNumLadderRungs; ++k) {
    if (!fitted[k]) continue;
    double sum = 0;
    for (int q : scored) {
      sq[k].push_back(Sqr(predict(k, q) - slice.value[q]));
      sum += sq[k].back();
    }
    r.held_out[k] = std::sqrt(sum / signal);
  }

  const int n = static_cast<int>(UsableTrainingDots(slice, options.point).size());
  const double log_rms[kNumLadderRungs] = {r.single.log_rms_residual, r.analytic.log_rms_residual,
                                           r.tabulated.log_rms_residual};
  double best_bic = 1e300;
  for (int k = 0; k < kNumLadderRungs; ++k) {
    if (!fitted[k] || r.held_out[k] < 0) continue;
    r.bic[k] = n * std::log(std::max(1e-12, Sqr(log_rms[k]))) + r.parameters[k] * std::log(std::max(1, n));
    if (r.bic[k] < best_bic) {
      best_bic = r.bic[k];
      r.chosen_by_bic = k;
    }
  }
  r.chosen = ChooseLadderRung({&r}, options.significance_sigmas);
  return r;
}

int ChooseLadderRung(const std::vector<const LadderResult*>& group, double significance_sigmas) {
  // Per-dot squared errors relative to their point's signal, pooled over the group.
  std::vector<std::vector<double>> pooled(kNumLadderRungs);
  std::array<bool, kNumLadderRungs> available{{true, true, true}};
  int points = 0;
  for (const LadderResult* r : group) {
    if (r->specular || r->signal <= 0) continue;
    ++points;
    for (int k = 0; k < kNumLadderRungs; ++k) {
      if (r->squared_errors[k].empty()) available[k] = false;
      for (double e : r->squared_errors[k]) pooled[k].push_back(e / r->signal);
    }
  }
  if (points == 0) return -1;
  for (int k = 0; k < kNumLadderRungs; ++k) {
    if (!available[k]) pooled[k].clear();
  }
  return SimplestRungWithinNoise(pooled, significance_sigmas);
}

}  // namespace thinslab
