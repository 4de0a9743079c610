// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_slice_shape.h"

#include <algorithm>
#include <cmath>

#include "thinslab/core/math.h"

namespace thinslab {
namespace {

Eigen::Vector2d DeviationFromStraightThrough(const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
  return Eigen::Vector2d(i.x() + o.x(), i.y() + o.y());
}

}  // namespace

SliceShapeGrid MakeSliceShapeGrid(const DmfSlice& centre_slice, int n) {
  SliceShapeGrid grid;
  grid.n = std::max(2, n);
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const Eigen::Vector3d& i : centre_slice.i) {
    const Eigen::Vector2d u = DeviationFromStraightThrough(i, centre_slice.o);
    lo = lo.cwiseMin(u);
    hi = hi.cwiseMax(u);
  }
  if (!(hi.x() >= lo.x() && hi.y() >= lo.y())) {
    lo = Eigen::Vector2d(-1, -1);
    hi = Eigen::Vector2d(1, 1);
  }
  grid.spacing = std::max(1e-6, std::max(hi.x() - lo.x(), hi.y() - lo.y()) / (grid.n - 1));
  grid.min_u = 0.5 * (lo + hi) - 0.5 * (grid.n - 1) * grid.spacing * Eigen::Vector2d::Ones();
  return grid;
}

bool AlignedSliceShape(const DmfSlice& slice, const SliceShapeGrid& grid, float* out) {
  const int n = grid.n;
  std::vector<double> value(grid.num_nodes(), 0.0), weight(grid.num_nodes(), 0.0);
  const double inv_two_sigma2 = 0.5 / (grid.spacing * grid.spacing);
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (!slice.train[q]) continue;
    const double v = std::max(0.0, slice.value[q] - slice.rho_d);
    const Eigen::Vector2d g = (DeviationFromStraightThrough(slice.i[q], slice.o) - grid.min_u) / grid.spacing;
    const int b0 = static_cast<int>(std::ceil(g.x() - 2)), b1 = static_cast<int>(std::floor(g.x() + 2));
    const int a0 = static_cast<int>(std::ceil(g.y() - 2)), a1 = static_cast<int>(std::floor(g.y() + 2));
    // The Gaussian is separable: one exponential per node row and column within 2 sigma.
    double wx[5], wy[5];
    for (int k = 0; k < 5; ++k) {
      wx[k] = std::exp(-Sqr((b0 + k - g.x()) * grid.spacing) * inv_two_sigma2);
      wy[k] = std::exp(-Sqr((a0 + k - g.y()) * grid.spacing) * inv_two_sigma2);
    }
    for (int a = std::max(0, a0); a <= std::min(n - 1, a1); ++a) {
      for (int b = std::max(0, b0); b <= std::min(n - 1, b1); ++b) {
        const double w = wy[a - a0] * wx[b - b0];
        value[a * n + b] += w * v;
        weight[a * n + b] += w;
      }
    }
  }
  double sum = 0;
  for (int k = 0; k < grid.num_nodes(); ++k) {
    value[k] = weight[k] > 0 ? value[k] / weight[k] : 0.0;
    sum += value[k];
  }
  const bool ok = sum > 0;
  for (int k = 0; k < grid.num_nodes(); ++k) out[k] = ok ? static_cast<float>(value[k] / sum) : 0.0f;
  return ok;
}

}  // namespace thinslab
