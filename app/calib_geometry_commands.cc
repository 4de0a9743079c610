// SPDX-License-Identifier: Apache-2.0
// Placeholder until the geometric calibration commands land (issue #6).
#include <iostream>

#include "app/commands.h"

namespace thinslab {

static int NotYet(const char* what) {
  std::cerr << "thinslab calib " << what << ": not implemented yet\n";
  return 2;
}
int RunCalibCamera(int, char**) { return NotYet("camera"); }
int RunCalibPose(int, char**) { return NotYet("pose"); }
int RunCalibDots(int, char**) { return NotYet("dots"); }

}  // namespace thinslab
