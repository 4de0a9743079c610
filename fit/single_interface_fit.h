// SPDX-License-Identifier: Apache-2.0
// The single-refraction baseline of Dai et al. 2009, Fig. 5, and rung 3 of the model ladder
// (issue #8): the slab's BTDF slice fitted with one rough interface (Walter et al. 2007, Eqs. 21
// and 33-34; GGX Eqs. 33-34 or Beckmann Eqs. 25-26, each with its own Smith term) on one face and
// a flat other face, i.e. R = rho_d + k_s rho_{t or b}(i, o) of optics/dual_microfacet_btdf.h
// with an analytic isotropic NDF. Parameters ln k_s and ln alpha_g by Ceres on the Eq. 15 log
// residuals of the same measurements the dual-microfacet fit uses; both faces (and, unless only
// GGX is asked for, both families) are tried and the lowest training cost kept: the discrete
// choices add no continuous parameter.
#pragma once

#include <Eigen/Core>

#include "thinslab/fit/dmf_point_fit.h"

namespace thinslab {

enum class MicrofacetFamily { kGgx, kBeckmann };

struct SingleInterfaceFit {
  bool ok = false;
  bool rough_top = true;  // Which face carries the roughness.
  MicrofacetFamily family = MicrofacetFamily::kGgx;
  double alpha = 0.2;     // Roughness of `family`.
  double k_s = 0;
  double rho_d = 0;
  double log_rms_residual = 0;
};

// Uses options.eta, min_relative_value, noise_sigmas and min_measurements. `ggx_only`: the
// Fig. 5 baseline (one GGX interface), otherwise GGX and Beckmann.
SingleInterfaceFit FitSingleInterface(const DmfSlice& slice, const DmfPointFitOptions& options, bool ggx_only = false);
inline SingleInterfaceFit FitSingleInterfaceGgx(const DmfSlice& slice, const DmfPointFitOptions& options) {
  return FitSingleInterface(slice, options, true);
}
double PredictSingleInterface(const SingleInterfaceFit& fit, double eta, const Eigen::Vector3d& i,
                              const Eigen::Vector3d& o);

}  // namespace thinslab
