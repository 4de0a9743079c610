// SPDX-License-Identifier: Apache-2.0
// Laser interface: emission on/off. Real back-end: the libusb trigger (issue #7); simulated:
// sim/SimLaserLobeRig.
#pragma once

#include "thinslab/core/status.h"

namespace thinslab {

class Laser {
 public:
  virtual ~Laser() = default;
  virtual Status SetEmission(bool on) = 0;
};

}  // namespace thinslab
