// SPDX-License-Identifier: Apache-2.0
// Data residual of the scattering-aware tau fit, per rectified pixel p:
//   r_p = (e^{-tau_p} - d_p) / sigma_p,
// where d_p = m_p - S_p is the measured shadow/reference ratio m_p minus the light the
// current layer estimate scatters onto p (Gu et al. 2007, Eq. 6, summed over the layer), so
// e^{-tau_p} is the reduced transmission of Eq. 5. sigma_p is the standard deviation of m_p
// (unitless). d_p is read through a pointer because the fixed-point iteration updates it
// between solves of one problem that is built once.
#pragma once

#include <ceres/ceres.h>

namespace thinslab {

class ShadowAttenuationCost {
 public:
  ShadowAttenuationCost(const double* unscattered_ratio, double sigma)
      : unscattered_ratio_(unscattered_ratio), inv_sigma_(1.0 / sigma) {}

  template <typename T>
  bool operator()(const T* const tau, T* residual) const {
    using std::exp;
    residual[0] = (exp(-tau[0]) - T(*unscattered_ratio_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const double* unscattered_ratio, double sigma) {
    return new ceres::AutoDiffCostFunction<ShadowAttenuationCost, 1, 1>(
        new ShadowAttenuationCost(unscattered_ratio, sigma));
  }

 private:
  const double* unscattered_ratio_;
  double inv_sigma_;
};

// Smoothness prior between 4-neighbours: r = (tau_p - tau_q) / sigma_tau (unitless); used
// with a Huber loss so edges of specks and ridges are penalised linearly, not quadratically.
class TauSmoothnessCost {
 public:
  explicit TauSmoothnessCost(double sigma_tau) : inv_sigma_(1.0 / sigma_tau) {}

  template <typename T>
  bool operator()(const T* const tau_p, const T* const tau_q, T* residual) const {
    residual[0] = (tau_p[0] - tau_q[0]) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(double sigma_tau) {
    return new ceres::AutoDiffCostFunction<TauSmoothnessCost, 1, 1, 1>(new TauSmoothnessCost(sigma_tau));
  }

 private:
  double inv_sigma_;
};

}  // namespace thinslab
