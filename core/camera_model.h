// SPDX-License-Identifier: Apache-2.0
// OpenCV pinhole + Brown-Conrady distortion (k1, k2, p1, p2[, k3]) for CameraInfo.
// Returned pixel coordinates follow the thinslab convention: pixel (x, y) covers
// [x, x+1) x [y, y+1), so u_thinslab = u_opencv + 0.5 (docs/conventions.md).
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <vector>

#include "thinslab/core/session.h"

namespace thinslab {

// Projects a point given in the sample frame. Returns false if it is behind the camera.
inline bool ProjectSamplePoint(const CameraInfo& camera, const Eigen::Vector3d& x_in_sample,
                               Eigen::Vector2d* pixel) {
  const Eigen::Vector3d x_in_cam = camera.cam_from_sample * x_in_sample;
  if (x_in_cam.z() <= 0) return false;
  const double x = x_in_cam.x() / x_in_cam.z(), y = x_in_cam.y() / x_in_cam.z();
  const auto& d = camera.distortion;
  const double k1 = d.size() > 0 ? d[0] : 0, k2 = d.size() > 1 ? d[1] : 0;
  const double p1 = d.size() > 2 ? d[2] : 0, p2 = d.size() > 3 ? d[3] : 0;
  const double k3 = d.size() > 4 ? d[4] : 0;
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  *pixel = Eigen::Vector2d(camera.fx_px * xd + camera.cx_px + 0.5, camera.fy_px * yd + camera.cy_px + 0.5);
  return true;
}

// Brown-Conrady distortion of normalised coordinates (x, y) = (X/Z, Y/Z), the same formula as
// ProjectSamplePoint (OpenCV's model with k1, k2, p1, p2, k3).
inline Eigen::Vector2d DistortNormalized(const std::vector<double>& d, const Eigen::Vector2d& xy) {
  const double k1 = d.size() > 0 ? d[0] : 0, k2 = d.size() > 1 ? d[1] : 0;
  const double p1 = d.size() > 2 ? d[2] : 0, p2 = d.size() > 3 ? d[3] : 0;
  const double k3 = d.size() > 4 ? d[4] : 0;
  const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return Eigen::Vector2d(x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                         y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y);
}

// Inverse of DistortNormalized by Newton iterations with the analytic 2x2 Jacobian, started at
// `initial` (the distorted point if not given; a neighbouring pixel's solution makes renderers
// converge in one or two steps). Converges to < 1e-12 for real lenses inside the image.
inline Eigen::Vector2d UndistortNormalized(const std::vector<double>& d, const Eigen::Vector2d& xy_distorted,
                                           const Eigen::Vector2d* initial = nullptr) {
  const double k1 = d.size() > 0 ? d[0] : 0, k2 = d.size() > 1 ? d[1] : 0;
  const double p1 = d.size() > 2 ? d[2] : 0, p2 = d.size() > 3 ? d[3] : 0;
  const double k3 = d.size() > 4 ? d[4] : 0;
  if (k1 == 0 && k2 == 0 && p1 == 0 && p2 == 0 && k3 == 0) return xy_distorted;
  Eigen::Vector2d xy = initial ? *initial : xy_distorted;
  for (int iter = 0; iter < 20; ++iter) {
    const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
    const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2);  // d radial / d r2.
    const Eigen::Vector2d r(x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - xy_distorted.x(),
                            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - xy_distorted.y());
    if (r.squaredNorm() < 1e-26) break;
    Eigen::Matrix2d jac;
    jac(0, 0) = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x;
    jac(0, 1) = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y;
    jac(1, 0) = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y;
    jac(1, 1) = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x;
    xy -= jac.inverse() * r;
  }
  return xy;
}

// Camera-frame ray direction (z = 1) through a thinslab pixel coordinate (centres at +0.5).
// `initial`: optional starting guess for the undistorted (x, y), as in UndistortNormalized.
inline Eigen::Vector3d PixelToCameraRay(const CameraInfo& camera, const Eigen::Vector2d& pixel,
                                        const Eigen::Vector2d* initial = nullptr) {
  const Eigen::Vector2d distorted((pixel.x() - 0.5 - camera.cx_px) / camera.fx_px,
                                  (pixel.y() - 0.5 - camera.cy_px) / camera.fy_px);
  const Eigen::Vector2d xy = UndistortNormalized(camera.distortion, distorted, initial);
  return Eigen::Vector3d(xy.x(), xy.y(), 1.0);
}

}  // namespace thinslab
