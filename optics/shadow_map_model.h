// SPDX-License-Identifier: Apache-2.0
// Forward model of the shadow-map rig (Gu et al. 2007, Sec. 5.1, Fig. 9a): a collimated flat
// field at normal incidence crosses a contaminant layer tau(x, y) and lands on a Lambertian
// board parallel to it at distance D. The board irradiance is the reduced (Eq. 5) light plus
// light scattered by every point of the layer (Eq. 6), integrated over the layer:
//
//   E_board(x) = E0(x) e^{-tau(x)} + sum_x' E0(x') A_px L(tau(x'), mu) mu^4 / D^2,
//
// where L is the exit radiance per unit incident irradiance of the layer point x' towards x,
// mu = D / |x - x' + D e_z| and A_px the source pixel area (solid angle of a board element
// seen from x' is dA mu / (D/mu)^2, its projected area adds one more mu: mu^4 / D^2).
// L depends non-linearly on tau, so it is expanded on tau nodes t_j:
//   L(tau, mu) = tau * sum_j w_j(tau) R_j(mu),   R_j(mu) = L(t_j, mu) / t_j,
// with hat weights w_j; R is much smoother in tau than L (L ~ tau / mu for small tau), so
// linear interpolation of R is accurate with a few nodes. Each node is one convolution.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "thinslab/core/image.h"

namespace thinslab {

struct BoardGeometry {
  double distance_m = 0;       // Layer-to-board distance D.
  double pixel_pitch_m = 0;    // Grid pitch on the board (= on the layer; planes are parallel).
  double max_angle_deg = 80;   // Scattered light beyond this angle from the normal is dropped.
  int max_radius_px = 0;       // Caps the kernel radius (0 = no cap); set to the grid diagonal.
};

// Radius [px] of BuildBoardKernel's kernel: light up to max_angle_deg from the normal, capped.
int BoardKernelRadiusPx(const BoardGeometry& geometry);

// Pixel-integrated irradiance kernel of a radiance lobe R(mu) leaving one source pixel of unit
// incident irradiance. Square, odd size, centre = zero offset; entries in units of R.
Image BuildBoardKernel(const std::function<double(double mu)>& radiance, const BoardGeometry& geometry);

// Zero-padded 2-D convolution of `source` with a point-symmetric, odd-sized `kernel` (same
// output size as `source`); DFT-based for large kernels.
Image ConvolveZeroPadded(const Image& source, const Image& kernel);

class ScatterKernelBank {
 public:
  // `radiance_per_tau(t, mu)` must return L(t, mu) / t (and its limit at t = 0).
  ScatterKernelBank(const std::vector<double>& tau_nodes,
                    const std::function<double(double tau, double mu)>& radiance_per_tau,
                    const BoardGeometry& geometry);

  // Scattered board irradiance for incident irradiance `e0` and layer `tau` (same grid).
  // Sources outside the grid are taken as clean.
  Image Scattered(const Image& e0, const Image& tau) const;

  // Default node set: 0.1 steps to 1.5, 0.25 steps to 3, then 4 and 6.
  static std::vector<double> DefaultNodes(double spacing_scale = 1.0);
  const std::vector<double>& nodes() const { return nodes_; }
  const Image& kernel(int j) const { return kernels_[j]; }

 private:
  std::vector<double> nodes_;
  std::vector<Image> kernels_;
};

}  // namespace thinslab
