// SPDX-License-Identifier: Apache-2.0
// Pattern ids shown by a Projector (drivers/display.h), shared by the real SDL2 pattern window
// and the simulated displays so both agree on what "dot:10.5,20.5" means. Grammar
// (docs/drivers.md, "Display"):
//   ""                                   black (light source off)
//   "flat"                               white, level 1
//   "flat:<level>"                       uniform level in [0, 1] (gamma measurement sequence)
//   "dot:<x_px>,<y_px>"                  one dot centred at monitor pixel coordinates
//   "dots:<x0>,<y0>,<dx>,<dy>,<nx>,<ny>" an nx by ny grid of dots, first at (x0, y0)
// Coordinates follow docs/conventions.md: pixel (i, j) covers [i, i+1) x [j, j+1), so its centre
// is (i + 0.5, j + 0.5) and "dot:10.5,20.5" is centred on pixel (10, 20).
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct PatternSpec {
  enum class Kind { kBlack, kFlat, kDots };
  Kind kind = Kind::kBlack;
  double level = 0;  // kFlat: linear emitted level in [0, 1]; kDots: dot level (1).
  struct Dot {
    double x_px = 0, y_px = 0;
  };
  std::vector<Dot> dots;  // kDots only.
};

// Parses a pattern id; errors name the id and the malformed field.
Status ParsePatternId(const std::string& id, PatternSpec* spec);

// Formats ids the parser reads back exactly (shortest round-trip decimal).
std::string DotPatternId(double x_px, double y_px);
std::string FlatPatternId(double level);

// Rasterises `spec` into a width x height single-channel image of linear levels in [0, 1]
// (before display gamma). A dot is a disc of radius `dot_radius_px` integrated against a
// separable tent (bilinear) kernel at each pixel centre (anti-aliased edges, one pixel of extra
// blur), which makes the intensity centroid of an isolated, unclipped dot equal its centre
// (< 1e-4 px) and its sum the disc area (pattern_id.cc says why a plain box does not). Overlapping
// dots saturate at 1; dots partly off-screen are clipped. Errors: non-positive size, radius
// outside (0, 1000] px.
Status RasterizePattern(const PatternSpec& spec, int width, int height, double dot_radius_px,
                        Image* image);

}  // namespace thinslab
