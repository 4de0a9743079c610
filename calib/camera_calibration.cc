// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/camera_calibration.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "thinslab/core/opencv_error.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"

namespace thinslab {

Status ChessboardSpec::Check() const {
  if (inner_cols < 3 || inner_rows < 3) {
    return Status::Error("chessboard: need at least 3x3 inner corners, got " + std::to_string(inner_cols) + "x" +
                         std::to_string(inner_rows));
  }
  if (!(square_m > 0) || !std::isfinite(square_m)) {
    return Status::Error("chessboard: square size must be > 0 m, got " + std::to_string(square_m));
  }
  return Status::Ok();
}

std::vector<Eigen::Vector3d> ChessboardSpec::CornersInBoard() const {
  std::vector<Eigen::Vector3d> pts;
  for (int j = 0; j < inner_rows; ++j) {
    for (int i = 0; i < inner_cols; ++i) pts.emplace_back(i * square_m, j * square_m, 0.0);
  }
  return pts;
}

Status CameraCalibrationOptions::Check() const {
  THINSLAB_RETURN_IF_ERROR(board.Check());
  if (num_distortion != 4 && num_distortion != 5) {
    return Status::Error("CameraCalibrationOptions::num_distortion: must be 4 or 5, got " +
                         std::to_string(num_distortion));
  }
  if (min_views < 2) return Status::Error("CameraCalibrationOptions::min_views: must be >= 2");
  if (subpix_half_window_px < 0) return Status::Error("CameraCalibrationOptions::subpix_half_window_px: must be >= 0");
  return Status::Ok();
}

namespace {

// Min-max scaling to 8 bits: the detectors threshold 8-bit images.
cv::Mat ToGray8(const Image& image) {
  float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
  for (size_t p = 0; p < image.num_pixels(); ++p) {
    const float v = image.data()[p * image.num_channels()];
    if (!std::isfinite(v)) continue;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  const double scale = hi > lo ? 255.0 / (hi - lo) : 0.0;
  cv::Mat gray(image.height(), image.width(), CV_8UC1);
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      const float v = image.at(x, y);
      gray.at<uint8_t>(y, x) = static_cast<uint8_t>(std::isfinite(v) ? std::lround((v - lo) * scale) : 0);
    }
  }
  return gray;
}

}  // namespace

