// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/pixel_trace.h"

#include <cstdio>

namespace thinslab {

Status ParsePixelTrace(const std::string& text, const std::string& option, PixelTrace* trace) {
  if (text.empty()) return Status::Ok();
  int x = -1, y = -1, used = 0;
  if (std::sscanf(text.c_str(), "%d,%d%n", &x, &y, &used) != 2 || used != static_cast<int>(text.size()) || x < 0 ||
      y < 0) {
    return Status::Error(option + " '" + text + "': expected X,Y, two non-negative integers (a map pixel)");
  }
  trace->x = x;
  trace->y = y;
  return Status::Ok();
}

Status CheckPixelTraceInside(const PixelTrace& trace, int width, int height, const std::string& option) {
  if (trace.x < 0 || (trace.x < width && trace.y < height)) return Status::Ok();
  return Status::Error(option + " " + std::to_string(trace.x) + "," + std::to_string(trace.y) + " is outside the " +
                       std::to_string(width) + " x " + std::to_string(height) + " map");
}

}  // namespace thinslab
