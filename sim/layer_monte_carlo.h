// SPDX-License-Identifier: Apache-2.0
// Monte Carlo light transport through a plane-parallel scattering layer (optical thickness
// tau, single-scattering albedo omega0, Henyey-Greenstein g) lit at normal incidence, with
// all orders of scattering. It produces the angular distribution of light leaving the far
// side, the quantity Gu et al. 2007 model by single scattering (Eq. 6). The simulated rig
// renders with it, so fits of Eq. 6 are tested against a more complete model.
//
// Not modelled: lateral displacement inside the layer (the layer is thin against the
// layer-to-board distance) and Fresnel reflection at the glass for back-scattered light.
#pragma once

#include <cstdint>
#include <vector>

namespace thinslab {

struct LayerMonteCarloOptions {
  double albedo = 0.3;  // Single-scattering albedo omega0, unitless [0, 1].
  double g = 0.8;       // HG mean cosine, unitless (-1, 1).
  int num_photons = 200000;
  int num_mu_bins = 128;  // Uniform bins of the exit cosine mu in (0, 1].
  uint64_t seed = 1;
};

// Exit radiance per unit incident irradiance [1/sr], split by scattering order, on uniform
// mu bins: bin b covers mu in [b / n, (b + 1) / n).
struct LayerExitDistribution {
  double tau = 0;
  std::vector<double> single_scatter;    // Exactly one scattering event.
  std::vector<double> multiple_scatter;  // Two or more.
  double direct = 0;                     // Unscattered transmittance (estimate of e^-tau).

  // Piecewise-linear lookup at the bin centres.
  double MultipleAt(double mu) const;
  double SingleAt(double mu) const;
};

LayerExitDistribution SimulateLayer(double tau, const LayerMonteCarloOptions& options);

}  // namespace thinslab
