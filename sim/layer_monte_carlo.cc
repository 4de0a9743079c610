// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/layer_monte_carlo.h"

#include <cmath>
#include <random>

#include "thinslab/core/math.h"
#include "thinslab/optics/henyey_greenstein.h"

namespace thinslab {
namespace {

double Lookup(const std::vector<double>& bins, double mu) {
  const int n = static_cast<int>(bins.size());
  const double f = Clamp(mu * n - 0.5, 0.0, n - 1.0);
  const int i = std::min(static_cast<int>(f), n - 2);
  const double t = f - i;
  return (1 - t) * bins[i] + t * bins[i + 1];
}

}  // namespace

double LayerExitDistribution::MultipleAt(double mu) const { return Lookup(multiple_scatter, mu); }
double LayerExitDistribution::SingleAt(double mu) const { return Lookup(single_scatter, mu); }

LayerExitDistribution SimulateLayer(double tau, const LayerMonteCarloOptions& options) {
  LayerExitDistribution out;
  out.tau = tau;
  const int nb = options.num_mu_bins;
  out.single_scatter.assign(nb, 0.0);
  out.multiple_scatter.assign(nb, 0.0);
  if (tau <= 0) {
    out.direct = 1.0;
    return out;
  }
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  double direct_sum = 0;
  // Depth z is optical depth from the lit face (0) to the far face (tau); cos_z is the
  // direction cosine along +depth.
  for (int p = 0; p < options.num_photons; ++p) {
    double z = 0, dir_x = 0, dir_y = 0, dir_z = 1, weight = 1;
    int order = 0;
    while (true) {
      const double step = -std::log(1.0 - uni(rng));
      z += step * dir_z;
      if (z >= tau) {
        if (order == 0) {
          direct_sum += weight;
        } else {
          const int bin = std::min(nb - 1, static_cast<int>(dir_z * nb));
          (order == 1 ? out.single_scatter : out.multiple_scatter)[bin] += weight;
        }
        break;
      }
      if (z <= 0) break;  // Back into the glass: not modelled further.
      // Scatter: survive with probability omega0 (absorption as weight), new HG direction.
      weight *= options.albedo;
      ++order;
      if (weight < 1e-4) {
        if (uni(rng) > 0.1) break;  // Russian roulette.
        weight /= 0.1;
      }
      const double cos_t = SampleHenyeyGreensteinCosTheta(uni(rng), options.g);
      const double sin_t = SafeSqrt(1 - cos_t * cos_t);
      const double phi = 2 * kPi * uni(rng);
      // Frame around the current direction.
      double ux, uy, uz;
      if (std::abs(dir_z) < 0.999) {
        const double inv = 1.0 / std::sqrt(1 - dir_z * dir_z);
        ux = -dir_y * inv;
        uy = dir_x * inv;
        uz = 0;
      } else {
        ux = 1;
        uy = 0;
        uz = 0;
      }
      const double vx = dir_y * uz - dir_z * uy, vy = dir_z * ux - dir_x * uz, vz = dir_x * uy - dir_y * ux;
      const double nx = sin_t * (std::cos(phi) * ux + std::sin(phi) * vx) + cos_t * dir_x;
      const double ny = sin_t * (std::cos(phi) * uy + std::sin(phi) * vy) + cos_t * dir_y;
      const double nz = sin_t * (std::cos(phi) * uz + std::sin(phi) * vz) + cos_t * dir_z;
      const double norm = std::sqrt(nx * nx + ny * ny + nz * nz);
      dir_x = nx / norm;
      dir_y = ny / norm;
      dir_z = nz / norm;
    }
  }
  // Flux per bin / (photons * bin solid angle * mu) = radiance per unit incident irradiance.
  for (int b = 0; b < nb; ++b) {
    const double mu = (b + 0.5) / nb;
    const double norm = 1.0 / (options.num_photons * 2 * kPi * (1.0 / nb) * mu);
    out.single_scatter[b] *= norm;
    out.multiple_scatter[b] *= norm;
  }
  out.direct = direct_sum / options.num_photons;
  return out;
}

}  // namespace thinslab
