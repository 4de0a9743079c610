// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_ndf_grid.h"

#include <glog/logging.h>

#include <algorithm>

#include "thinslab/core/math.h"

namespace thinslab {

DmfNdfGrid::DmfNdfGrid(int n) : n_(n) {
  CHECK_GE(n, 4);
  unknown_.assign(num_cells(), -1);
  in_disk_.assign(num_cells(), false);
  const double h = cell_width();
  for (int row = 0; row < n_; ++row) {
    for (int col = 0; col < n_; ++col) {
      const int cell = row * n_ + col;
      const double r = std::hypot(CellCentre(col), CellCentre(row));
      in_disk_[cell] = r < 1;
      if (r < 1 - h) {
        unknown_[cell] = num_unknowns_++;
        cell_of_unknown_.push_back(cell);
      }
    }
  }
}

DmfNdfGrid::Stencil DmfNdfGrid::Lookup(const Eigen::Vector3d& h) const {
  const double w = cell_width();
  const double u = Clamp((h.x() + 1) / w - 0.5, 0.0, n_ - 1.0);
  const double v = Clamp((h.y() + 1) / w - 0.5, 0.0, n_ - 1.0);
  const int c0 = std::min(static_cast<int>(u), n_ - 2), r0 = std::min(static_cast<int>(v), n_ - 2);
  const double fu = u - c0, fv = v - r0;
  Stencil s;
  s.cells = {r0 * n_ + c0, r0 * n_ + c0 + 1, (r0 + 1) * n_ + c0, (r0 + 1) * n_ + c0 + 1};
  s.weights = {(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv};
  return s;
}

double DmfNdfGrid::ProjectedIntegral(const std::vector<double>& log_d_cells) const {
  double sum = 0;
  for (int cell = 0; cell < num_cells(); ++cell) {
    if (in_disk_[cell]) sum += std::exp(log_d_cells[cell]);
  }
  return sum * cell_width() * cell_width();
}

}  // namespace thinslab
