// SPDX-License-Identifier: Apache-2.0
// One map point followed through a per-pixel fit (`--pixel X,Y`, as pbrt's --pixel): the fit
// writes that point's data, its iterations and its result to `out`. Off unless `out` is set.
#pragma once

#include <ostream>
#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

struct PixelTrace {
  int x = -1, y = -1;
  std::ostream* out = nullptr;

  bool enabled() const { return out != nullptr && x >= 0 && y >= 0; }
  bool At(int px, int py) const { return enabled() && px == x && py == y; }
};

// "X,Y" (non-negative integers) into `trace`; "" leaves it off. Errors name `option`.
Status ParsePixelTrace(const std::string& text, const std::string& option, PixelTrace* trace);
// The traced point must lie on a width x height map.
Status CheckPixelTraceInside(const PixelTrace& trace, int width, int height, const std::string& option);

}  // namespace thinslab
