// SPDX-License-Identifier: Apache-2.0
// `thinslab calib <what>`: dispatches to the geometric (calib_geometry_commands.cc) and
// radiometric (calib_radiometry_commands.cc) calibration commands.
#include <iostream>
#include <string>

#include "thinslab/app/commands.h"

namespace thinslab {

int RunCalib(int argc, char** argv) {
  struct Sub {
    const char* name;
    int (*run)(int, char**);
    const char* help;
  };
  static const Sub kSubs[] = {
      {"camera", RunCalibCamera, "intrinsics and distortion from chessboard views"},
      {"pose", RunCalibPose, "pose of the sample/board plane from a target on it"},
      {"dots", RunCalibDots, "CRT/monitor dot positions and radiances from the all-dots frame"},
      {"response", RunCalibResponse, "camera response from exposure brackets (Debevec, Robertson)"},
      {"hdr", RunCalibHdr, "merge exposure brackets into HDR radiance with variance"},
      {"flat", RunCalibFlat, "projector flat field for shadow maps"},
      {"gamma", RunCalibGamma, "display gamma table from a display_gamma session (acquire gamma)"},
  };
  const std::string what = argc > 0 ? argv[0] : "";
  for (const Sub& sub : kSubs) {
    if (what == sub.name) return sub.run(argc - 1, argv + 1);
  }
  std::string usage = "usage: thinslab calib <what> ...\n";
  for (const Sub& sub : kSubs) usage += "  " + std::string(sub.name) + std::string(10 - std::string(sub.name).size(), ' ') + sub.help + "\n";
  return SubcommandUsage("calib", what, usage);
}

}  // namespace thinslab
