// SPDX-License-Identifier: Apache-2.0
// Ring residual of the laser-lobe fit (Gu et al. 2007, Eq. 8), per ring k at angle theta_k:
//   r_k = (exp(log_beta) LaserLobeProfile(cos theta_k; g, tau) - I_k) / sigma_k,
// I_k the ring's robust mean radiance (flat-fielded DN per microsecond) and sigma_k its standard
// error. beta is fitted as log_beta so it stays positive without a bound.
#pragma once

#include <ceres/ceres.h>

#include "thinslab/optics/dirty_glass.h"

namespace thinslab {

class LaserLobeRingCost {
 public:
  LaserLobeRingCost(double cos_theta, double intensity, double sigma)
      : cos_theta_(cos_theta), intensity_(intensity), inv_sigma_(1.0 / sigma) {}

  template <typename T>
  bool operator()(const T* const log_beta, const T* const g, const T* const tau, T* residual) const {
    using std::exp;
    residual[0] = (exp(log_beta[0]) * LaserLobeProfile(T(cos_theta_), g[0], tau[0]) - T(intensity_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(double cos_theta, double intensity, double sigma) {
    return new ceres::AutoDiffCostFunction<LaserLobeRingCost, 1, 1, 1, 1>(
        new LaserLobeRingCost(cos_theta, intensity, sigma));
  }

 private:
  double cos_theta_, intensity_, inv_sigma_;
};

// The same ring with a second, broader lobe of the same form at g^2 and relative amplitude c >= 0:
//   r_k = (exp(log_beta) (P(cos theta_k; g, tau) + c P(cos theta_k; g^2, tau)) - I_k) / sigma_k.
// Light scattered twice by HG(g) leaves with about HG(g^2) (the mean cosine of the composition
// is g^2), so this is Eq. 8 extended by second-order scattering: how far g moves when the
// extension is allowed measures what single scattering leaves out (fit/phase_fit.cc).
class LaserLobeTwoOrderRingCost {
 public:
  LaserLobeTwoOrderRingCost(double cos_theta, double intensity, double sigma)
      : cos_theta_(cos_theta), intensity_(intensity), inv_sigma_(1.0 / sigma) {}

  template <typename T>
  bool operator()(const T* const log_beta, const T* const g, const T* const c, const T* const tau,
                  T* residual) const {
    using std::exp;
    const T cos_theta(cos_theta_);
    const T lobe = LaserLobeProfile(cos_theta, g[0], tau[0]) + c[0] * LaserLobeProfile(cos_theta, g[0] * g[0], tau[0]);
    residual[0] = (exp(log_beta[0]) * lobe - T(intensity_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(double cos_theta, double intensity, double sigma) {
    return new ceres::AutoDiffCostFunction<LaserLobeTwoOrderRingCost, 1, 1, 1, 1, 1>(
        new LaserLobeTwoOrderRingCost(cos_theta, intensity, sigma));
  }

 private:
  double cos_theta_, intensity_, inv_sigma_;
};

// Gaussian prior on one parameter: r = (x - mean) / sigma (e.g. tau from a shadow-map fit).
class GaussianPriorCost {
 public:
  GaussianPriorCost(double mean, double sigma) : mean_(mean), inv_sigma_(1.0 / sigma) {}

  template <typename T>
  bool operator()(const T* const x, T* residual) const {
    residual[0] = (x[0] - T(mean_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(double mean, double sigma) {
    return new ceres::AutoDiffCostFunction<GaussianPriorCost, 1, 1>(new GaussianPriorCost(mean, sigma));
  }

 private:
  double mean_, inv_sigma_;
};

}  // namespace thinslab