Status DetectChessboard(const Image& image, const ChessboardSpec& board, const std::string& what,
                        std::vector<Eigen::Vector2d>* corners_px, int subpix_half_window_px) {
  THINSLAB_RETURN_IF_ERROR(board.Check());
  if (image.empty() || image.num_channels() != 1) {
    return Status::Error(what + ": expected a non-empty single-channel image");
  }
  const cv::Mat gray = ToGray8(image);
  const cv::Size pattern(board.inner_cols, board.inner_rows);
  std::vector<cv::Point2f> corners;
  bool found = cv::findChessboardCorners(gray, pattern, corners,
                                         cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
  if (found) {
    // The refinement window must stay inside one square's neighbourhood: at most ~0.4 of the
    // smallest corner spacing, capped at OpenCV's customary 11 px half-size.
    double min_spacing = std::numeric_limits<double>::max();
    for (int j = 0; j < board.inner_rows; ++j) {
      for (int i = 0; i + 1 < board.inner_cols; ++i) {
        const int k = j * board.inner_cols + i;
        min_spacing = std::min(min_spacing, static_cast<double>(cv::norm(corners[k + 1] - corners[k])));
      }
    }
    const int half = subpix_half_window_px > 0 ? subpix_half_window_px
                                               : std::clamp(static_cast<int>(0.4 * min_spacing), 2, 11);
    cv::cornerSubPix(gray, corners, cv::Size(half, half), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
  } else {
    // The sector-based detector copes with blur and low contrast where the classic one fails;
    // its corners are already sub-pixel.
    found = cv::findChessboardCornersSB(gray, pattern, corners, cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_ACCURACY);
  }
  if (!found || corners.size() != static_cast<size_t>(board.inner_cols * board.inner_rows)) {
    return Status::Error(what + ": chessboard with " + std::to_string(board.inner_cols) + "x" +
                         std::to_string(board.inner_rows) + " inner corners not found");
  }
  corners_px->clear();
  for (const cv::Point2f& c : corners) corners_px->emplace_back(c.x + 0.5, c.y + 0.5);  // OpenCV -> thinslab.
  return Status::Ok();
}

Status CalibrateCameraFromCorners(const std::vector<std::vector<Eigen::Vector2d>>& corners_px,
                                  const std::vector<std::string>& names, int width_px, int height_px,
                                  const CameraCalibrationOptions& options, CameraCalibrationResult* result) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  if (names.size() != corners_px.size()) return Status::Error("calibration: one name per view needed");
  if (width_px <= 0 || height_px <= 0) return Status::Error("calibration: image size must be positive");
  if (static_cast<int>(corners_px.size()) < options.min_views) {
    return Status::Error("calibration: " + std::to_string(corners_px.size()) + " views with a detected board, need at least " +
                         std::to_string(options.min_views));
  }
  const std::vector<Eigen::Vector3d> board = options.board.CornersInBoard();
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  for (size_t v = 0; v < corners_px.size(); ++v) {
    if (corners_px[v].size() != board.size()) {
      return Status::Error("calibration: view '" + names[v] + "' has " + std::to_string(corners_px[v].size()) +
                           " corners, the board has " + std::to_string(board.size()));
    }
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    for (size_t k = 0; k < board.size(); ++k) {
      obj.emplace_back(static_cast<float>(board[k].x()), static_cast<float>(board[k].y()), 0.0f);
      img.emplace_back(static_cast<float>(corners_px[v][k].x() - 0.5), static_cast<float>(corners_px[v][k].y() - 0.5));
    }
    object_points.push_back(std::move(obj));
    image_points.push_back(std::move(img));
  }
  cv::Mat K, D, std_intrinsics, std_extrinsics, per_view_errors;
  std::vector<cv::Mat> rvecs, tvecs;
  int flags = 0;
  if (options.num_distortion == 4) flags |= cv::CALIB_FIX_K3;
  double rms = 0;
  try {
    rms = cv::calibrateCamera(object_points, image_points, cv::Size(width_px, height_px), K, D, rvecs, tvecs,
                              std_intrinsics, std_extrinsics, per_view_errors, flags,
                              cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  } catch (const cv::Exception& e) {
    return Status::Error(std::string("calibration: OpenCV calibrateCamera failed: ") + OpenCvErrorText(e));
  }
  if (!std::isfinite(rms) || K.at<double>(0, 0) <= 0 || K.at<double>(1, 1) <= 0) {
    return Status::Error("calibration: the solver did not converge (degenerate views: vary the board tilt)");
  }
  CameraCalibrationResult out;
  out.camera.width_px = width_px;
  out.camera.height_px = height_px;
  out.camera.fx_px = K.at<double>(0, 0);
  out.camera.fy_px = K.at<double>(1, 1);
  out.camera.cx_px = K.at<double>(0, 2);
  out.camera.cy_px = K.at<double>(1, 2);
  out.camera.distortion.resize(options.num_distortion);
  for (int k = 0; k < options.num_distortion; ++k) out.camera.distortion[k] = D.at<double>(0, k);
  out.fx_std_px = std_intrinsics.at<double>(0);
  out.fy_std_px = std_intrinsics.at<double>(1);
  out.cx_std_px = std_intrinsics.at<double>(2);
  out.cy_std_px = std_intrinsics.at<double>(3);
  out.distortion_std.resize(options.num_distortion);
  for (int k = 0; k < options.num_distortion; ++k) out.distortion_std[k] = std_intrinsics.at<double>(4 + k);
  out.rms_px = rms;
  out.num_views_used = static_cast<int>(corners_px.size());
  for (size_t v = 0; v < corners_px.size(); ++v) {
    CalibrationViewReport view;
    view.name = names[v];
    view.detected = true;
    view.corners_px = corners_px[v];
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object_points[v], rvecs[v], tvecs[v], K, D, projected);
    double sum2 = 0;
    for (size_t k = 0; k < projected.size(); ++k) {
      const double e = cv::norm(projected[k] - image_points[v][k]);
      sum2 += e * e;
      view.max_px = std::max(view.max_px, e);
    }
    view.rms_px = std::sqrt(sum2 / projected.size());
    cv::Mat R;
    cv::Rodrigues(rvecs[v], R);
    Eigen::Matrix3d rot;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) rot(r, c) = R.at<double>(r, c);
    }
    view.cam_from_board.rotation = Eigen::Quaterniond(rot).normalized();
    view.cam_from_board.translation = Eigen::Vector3d(tvecs[v].at<double>(0), tvecs[v].at<double>(1), tvecs[v].at<double>(2));
    out.views.push_back(std::move(view));
  }
  *result = std::move(out);
  return Status::Ok();
}

