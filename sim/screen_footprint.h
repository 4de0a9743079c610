// SPDX-License-Identifier: Apache-2.0
// Exact area integral of a pixelated screen over a camera (sub-)pixel's footprint. A camera pixel
// integrates the radiance over its whole area; point samples of a screen made of uniform square
// emitters alias instead: a dot of radius 2 monitor px seen by ~2 camera px with 4 x 4 point
// samples per pixel gets its integrated flux wrong by up to +-40 % depending on where its edges
// fall between the samples (15 % RMS over a dot grid), and that flux is L_q A_q of Dai et al.
// 2009 Eq. 12 for every measurement of the dot. Clipping the footprint polygon against each
// emitter square conserves the flux at any sub-pixel phase.
#pragma once

#include <Eigen/Core>

#include "thinslab/core/image.h"

namespace thinslab {

struct ScreenFootprintMean {
  double level = 0;   // Mean of `levels` over the footprint (0 outside the screen).
  double inside = 0;  // Fraction of the footprint on the screen [0, 1].
};

// The footprint is the parallelogram centre + s eu + t ev, s, t in [-1/2, 1/2], in screen pixel
// coordinates (pixel (x, y) is the square [x, x + 1) x [y, y + 1), value levels.at(x, y)).
// A degenerate footprint (zero area) takes the value at its centre.
ScreenFootprintMean MeanOverFootprint(const Image& levels, const Eigen::Vector2d& centre, const Eigen::Vector2d& eu,
                                      const Eigen::Vector2d& ev);

// Area of the convex polygon `poly` (n vertices, either orientation) inside the axis-aligned box
// [x0, x1] x [y0, y1].
double ConvexPolygonAreaInBox(const Eigen::Vector2d* poly, int n, double x0, double y0, double x1, double y1);

}  // namespace thinslab
