// SPDX-License-Identifier: Apache-2.0
#include "fit/single_interface_fit.h"

#include <ceres/ceres.h>

#include <cmath>

#include "optics/dual_microfacet_btdf.h"
#include "optics/microfacet.h"

namespace thinslab {
namespace {

struct SingleInterfaceResidual {
  Eigen::Vector3d i, o;
  double log_value, eta;
  bool rough_top;
  template <typename T>
  bool operator()(const T* log_alpha, const T* log_k, T* residual) const {
    using std::exp;
    using std::log;
    const GgxDistributionT<T> ggx(exp(log_alpha[0]));
    const DualMicrofacetBtdf<GgxDistributionT<T>> btdf(ggx, ggx, T(eta));
    const Vector3T<T> it = i.cast<T>(), ot = o.cast<T>();
    const T rho = rough_top ? btdf.EvalTop(it, ot) : btdf.EvalBottom(it, ot);
    // A configuration that cannot transmit along (i, o) predicts 0; a large finite residual keeps
    // the solver away from it.
    residual[0] = rho > T(0) ? T(log_value) - log_k[0] - log(rho) : T(10.0);
    return true;
  }
};

}  // namespace

SingleInterfaceFit FitSingleInterfaceGgx(const DmfSlice& slice, const DmfPointFitOptions& options) {
  SingleInterfaceFit best;
  best.rho_d = slice.rho_d;
  const std::vector<int> used = UsableTrainingDots(slice, options);
  if (static_cast<int>(used.size()) < options.min_measurements) return best;
  double best_cost = 1e300;
  for (bool rough_top : {true, false}) {
    double log_alpha = std::log(0.2), log_k = 0;
    ceres::Problem problem;
    for (int q : used) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SingleInterfaceResidual, 1, 1, 1>(
                                   new SingleInterfaceResidual{slice.i[q], slice.o,
                                                               std::log(slice.value[q] - slice.rho_d), options.eta,
                                                               rough_top}),
                               nullptr, &log_alpha, &log_k);
    }
    problem.SetParameterLowerBound(&log_alpha, 0, std::log(kMinMicrofacetAlpha));
    problem.SetParameterUpperBound(&log_alpha, 0, std::log(kMaxMicrofacetAlpha));
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.max_num_iterations = 50;
    solver.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    if (summary.final_cost < best_cost) {
      best_cost = summary.final_cost;
      best.ok = true;
      best.rough_top = rough_top;
      best.alpha = std::exp(log_alpha);
      best.k_s = std::exp(log_k);
      best.log_rms_residual = std::sqrt(2 * summary.final_cost / used.size());
    }
  }
  return best;
}

double PredictSingleInterfaceGgx(const SingleInterfaceFit& fit, double eta, const Eigen::Vector3d& i,
                                 const Eigen::Vector3d& o) {
  if (!fit.ok) return fit.rho_d;
  const GgxDistribution ggx(fit.alpha);
  const auto btdf = MakeDualMicrofacetBtdf(ggx, ggx, eta);
  return fit.rho_d + fit.k_s * (fit.rough_top ? btdf.EvalTop(i, o) : btdf.EvalBottom(i, o));
}

}  // namespace thinslab
