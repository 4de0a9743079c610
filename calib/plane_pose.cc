// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/plane_pose.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "thinslab/core/opencv_error.h"
#include "thinslab/core/camera_model.h"

namespace thinslab {

namespace {

cv::Mat CameraMatrix(const CameraInfo& camera) {
  return (cv::Mat_<double>(3, 3) << camera.fx_px, 0, camera.cx_px, 0, camera.fy_px, camera.cy_px, 0, 0, 1);
}

cv::Mat DistortionVector(const CameraInfo& camera) {
  cv::Mat d(1, 5, CV_64F, cv::Scalar(0));
  for (size_t k = 0; k < camera.distortion.size() && k < 5; ++k) d.at<double>(0, static_cast<int>(k)) = camera.distortion[k];
  return d;
}

Rigid3d FromRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d rot;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rot(r, c) = R.at<double>(r, c);
  }
  Rigid3d out;
  out.rotation = Eigen::Quaterniond(rot).normalized();
  out.translation = Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  return out;
}

}  // namespace

Status EstimatePlanePose(const CameraInfo& camera, const std::vector<Eigen::Vector3d>& points_in_plane,
                         const std::vector<Eigen::Vector2d>& pixels, PlanePoseResult* result) {
  if (points_in_plane.size() != pixels.size()) return Status::Error("plane pose: points and pixels differ in number");
  if (points_in_plane.size() < 4) {
    return Status::Error("plane pose: need at least 4 target points, got " + std::to_string(points_in_plane.size()));
  }
  if (!(camera.fx_px > 0) || !(camera.fy_px > 0)) {
    return Status::Error("plane pose: camera '" + camera.id + "' has no intrinsics (run `thinslab calib camera` first)");
  }
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  for (size_t k = 0; k < pixels.size(); ++k) {
    if (std::abs(points_in_plane[k].z()) > 1e-12) return Status::Error("plane pose: target points must have z = 0");
    obj.emplace_back(points_in_plane[k].x(), points_in_plane[k].y(), 0.0);
    img.emplace_back(pixels[k].x() - 0.5, pixels[k].y() - 0.5);  // thinslab -> OpenCV pixel centres.
  }
  const cv::Mat K = CameraMatrix(camera), D = DistortionVector(camera);
  cv::Mat rvec, tvec;
  try {
    if (!cv::solvePnP(obj, img, K, D, rvec, tvec, false, cv::SOLVEPNP_IPPE)) {
      return Status::Error("plane pose: solvePnP found no pose (target degenerate or seen edge-on)");
    }
    cv::solvePnPRefineLM(obj, img, K, D, rvec, tvec,
                         cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-12));
  } catch (const cv::Exception& e) {
    return Status::Error(std::string("plane pose: OpenCV failed: ") + OpenCvErrorText(e));
  }
  std::vector<cv::Point2d> projected;
  cv::Mat jacobian;
  cv::projectPoints(obj, rvec, tvec, K, D, projected, jacobian);
  const int n = static_cast<int>(obj.size());
  double ssr = 0, worst = 0;
  for (int k = 0; k < n; ++k) {
    const double e = cv::norm(projected[k] - img[k]);
    ssr += e * e;
    worst = std::max(worst, e);
  }
  // First-order covariance of (rvec, t): residual variance per coordinate times (J^T J)^-1.
  Eigen::MatrixXd J(2 * n, 6);
  for (int r = 0; r < 2 * n; ++r) {
    for (int c = 0; c < 6; ++c) J(r, c) = jacobian.at<double>(r, c);
  }
  const Eigen::Matrix<double, 6, 6> JtJ = J.transpose() * J;
  Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(JtJ);
  if (!lu.isInvertible()) return Status::Error("plane pose: pose is not determined by the target (degenerate geometry)");
  const double sigma2 = n > 3 ? ssr / (2 * n - 6) : 0.0;
  PlanePoseResult out;
  out.cam_from_plane = FromRvecTvec(rvec, tvec);
  out.rms_px = std::sqrt(ssr / n);
  out.max_px = worst;
  out.num_points = n;
  out.covariance = sigma2 * lu.inverse();
  for (int k = 0; k < 3; ++k) {
    out.rotation_std_rad[k] = std::sqrt(std::max(0.0, out.covariance(k, k)));
    out.translation_std_m[k] = std::sqrt(std::max(0.0, out.covariance(3 + k, 3 + k)));
  }
  if (!(out.rms_px < 1e6) || !out.cam_from_plane.translation.allFinite()) {
    return Status::Error("plane pose: solver diverged");
  }
  *result = out;
  return Status::Ok();
}

