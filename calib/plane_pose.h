// SPDX-License-Identifier: Apache-2.0
// Pose of a plane (the sample plane, or the board of the shadow-map rig) from a planar target
// lying on it, seen by a camera with known intrinsics and distortion: IPPE initialisation
// (cv::solvePnP, SOLVEPNP_IPPE), Levenberg-Marquardt refinement of the reprojection error, and
// the first-order covariance sigma^2 (J^T J)^-1 with sigma^2 = SSR / (2N - 6).
//
// With a pose, calib/board_rectification.h resamples any frame onto metric plane coordinates
// (area-weighted, distortion included through core/camera_model.h).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "thinslab/calib/camera_calibration.h"
#include "thinslab/core/image.h"
#include "thinslab/core/rigid3.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct PlanePoseResult {
  Rigid3d cam_from_plane;
  double rms_px = 0;  // RMS reprojection distance over the target points, px.
  double max_px = 0;
  int num_points = 0;
  // 1-sigma uncertainties: rotation as a rotation vector of cam_from_plane (rad, camera axes),
  // translation in metres (camera frame).
  Eigen::Vector3d rotation_std_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation_std_m = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();  // [rvec, t].
};

// `points_in_plane` lie on z = 0 of the plane frame; `pixels` are thinslab pixel coordinates.
// The camera's intrinsics and distortion are used; its cam_from_sample is ignored. Needs >= 4
// points; errors if the solver fails or the plane is seen edge-on.
Status EstimatePlanePose(const CameraInfo& camera, const std::vector<Eigen::Vector3d>& points_in_plane,
                         const std::vector<Eigen::Vector2d>& pixels, PlanePoseResult* result);

// Pose of the sample plane from a chessboard lying on it (board frame: camera_calibration.h;
// `sample_from_board` places it in the sample frame, e.g. a translation for the board's
// thickness and position). The camera must see the board's front (+z of the board frame).
// OpenCV's corner order is ambiguous up to mirror and a half turn; mirrors are rejected by the
// side the camera is on and the half turn by the colour of the squares: square (-1, -1) (next to
// inner corner (0, 0)) is black. This needs inner_cols + inner_rows odd (e.g. 9x6); other boards
// give an error. result->cam_from_plane is cam_from_sample.
Status EstimateSamplePoseFromChessboard(const CameraInfo& camera, const Image& image, const ChessboardSpec& board,
                                        const Rigid3d& sample_from_board, PlanePoseResult* result);

}  // namespace thinslab
