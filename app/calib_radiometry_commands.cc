// SPDX-License-Identifier: Apache-2.0
// Placeholder until the radiometric calibration commands land (issue #6).
#include <iostream>

#include "app/commands.h"

namespace thinslab {

static int NotYet(const char* what) {
  std::cerr << "thinslab calib " << what << ": not implemented yet\n";
  return 2;
}
int RunCalibResponse(int, char**) { return NotYet("response"); }
int RunCalibHdr(int, char**) { return NotYet("hdr"); }
int RunCalibFlat(int, char**) { return NotYet("flat"); }

}  // namespace thinslab