Status EstimateSamplePoseFromChessboard(const CameraInfo& camera, const Image& image, const ChessboardSpec& board,
                                        const Rigid3d& sample_from_board, PlanePoseResult* result) {
  THINSLAB_RETURN_IF_ERROR(board.Check());
  if ((board.inner_cols + board.inner_rows) % 2 == 0) {
    return Status::Error("plane pose: a " + std::to_string(board.inner_cols) + "x" + std::to_string(board.inner_rows) +
                         " chessboard (--board) looks the same after a half turn; use a board with inner_cols + "
                         "inner_rows odd (e.g. 9x6)");
  }
  if (image.width() != camera.width_px || image.height() != camera.height_px) {
    return Status::Error("plane pose: image is " + std::to_string(image.width()) + "x" + std::to_string(image.height()) +
                         ", camera '" + camera.id + "' is " + std::to_string(camera.width_px) + "x" +
                         std::to_string(camera.height_px));
  }
  std::vector<Eigen::Vector2d> corners;
  THINSLAB_RETURN_IF_ERROR(DetectChessboard(image, board, "pose target", &corners));
  const std::vector<Eigen::Vector3d> in_board = board.CornersInBoard();
  const int nc = board.inner_cols, nr = board.inner_rows;
  // The four re-labellings of OpenCV's order: identity, half turn, and the two mirrors.
  const int flips[4][2] = {{0, 0}, {1, 1}, {1, 0}, {0, 1}};
  double best_score = -std::numeric_limits<double>::infinity();
  PlanePoseResult best;
  bool any = false;
  for (const auto& flip : flips) {
    std::vector<Eigen::Vector2d> pixels(corners.size());
    for (int j = 0; j < nr; ++j) {
      for (int i = 0; i < nc; ++i) {
        const int src = (flip[1] ? nr - 1 - j : j) * nc + (flip[0] ? nc - 1 - i : i);
        pixels[j * nc + i] = corners[src];
      }
    }
    PlanePoseResult pose;
    if (!EstimatePlanePose(camera, in_board, pixels, &pose).ok()) continue;
    // The camera must be on the board's +z side.
    if (!(pose.cam_from_plane.Inverse().translation.z() > 0)) continue;
    // Colour test on the ring of squares around the inner corners: square (a, b) is black when
    // a + b is even. Score = mean(white) - mean(black), positive for the right labelling.
    CameraInfo cam = camera;
    cam.cam_from_sample = pose.cam_from_plane;
    double score = 0;
    for (int a = -1; a < nc; ++a) {
      for (int b : {-1, nr - 1}) {
        Eigen::Vector2d px;
        const Eigen::Vector3d centre((a + 0.5) * board.square_m, (b + 0.5) * board.square_m, 0);
        if (!ProjectSamplePoint(cam, centre, &px)) continue;
        const double value = image.Bilinear(px.x(), px.y());
        score += ((a + b) % 2 == 0 ? -value : value);
      }
    }
    if (!any || score > best_score) {
      best_score = score;
      best = pose;
      any = true;
    }
  }
  if (!any) return Status::Error("plane pose: no consistent pose for the detected chessboard (camera behind the board?)");
  if (!(best_score > 0)) {
    return Status::Error("plane pose: chessboard colours do not match the spec (square next to inner corner (0,0) "
                         "must be black)");
  }
  // cam_from_sample = cam_from_board * board_from_sample. The covariance stays in the camera
  // frame, so it is unchanged by a fixed board placement.
  const Rigid3d board_from_sample = sample_from_board.Inverse();
  Rigid3d cam_from_sample;
  cam_from_sample.rotation = (best.cam_from_plane.rotation * board_from_sample.rotation).normalized();
  cam_from_sample.translation = best.cam_from_plane.rotation * board_from_sample.translation + best.cam_from_plane.translation;
  best.cam_from_plane = cam_from_sample;
  *result = best;
  return Status::Ok();
}

}  // namespace thinslab
