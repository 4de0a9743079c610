// SPDX-License-Identifier: Apache-2.0
// Camera intrinsics and Brown-Conrady distortion from chessboard views (Zhang 2000, as in OpenCV's
// calibrateCamera, which Dai et al. 2009 Section 4.1 cite as [Zha00]): corners found by
// findChessboardCorners (findChessboardCornersSB as a fallback) and refined by cornerSubPix, then
// the joint nonlinear least-squares over intrinsics, distortion and one pose per view. Reports
// the RMS reprojection error, the RMS per view and the standard deviations of the intrinsics
// (from the Jacobian at the optimum, scaled by the residual variance).
//
// Pixel coordinates in this interface follow thinslab (centres at +0.5); cx_px, cy_px in
// CameraInfo keep OpenCV's integer-centre convention (core/session.h).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

// Inner-corner counts of a printed chessboard and its square size. Board frame: the board is
// z = 0, inner corner (i, j) at (i, j, 0) * square_m (OpenCV's object-point order, row-major
// with inner_cols corners per row).
struct ChessboardSpec {
  int inner_cols = 9;
  int inner_rows = 6;
  double square_m = 0.025;
  Status Check() const;
  std::vector<Eigen::Vector3d> CornersInBoard() const;
};

// Finds the inner corners of `board` in a single-channel image of any scale (raw DN, float
// radiance or 8-bit grey; it is min-max scaled to 8 bits for detection). Corners are returned in
// thinslab pixel coordinates, in OpenCV's order (the board's 180-degree ambiguity is not
// resolved here: see plane_pose.h). Error "board not found" names `what`.
// `subpix_half_window_px`: cornerSubPix half-size; 0 picks 0.4 x the smallest corner spacing
// (2 to 11 px), which keeps the window inside the neighbouring squares.
Status DetectChessboard(const Image& image, const ChessboardSpec& board, const std::string& what,
                        std::vector<Eigen::Vector2d>* corners_px, int subpix_half_window_px = 0);

struct CameraCalibrationOptions {
  ChessboardSpec board;
  int num_distortion = 5;  // 4 (k1, k2, p1, p2) or 5 (+ k3).
  int min_views = 3;       // Fewer detected boards than this is an error.
  int subpix_half_window_px = 0;  // 0 = adaptive (DetectChessboard).
  Status Check() const;
};

struct CalibrationViewReport {
  std::string name;           // File name or label.
  bool detected = false;
  std::string error;          // Why the board was not found, if !detected.
  double rms_px = 0;          // RMS reprojection error of this view's corners, px.
  double max_px = 0;          // Largest corner reprojection error of this view, px.
  Rigid3d cam_from_board;     // Estimated pose of the board for this view.
  std::vector<Eigen::Vector2d> corners_px;  // Detected corners (thinslab pixel coordinates).
};

struct CameraCalibrationResult {
  // Intrinsics and distortion (id, pose and sensor fields are left default).
  CameraInfo camera;
  // Standard deviations (1 sigma) in the same units: fx, fy, cx, cy in px, then the distortion
  // coefficients (unitless) in CameraInfo::distortion order.
  double fx_std_px = 0, fy_std_px = 0, cx_std_px = 0, cy_std_px = 0;
  std::vector<double> distortion_std;
  double rms_px = 0;  // sqrt(mean over all corners of the squared reprojection distance), px.
  int num_views_used = 0;
  std::vector<CalibrationViewReport> views;  // Every input view, detected or not, in input order.
};

// Calibrates from already detected corners (one vector per view, ChessboardSpec order, thinslab
// pixel coordinates) of a width x height camera.
Status CalibrateCameraFromCorners(const std::vector<std::vector<Eigen::Vector2d>>& corners_px,
                                  const std::vector<std::string>& names, int width_px, int height_px,
                                  const CameraCalibrationOptions& options, CameraCalibrationResult* result);

struct NamedImage {
  std::string name;
  Image image;  // Single channel.
};

// Detects the board in every image (all images must share one size) and calibrates from those
// where it was found. Views without a board are listed in `result->views` with the reason; fewer
// than options.min_views detections is an error listing them.
Status CalibrateCameraFromImages(const std::vector<NamedImage>& images, const CameraCalibrationOptions& options,
                                 CameraCalibrationResult* result);

// Loads a calibration photograph as one grey channel: 8/16-bit PNG, JPEG, TIFF, ... through
// OpenCV, or a single-channel EXR frame (channel "Y"). Errors name the file.
Status LoadCalibrationImage(const std::string& path, Image* image);

}  // namespace thinslab
