// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/single_interface_fit.h"

#include <ceres/ceres.h>

#include <cmath>

#include "thinslab/fit/small_dense_solve.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

template <template <typename> class Distribution>
struct SingleInterfaceResidual {
  Eigen::Vector3d i, o;
  double log_value, eta;
  bool rough_top;
  template <typename T>
  bool operator()(const T* log_alpha, const T* log_k, T* residual) const {
    using std::exp;
    using std::log;
    const Distribution<T> ndf(exp(log_alpha[0]));
    const DualMicrofacetBtdf<Distribution<T>> btdf(ndf, ndf, T(eta));
    const Vector3T<T> it = i.cast<T>(), ot = o.cast<T>();
    const T rho = rough_top ? btdf.EvalTop(it, ot) : btdf.EvalBottom(it, ot);
    // A configuration that cannot transmit along (i, o) predicts 0; a large finite residual keeps
    // the solver away from it.
    residual[0] = rho > T(0) ? T(log_value) - log_k[0] - log(rho) : T(10.0);
    return true;
  }
};

// One face, one family: returns the final cost (1e300 when nothing was fitted).
template <template <typename> class Distribution>
double FitOneConfiguration(const DmfSlice& slice, const std::vector<int>& used, double eta, bool rough_top,
                           double* alpha, double* k_s) {
  double log_alpha = std::log(0.2), log_k = 0;
  ceres::Problem problem;
  using Residual = SingleInterfaceResidual<Distribution>;
  for (int q : used) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Residual, 1, 1, 1>(new Residual{
                                 slice.i[q], slice.o, std::log(slice.value[q] - slice.rho_d), eta, rough_top}),
                             nullptr, &log_alpha, &log_k);
  }
  problem.SetParameterLowerBound(&log_alpha, 0, std::log(kMinMicrofacetAlpha));
  problem.SetParameterUpperBound(&log_alpha, 0, std::log(kMaxMicrofacetAlpha));
  const double cost = SolveSmallDenseProblem(&problem, 50);
  *alpha = std::exp(log_alpha);
  *k_s = std::exp(log_k);
  return cost;
}

template <typename Distribution>
double EvalFace(const Distribution& ndf, bool rough_top, double eta, const Eigen::Vector3d& i,
                const Eigen::Vector3d& o) {
  const auto btdf = MakeDualMicrofacetBtdf(ndf, ndf, eta);
  return rough_top ? btdf.EvalTop(i, o) : btdf.EvalBottom(i, o);
}

}  // namespace

SingleInterfaceFit FitSingleInterface(const DmfSlice& slice, const DmfPointFitOptions& options, bool ggx_only) {
  SingleInterfaceFit best;
  best.rho_d = slice.rho_d;
  const std::vector<int> used = UsableTrainingDots(slice, options);
  if (static_cast<int>(used.size()) < options.min_measurements) return best;
  double best_cost = 1e300;
  for (MicrofacetFamily family : {MicrofacetFamily::kGgx, MicrofacetFamily::kBeckmann}) {
    if (ggx_only && family != MicrofacetFamily::kGgx) continue;
    for (bool rough_top : {true, false}) {
      double alpha = 0, k_s = 0;
      const double cost =
          family == MicrofacetFamily::kGgx
              ? FitOneConfiguration<GgxDistributionT>(slice, used, options.eta, rough_top, &alpha, &k_s)
              : FitOneConfiguration<BeckmannDistributionT>(slice, used, options.eta, rough_top, &alpha, &k_s);
      if (cost < best_cost) {
        best_cost = cost;
        best.ok = true;
        best.rough_top = rough_top;
        best.family = family;
        best.alpha = alpha;
        best.k_s = k_s;
        best.log_rms_residual = std::sqrt(2 * cost / used.size());
      }
    }
  }
  return best;
}

double PredictSingleInterface(const SingleInterfaceFit& fit, double eta, const Eigen::Vector3d& i,
                              const Eigen::Vector3d& o) {
  if (!fit.ok) return fit.rho_d;
  const double rho = fit.family == MicrofacetFamily::kGgx
                         ? EvalFace(GgxDistribution(fit.alpha), fit.rough_top, eta, i, o)
                         : EvalFace(BeckmannDistribution(fit.alpha), fit.rough_top, eta, i, o);
  return fit.rho_d + fit.k_s * rho;
}

}  // namespace thinslab
