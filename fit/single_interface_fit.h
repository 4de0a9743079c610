// SPDX-License-Identifier: Apache-2.0
// The single-refraction baseline of Dai et al. 2009, Fig. 5: the slab's BTDF slice fitted with
// one rough GGX interface (Walter et al. 2007, Eqs. 21 and 33-34) on one face and a flat other
// face, i.e. R = rho_d + k_s rho_{t or b}(i, o) of optics/dual_microfacet_btdf.h with an
// analytic isotropic GGX NDF and its own Smith term. Parameters ln k_s and ln alpha_g by Ceres
// on the Eq. 15 log residuals of the same measurements the dual-microfacet fit uses; both faces
// are tried and the better one kept.
#pragma once

#include <Eigen/Core>

#include "fit/dmf_point_fit.h"

namespace thinslab {

struct SingleInterfaceFit {
  bool ok = false;
  bool rough_top = true;  // Which face carries the roughness.
  double alpha = 0.2;     // GGX roughness.
  double k_s = 0;
  double rho_d = 0;
  double log_rms_residual = 0;
};

// Uses options.eta, min_relative_value, noise_sigmas and min_measurements.
SingleInterfaceFit FitSingleInterfaceGgx(const DmfSlice& slice, const DmfPointFitOptions& options);
double PredictSingleInterfaceGgx(const SingleInterfaceFit& fit, double eta, const Eigen::Vector3d& i,
                                 const Eigen::Vector3d& o);

}  // namespace thinslab
