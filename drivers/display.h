// SPDX-License-Identifier: Apache-2.0
// Light-source interfaces: a projector/monitor showing named patterns. "" switches it off
// (black). Real back-end: the SDL2 pattern window; simulated: sim/SimProjector.
#pragma once

#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

class Projector {
 public:
  virtual ~Projector() = default;
  // Shows `pattern` ("flat", "" for off, or a generator id) and waits until it is settled.
  virtual Status ShowPattern(const std::string& pattern) = 0;
  // Refresh period of the display in seconds (0 if not a scanned display), so exposures can be
  // chosen as whole multiples of it.
  virtual double refresh_period_s() const { return 0; }
};

}  // namespace thinslab
