// SPDX-License-Identifier: Apache-2.0
// The slice shapes the k-means acceleration compares (Dai et al. 2009, Sec. 4.3, Eqs. 20-22).
// Dai resamples every point's measurements onto one hemicube of light directions before the
// clustering ("measurements ... are irregularly scattered as a function of i because of spatial
// variation in the lighting direction i_q(x)", Sec. 4.1), so that the slices of one material
// are one vector wherever the point lies. Indexed by dot instead, a point's lobe moves across the
// dots as the point moves (4 mm at a monitor 40 mm away turns every direction by ~6 degrees):
// on the simulated nine-region rig 136 of 230 interpolated points then had a representative
// of another material among their Eq. 20 neighbours, and their held-out error doubled.
//
// Here the common coordinate is the deviation from straight-through transmission,
// u = i_xy + o_xy (optical frame; a thin slab with parallel faces transmits straight through at
// i = -o), which also follows the point's own view o where Dai keeps one o_c: the shape of a
// material's lobe is then one function of u to first order in the change of view.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "thinslab/fit/dmf_point_fit.h"

namespace thinslab {

struct SliceShapeGrid {
  int n = 0;                               // n x n nodes.
  Eigen::Vector2d min_u = Eigen::Vector2d::Zero();
  double spacing = 0;                      // Node spacing in u; node (a, b) at min_u + (b, a) spacing.
  int num_nodes() const { return n * n; }
};

// A grid over the u of every dot seen from `centre_slice` (the sample's central point), with
// `n` nodes per side (the dot grid's resolution is a natural choice).
SliceShapeGrid MakeSliceShapeGrid(const DmfSlice& centre_slice, int n);

// The training values R - rho_d (clipped at 0) of `slice` resampled onto `grid` by normalised
// Gaussian convolution (sigma = one node spacing; nodes with no training dot within two spacings
// are 0), then divided by their sum (k_s and rho_d stay per point). `out` has grid.num_nodes()
// entries; false (and zeros) when the slice has no positive training value on the grid.
bool AlignedSliceShape(const DmfSlice& slice, const SliceShapeGrid& grid, float* out);

}  // namespace thinslab
