// SPDX-License-Identifier: Apache-2.0
// `thinslab calib <what>`: dispatches to the geometric (calib_geometry_commands.cc) and
// radiometric (calib_radiometry_commands.cc) calibration commands.
#include <iostream>
#include <string>

#include "thinslab/app/commands.h"
#include "thinslab/app/subcommands.h"

namespace thinslab {

const std::vector<Subcommand>& CalibSubcommands() {
  static const std::vector<Subcommand> table = {
      {"camera", RunCalibCamera, "SESSION", "intrinsics and distortion from chessboard views"},
      {"pose", RunCalibPose, "SESSION", "pose of the sample/board plane from a target on it"},
      {"dots", RunCalibDots, "SESSION", "CRT/monitor dot positions and radiances from the all-dots frame"},
      {"response", RunCalibResponse, "SESSION", "camera response from exposure brackets (Debevec, Robertson)"},
      {"hdr", RunCalibHdr, "SESSION", "merge exposure brackets into HDR radiance with variance"},
      {"flat", RunCalibFlat, "SESSION", "projector flat field for shadow maps"},
      {"gamma", RunCalibGamma, "SESSION", "display gamma table from a display_gamma session (acquire gamma)"},
  };
  return table;
}

int RunCalib(int argc, char** argv) { return DispatchSubcommand("calib", CalibSubcommands(), argc, argv); }

}  // namespace thinslab
