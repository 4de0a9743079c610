// SPDX-License-Identifier: Apache-2.0
// Geometric calibration (issue #6; docs/models/geometric_calibration.md), without CLI or device
// code: what `thinslab calib camera|pose|dots` run. Each writes its section of rig.json (keeping
// the others) and a text report, atomically, and logs the report to `log`; warnings go to stderr.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "thinslab/calib/camera_calibration.h"
#include "thinslab/calib/dot_geometry.h"
#include "thinslab/calib/plane_pose.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/status.h"

namespace thinslab {

// `calib camera`: intrinsics and distortion from chessboard photographs -> OUT/rig.json,
// camera_calibration.txt, camera_views.csv.
struct CalibCameraRun {
  std::vector<std::string> images;  // Image files, or
  std::string images_dir;           // a folder of them (PNG/JPEG/TIFF/BMP/EXR/PGM).
  CameraCalibrationOptions options;  // options.board: the chessboard.
  std::string out_dir = ".";
  std::string camera_id = "cam0";   // Written to rig.json.
  std::string options_ini;          // The effective options, for rig.json's provenance.
};
Status CalibrateCamera(const CalibCameraRun& run, std::ostream& log, CameraCalibrationResult* result);

// `calib pose`: cam_from_sample from chessboard frames lying on the sample plane ->
// SESSION/calib/rig.json, pose_report.txt.
struct CalibPoseRun {
  std::string session_dir;
  ChessboardSpec board;
  Rigid3d sample_from_board;     // Inner corner (0, 0) in the sample frame.
  std::string kind = "target";   // Frame kind holding the chessboard.
  std::string rig_path;          // Intrinsics; "" = SESSION/calib/rig.json.
  bool allow_incomplete_capture = false;
  std::string options_ini;  // The effective options, for rig.json's provenance.
};
Status CalibratePose(const CalibPoseRun& run, std::ostream& log);

// `calib dots`: the monitor's dot positions and radiances from an all-dots frame without the
// sample -> SESSION/calib/rig.json, dots.csv, dots_report.txt.
struct CalibDotsRun {
  std::string session_dir;
  DotGeometryOptions options;
  double dot_radius_px = 0;      // 0 = rig.monitor.dot_radius_px, else 2 px with a warning.
  std::string kind = "all_dots";
  std::string rig_path;          // Intrinsics and pose; "" = SESSION/calib/rig.json.
  std::string response_path;     // "" = SESSION/calib/response.json if present; "linear".
  bool allow_incomplete_capture = false;
  std::string options_ini;  // The effective options, for rig.json's provenance.
};
Status CalibrateDots(const CalibDotsRun& run, std::ostream& log);

}  // namespace thinslab
