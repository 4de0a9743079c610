// SPDX-License-Identifier: Apache-2.0
// The unknown of the dual-microfacet fit (Dai et al. 2009, Sec. 4.2): ln D(h) on a grid over
// the hemisphere of microfacet normals. Dai et al. use a hemicube; thinslab uses the
// orthographic projection of optics/dual_microfacet_btdf.h's TabulatedNdf (h = (x, y,
// sqrt(1 - x^2 - y^2)), N x N cells over [-1, 1]^2, cell (row, col) centred at
// (-1 + (col + 0.5) h, -1 + (row + 0.5) h)), so the fitted table is that class's input without
// resampling and the Laplacian of Eq. 17 has the same four neighbours everywhere.
//
// Cells whose centre lies within one cell width of the rim (and all cells outside the disk) are
// "boundary" cells, fixed at ln epsilon (Eq. 17: "Boundary hemicube cells are removed from the
// set of unknowns and set to ln epsilon", epsilon = 1e-6). ln D at a direction h is the
// bilinear interpolation of the four cell centres around (h.x, h.y), which is linear in the
// unknowns: Eq. 16 then uses each measurement at its exact h_t, h_b instead of a resampled one.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <vector>

namespace thinslab {

class DmfNdfGrid {
 public:
  static constexpr double kLogEpsilon = -13.815510557964274;  // ln 1e-6 (Dai Sec. 4.2).

  explicit DmfNdfGrid(int n);

  int n() const { return n_; }
  double cell_width() const { return 2.0 / n_; }
  double CellCentre(int idx) const { return -1 + (idx + 0.5) * cell_width(); }
  int num_cells() const { return n_ * n_; }
  // Index of the unknown of cell (row * n + col), or -1 for a boundary cell.
  int unknown(int cell) const { return unknown_[cell]; }
  int num_unknowns() const { return num_unknowns_; }
  // Cell of unknown u.
  int cell_of_unknown(int u) const { return cell_of_unknown_[u]; }
  // The polar mirror h' = (-x, -y, z) of Eq. 19: the cell (n-1-row, n-1-col).
  int MirrorCell(int cell) const { return num_cells() - 1 - cell; }
  // True when the cell centre lies inside the unit disk.
  bool InDisk(int cell) const { return in_disk_[cell]; }

  // Bilinear weights of the four cell centres around (h.x, h.y) (clamped to the outermost
  // centres); cells[k] with weight weights[k], weights summing to 1.
  struct Stencil {
    std::array<int, 4> cells;
    std::array<double, 4> weights;
  };
  Stencil Lookup(const Eigen::Vector3d& h) const;

  // ln D at h from per-cell values (size num_cells()).
  double Interpolate(const std::vector<double>& log_d_cells, const Eigen::Vector3d& h) const {
    const Stencil s = Lookup(h);
    double v = 0;
    for (int k = 0; k < 4; ++k) v += s.weights[k] * log_d_cells[s.cells[k]];
    return v;
  }

  // Integral of D = exp(ln D) over the disk in projected coordinates, which is the projected-area
  // normalisation integral of D (m . n) d omega (Dai Sec. 3), by the midpoint rule over the
  // cells whose centre is inside the disk.
  double ProjectedIntegral(const std::vector<double>& log_d_cells) const;

 private:
  int n_;
  int num_unknowns_ = 0;
  std::vector<int> unknown_;
  std::vector<int> cell_of_unknown_;
  std::vector<bool> in_disk_;
};

}  // namespace thinslab