Status CalibrateCameraFromImages(const std::vector<NamedImage>& images, const CameraCalibrationOptions& options,
                                 CameraCalibrationResult* result) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  if (images.empty()) return Status::Error("calibration: no images given");
  const int width = images[0].image.width(), height = images[0].image.height();
  std::vector<CalibrationViewReport> reports;
  std::vector<std::vector<Eigen::Vector2d>> corners;
  std::vector<std::string> names;
  std::string missing;
  for (const NamedImage& named : images) {
    if (named.image.width() != width || named.image.height() != height) {
      return Status::Error(named.name + ": image is " + std::to_string(named.image.width()) + "x" +
                           std::to_string(named.image.height()) + ", the first image (" + images[0].name + ") is " +
                           std::to_string(width) + "x" + std::to_string(height));
    }
    CalibrationViewReport report;
    report.name = named.name;
    std::vector<Eigen::Vector2d> c;
    const Status s = DetectChessboard(named.image, options.board, named.name, &c, options.subpix_half_window_px);
    if (s.ok()) {
      report.detected = true;
      corners.push_back(c);
      names.push_back(named.name);
    } else {
      report.error = s.message();
      missing += (missing.empty() ? "" : ", ") + named.name;
    }
    reports.push_back(std::move(report));
  }
  if (static_cast<int>(corners.size()) < options.min_views) {
    return Status::Error("calibration: the " + std::to_string(options.board.inner_cols) + "x" +
                         std::to_string(options.board.inner_rows) + " board was found in " +
                         std::to_string(corners.size()) + " of " + std::to_string(images.size()) +
                         " images, need at least " + std::to_string(options.min_views) +
                         (missing.empty() ? std::string() : " (not found in: " + missing + ")"));
  }
  CameraCalibrationResult solved;
  THINSLAB_RETURN_IF_ERROR(CalibrateCameraFromCorners(corners, names, width, height, options, &solved));
  size_t next = 0;
  for (CalibrationViewReport& report : reports) {
    if (report.detected) report = solved.views[next++];
  }
  solved.views = std::move(reports);
  *result = std::move(solved);
  return Status::Ok();
}

Status LoadCalibrationImage(const std::string& path, Image* image) {
  if (!FileExists(path)) return Status::Error(path + ": no such file");
  const std::string lower = [&] {
    std::string s = path;
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
    return s;
  }();
  if (lower.size() > 4 && lower.compare(lower.size() - 4, 4, ".exr") == 0) {
    Image exr;
    THINSLAB_RETURN_IF_ERROR(ReadExr(path, &exr).WithContext(path));
    const int c = exr.ChannelIndex("Y");
    if (c < 0) return Status::Error(path + ": EXR has no channel 'Y'");
    *image = exr.Channel(c);
    return Status::Ok();
  }
  const std::string unreadable = UnreadableFileReason(path);
  if (!unreadable.empty()) return Status::Error(path + ": " + unreadable);
  cv::Mat m;
  try {
    m = cv::imread(path, cv::IMREAD_GRAYSCALE | cv::IMREAD_ANYDEPTH);
  } catch (const cv::Exception& e) {
    return Status::Error(path + ": cannot decode image: " + OpenCvErrorText(e));
  }
  if (m.empty()) return Status::Error(path + ": cannot decode image (not a PNG/JPEG/TIFF/EXR file?)");
  cv::Mat f;
  m.convertTo(f, CV_32F);
  Image out(f.cols, f.rows);
  for (int y = 0; y < f.rows; ++y) {
    for (int x = 0; x < f.cols; ++x) out.at(x, y) = f.at<float>(y, x);
  }
  *image = std::move(out);
  return Status::Ok();
}

}  // namespace thinslab
