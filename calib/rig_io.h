// SPDX-License-Identifier: Apache-2.0
// calib/rig.json: the geometric calibration read by the fit stage (docs/format.md, "Geometric
// calibration files"). Three optional sections, each written by one command and preserved by
// the others: "camera" (intrinsics, distortion, their standard deviations and RMS, from
// `thinslab calib camera`), "pose" (cam_from_sample, from `thinslab calib pose`), "monitor"
// (refined monitor pose and per-dot positions and radiances, from `thinslab calib dots`).
// Each section carries the provenance of the command that wrote it (core/provenance.h's
// object; absent in files written before 2026-12-06).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "thinslab/calib/dot_geometry.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

constexpr char kRigCalibrationFormat[] = "thinslab-rig-calibration";
constexpr char kRigCalibrationVersion[] = "1.0";

struct RigCameraCalibration {
  bool present = false;
  std::string camera_id = "cam0";
  int width_px = 0, height_px = 0;
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;  // OpenCV integer-centre convention.
  std::vector<double> distortion;                       // 0, 4 or 5 coefficients.
  double fx_std_px = 0, fy_std_px = 0, cx_std_px = 0, cy_std_px = 0;
  std::vector<double> distortion_std;                   // Same length as distortion.
  double rms_reprojection_px = 0;
  int num_views = 0;
  int board_inner_cols = 0, board_inner_rows = 0;
  double board_square_m = 0;
  std::string provenance_json;  // Compact JSON object, "" if none.
};

struct RigPoseCalibration {
  bool present = false;
  Rigid3d cam_from_sample;
  double rms_reprojection_px = 0, max_reprojection_px = 0;
  int num_points = 0;
  Eigen::Vector3d rotation_std_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation_std_m = Eigen::Vector3d::Zero();
  std::string provenance_json;
};

struct RigMonitorCalibration {
  bool present = false;
  Rigid3d sample_from_monitor;  // Refined in-plane.
  double pixel_pitch_m = 0;
  int width_px = 0, height_px = 0;
  double dot_radius_px = 0;
  double rms_residual_m = 0, max_residual_m = 0, homography_rms_px = 0;
  // The grid-scale measurement of the monitor distance (DotGeometryResult; optional in the file,
  // absent before 2026-12): remaining distance error, its statistical sigma, and how far
  // `calib dots --refine-distance` moved the plane towards the camera (0: not refined).
  double grid_scale = 1, distance_error_m = 0, distance_error_sigma_m = 0, distance_correction_m = 0;
  std::vector<DotRecord> dots;
  std::string provenance_json;
};

struct RigCalibration {
  RigCameraCalibration camera;
  RigPoseCalibration pose;
  RigMonitorCalibration monitor;
};

// Reads and validates rig.json; errors name the file and the JSON field path.
Status ReadRigCalibration(const std::string& path, RigCalibration* rig);
// Writes rig.json atomically.
Status WriteRigCalibration(const std::string& path, const RigCalibration& rig);
// Reads `path` if it exists (else an empty RigCalibration), so a command can replace its own
// section and keep the others.
Status ReadRigCalibrationIfExists(const std::string& path, RigCalibration* rig);

// The manifest camera with the calibrated intrinsics/distortion and pose where present.
// Errors if the calibrated camera id or image size differs from the camera's.
Status ApplyRigCalibration(const RigCalibration& rig, CameraInfo* camera);

}  // namespace thinslab
