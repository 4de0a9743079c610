// SPDX-License-Identifier: Apache-2.0
// OpenCV pinhole + Brown-Conrady distortion (k1, k2, p1, p2[, k3]) for CameraInfo.
// Returned pixel coordinates follow the thinslab convention: pixel (x, y) covers
// [x, x+1) x [y, y+1), so u_thinslab = u_opencv + 0.5 (docs/conventions.md).
#pragma once

#include <Eigen/Core>

#include "core/session.h"

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

}  // namespace thinslab
