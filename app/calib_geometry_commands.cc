// SPDX-License-Identifier: Apache-2.0
// Geometric calibration commands (issue #6; docs/models/geometric_calibration.md):
//   thinslab calib camera IMAGES... | --images DIR   intrinsics + distortion -> OUT/rig.json
//   thinslab calib pose SESSION                        cam_from_sample from "target" frames
//   thinslab calib dots SESSION                        monitor dot positions and radiances
// Each writes its section of rig.json (keeping the others) and a text report, atomically
// (pipeline/geometric_calibration.h runs them; this file parses their options).
#include <cstdio>
#include <iostream>
#include <vector>

#include "thinslab/app/calibration_options.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/pipeline/geometric_calibration.h"

namespace thinslab {

namespace {

// "9x6" -> inner corners.
Status ParseBoard(const std::string& text, double square_mm, ChessboardSpec* board) {
  int cols = 0, rows = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &cols, &x, &rows, &extra) != 3 || (x != 'x' && x != 'X')) {
    return Status::Error("--board: expected <inner_cols>x<inner_rows> such as 9x6, got '" + text + "'");
  }
  board->inner_cols = cols;
  board->inner_rows = rows;
  board->square_m = square_mm * 1e-3;
  return board->Check().WithContext("--board/--square-mm");
}

}  // namespace

int RunCalibCamera(int argc, char** argv) {
  CalibCameraRun run;
  std::string board_text = "9x6";
  std::string &images_dir = run.images_dir, &out_dir = run.out_dir, &camera_id = run.camera_id;
  double square_mm = 25;
  CameraCalibrationOptions& options = run.options;
  OptionParser parser("calib camera");
  parser.AddPositionalList("IMAGES", &run.images, "calibration photographs of the chessboard");
  parser.AddString("images", &images_dir, "folder of calibration photographs (instead of listing IMAGES...)");
  parser.AddString("board", &board_text, "inner corners <cols>x<rows> of the chessboard");
  parser.AddDouble("square-mm", &square_mm, "chessboard square size [mm]");
  parser.AddInt("distortion-coeffs", &options.num_distortion, "4 (k1 k2 p1 p2) or 5 (+ k3)");
  parser.AddInt("min-views", &options.min_views, "fewest views with a detected board");
  parser.AddInt("subpix-window-px", &options.subpix_half_window_px, "cornerSubPix half-window [px]; 0 = adaptive");
  parser.AddString("camera-id", &camera_id, "camera id written to rig.json");
  parser.AddString("out", &out_dir, "output folder for rig.json and the reports");
  parser.SetUsageLine("usage: thinslab calib camera IMAGES... | --images DIR [options]");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = ParseBoard(board_text, square_mm, &options.board);
  CameraCalibrationResult result;
  run.options_ini = parser.ToIni();
  if (status.ok()) status = CalibrateCamera(run, std::cout, &result);
  if (!status.ok()) return CommandFailed(status);
  return 0;
}

int RunCalibPose(int argc, char** argv) {
  std::string session_dir, board_text = "9x6", rig_path, offset_text = "0,0,0", kind = "target";
  double square_mm = 25;
  OptionParser parser("calib pose");
  parser.AddPositional("SESSION", &session_dir, "capture session with a chessboard frame on the sample plane");
  parser.AddString("board", &board_text, "inner corners <cols>x<rows> (inner_cols + inner_rows must be odd)");
  parser.AddDouble("square-mm", &square_mm, "chessboard square size [mm]");
  parser.AddString("board-offset-mm", &offset_text, "x,y,z of inner corner (0,0) in the sample frame [mm]");
  parser.AddString("kind", &kind, "frame kind holding the target");
  parser.AddString("rig", &rig_path, "rig.json with the camera intrinsics (default SESSION/calib/rig.json)");
  CalibPoseRun run;
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = ParseBoard(board_text, square_mm, &run.board);
  double ox = 0, oy = 0, oz = 0;
  char extra = 0;
  if (status.ok() && std::sscanf(offset_text.c_str(), "%lf,%lf,%lf%c", &ox, &oy, &oz, &extra) != 3) {
    status = Status::Error("--board-offset-mm: expected x,y,z, got '" + offset_text + "'");
  }
  run.sample_from_board.translation = Eigen::Vector3d(ox, oy, oz) * 1e-3;
  run.session_dir = session_dir;
  run.kind = kind;
  run.rig_path = rig_path;
  run.options_ini = parser.ToIni();
  if (status.ok()) status = CalibratePose(run, std::cout);
  if (!status.ok()) return CommandFailed(status);
  return 0;
}

int RunCalibDots(int argc, char** argv) {
  CalibDotsRun run;
  std::string &session_dir = run.session_dir, &rig_path = run.rig_path, &kind = run.kind;
  DotGeometryOptions& options = run.options;
  OptionParser parser("calib dots");
  parser.AddPositional("SESSION", &session_dir, "dot-scan session with an all-dots frame taken without the sample");
  AddDotDetectionOptions(&parser, &options, &run.dot_radius_px);
  parser.AddString("kind", &kind, "frame kind of the all-dots frames");
  parser.AddBool("refine-distance", &options.refine_distance,
                 "set the monitor distance d from the grid's scale instead of the manifest's");
  parser.AddString("rig", &rig_path, "rig.json with intrinsics and pose (default SESSION/calib/rig.json)");
  parser.AddString("response", &run.response_path,
                   "response.json that linearises the frames, or 'linear' (default SESSION/calib/response.json if "
                   "present)");
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = CheckDotRadiusOption(parser, run.dot_radius_px);
  run.options_ini = parser.ToIni();
  if (status.ok()) status = CalibrateDots(run, std::cout);
  if (!status.ok()) return CommandFailed(status);
  return 0;
}

}  // namespace thinslab
