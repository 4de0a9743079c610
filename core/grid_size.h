// SPDX-License-Identifier: Apache-2.0
// Map grid sizes from a region and a pitch, checked before any conversion to int: a pitch of
// 1e-12 m or a region of 1e300 m gives a count no int (or memory) can hold, which must be an
// error naming the fields, not an overflowed "-1179869184x-1179869184 grid" (issue #22).
#pragma once

#include <cmath>
#include <sstream>
#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

// Largest map a fit builds in one piece: 1e8 points (a 10000 x 10000 map), several GiB of
// per-point data in every fit.
inline constexpr double kMaxMapPoints = 1e8;

enum class GridRounding { kNearest, kFloor };

// `extent_x_m` / `extent_y_m` over `pitch_m`, rounded; `where` names the fields ("CAPTURE/
// session.json: rig.sample"). Refuses a non-finite, non-positive or too large grid, or one
// smaller than `min_side`.
inline Status CheckedGridSize(double extent_x_m, double extent_y_m, double pitch_m, GridRounding rounding,
                              int min_side, const std::string& where, int* width, int* height) {
  const auto count = [&](double extent) {
    const double n = extent / pitch_m;
    return rounding == GridRounding::kNearest ? std::round(n) : std::floor(n + 1e-6);
  };
  const double w = count(extent_x_m), h = count(extent_y_m);
  std::ostringstream msg;
  msg.precision(6);
  if (!(pitch_m > 0) || !std::isfinite(pitch_m) || !std::isfinite(w) || !std::isfinite(h)) {
    msg << where << ": region (" << extent_x_m << " x " << extent_y_m << " m) and pixel pitch " << pitch_m
        << " m do not give a finite grid";
    return Status::Error(msg.str());
  }
  if (w < min_side || h < min_side) {
    msg << where << ": region (" << extent_x_m << " x " << extent_y_m << " m) at pixel pitch " << pitch_m
        << " m gives a " << w << " x " << h << " grid; at least " << min_side << " x " << min_side << " is needed";
    return Status::Error(msg.str());
  }
  if (w * h > kMaxMapPoints) {
    msg << where << ": region (" << extent_x_m << " x " << extent_y_m << " m) at pixel pitch " << pitch_m
        << " m gives a " << w << " x " << h << " grid (" << w * h << " points); at most " << kMaxMapPoints
        << " points are supported: choose a larger pitch";
    return Status::Error(msg.str());
  }
  *width = static_cast<int>(w);
  *height = static_cast<int>(h);
  return Status::Ok();
}

}  // namespace thinslab
