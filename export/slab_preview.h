// SPDX-License-Identifier: Apache-2.0
// `thinslab preview` of a dual-microfacet fit (issue #27 item 4): the fitted sample in a
// canonical scene, rendered with the fitted model itself (no renderer needed): a backlit
// checkerboard (the papers' figures: Dai et al. 2009 Fig. 1 and 9 show slabs over text and
// patterns) at distance d below the sample, seen straight through it from +z (orthographic).
// Per map point x, with o = +z and the light's directions i in the lower hemisphere,
//   L(x) = integral R(x, i, o) C(x + i d / |i_z|) |i_z| d omega_i,
// R = rho_d + k_s rho of Eq. 12 with the point's tabulated NDF (fit/dmf_point_fit.h
// PredictDualMicrofacet). |i_z| d omega_i is the area element of the projected unit disk, so the
// integral is a sum over a grid of `directions` x `directions` cells of the disk. The slab's
// thickness is left out (it shifts where the light enters by less than a checker square at the
// default sizes). Points without a fit see the checkerboard straight through clean glass.
#pragma once

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/dmf_prediction.h"

namespace thinslab {

struct SlabPreviewOptions {
  double checker_m = 1e-3;             // Side of a checker square.
  double backlight_distance_m = 5e-3;  // Checkerboard plane z = -d.
  double dark_square = 0.1;            // Radiance of the dark squares (bright: 1).
  int max_size_px = 160;               // The map is sampled at most this many points per side.
  int directions = 48;                 // Cells per side of the projected-disk grid.
  int threads = 0;                     // 0: all cores.
  Status Check() const;                // Errors name SlabPreviewOptions::<field> and its option.
};

// Channels "fitted" (the sample) and "clean" (the same view through clean glass of the fit's eta,
// Fresnel at both faces), linear radiance, and "has_model" (1 where the point was fitted); one
// pixel per sampled map point, row 0 at min y.
Status RenderSlabPreview(const DmfFitOnDisk& fit, const SlabPreviewOptions& options, Image* view);

}  // namespace thinslab
