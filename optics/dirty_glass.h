// SPDX-License-Identifier: Apache-2.0
// The contaminant layer of Gu, Ramamoorthi, Belhumeur and Nayar 2007, "Dirty Glass:
// Rendering Contamination on Transparent Surfaces", for light at normal incidence from the
// glass side through a layer whose index matches air (dust, n2 = n1), which is the
// shadow-map and laser geometry of Sec. 5 (Fig. 9). Fresnel factors T12 T23 are 1 here and
// the glass transmittance cancels in every ratio to a clean-glass reference.
#pragma once

#include <cmath>
#include <vector>

#include "thinslab/optics/henyey_greenstein.h"

namespace thinslab {

// Gu et al. 2007, Eq. 5 with mu'_i = 1: unscattered (reduced) transmittance e^{-tau}.
template <typename T>
T LayerDirectTransmittance(const T& tau) {
  using std::exp;
  return exp(-tau);
}

// Gu et al. 2007, Eq. 6 with mu'_i = 1: single-scattered radiance leaving the layer at
// angle theta from the normal (mu = cos theta > 0), per unit incident irradiance [1/sr]:
//   L / E_i = omega0 p(theta; g) (e^{-tau} - e^{-tau/mu}) / (1 - mu).
// The (e^{-tau} - e^{-tau/mu}) / (1 - mu) factor tends to tau e^{-tau} as mu -> 1; it is
// evaluated as e^{-tau} (1 - e^{-tau s}) / (mu s) with s = 1/mu - 1 to avoid cancellation.
template <typename T>
T LayerSingleScatterRadiance(const T& tau, const T& mu, const T& albedo, const T& g) {
  using std::exp;
  using std::expm1;
  const T s = T(1) / mu - T(1);
  T path_factor;
  if (s < T(1e-8)) {
    path_factor = tau * exp(-tau) / mu;
  } else {
    path_factor = -exp(-tau) * expm1(-tau * s) / (mu * s);
  }
  // Scattering angle between the incident direction (along -z) and the exit direction.
  return albedo * HenyeyGreenstein(mu, g) * path_factor;
}

// Gu et al. 2007, Eq. 8: laser-lobe profile on the board at angle theta from the beam axis,
// up to the scale beta (which absorbs omega0, the beam power, the board albedo and the camera):
//   I(theta) / beta = p(theta; g) (e^{-tau} - e^{-tau/cos theta}) / (1 - cos theta) cos^4 theta,
// i.e. the single-scattered radiance of Eq. 6 (albedo 1) times cos^4 theta (appendix: board
// irradiance L cos theta d omega with d omega = dA cos theta / (d / cos theta)^2).
template <typename T>
T LaserLobeProfile(const T& cos_theta, const T& g, const T& tau) {
  const T mu2 = cos_theta * cos_theta;
  return LayerSingleScatterRadiance(tau, cos_theta, T(1), g) * mu2 * mu2;
}

// Gu et al. 2007, Fig. 2: the three contaminant categories. Dust has no interface with the air
// (n2 = n1), dirt and lipids do (n2 != n1); optical thickness is "small" for dust and lipids,
// "medium" for dirt.
struct ContaminantCategoryRange {
  const char* name;
  bool interface_with_air;
  const char* optical_thickness;
  double g_min, g_max;
};

inline const std::vector<ContaminantCategoryRange>& GuContaminantCategories() {
  static const std::vector<ContaminantCategoryRange> categories = {
      {"dust", false, "small", 0.4, 0.9}, {"dirt", true, "medium", 0.0, 0.8}, {"lipid", true, "small", 0.7, 1.0}};
  return categories;
}

}  // namespace thinslab
