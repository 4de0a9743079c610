// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/render_scene.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace thinslab {

SceneCamera CameraOf(const RenderScene& scene) {
  const Rigid3d sample_from_cam = scene.cam_from_sample.Inverse();
  SceneCamera camera;
  camera.eye = sample_from_cam.translation;
  camera.target = sample_from_cam * Eigen::Vector3d(0, 0, 1);
  camera.up = -(sample_from_cam.rotation * Eigen::Vector3d(0, 1, 0));
  return camera;
}

Rigid3d CameraAbove(const SceneGrid& grid, double height_m) {
  // OpenCV camera axes in the sample frame: x along +x, y (down in the image) along -y, z (the
  // view direction) along -z.
  Eigen::Matrix3d sample_from_cam_rot;
  sample_from_cam_rot.col(0) = Eigen::Vector3d(1, 0, 0);
  sample_from_cam_rot.col(1) = Eigen::Vector3d(0, -1, 0);
  sample_from_cam_rot.col(2) = Eigen::Vector3d(0, 0, -1);
  Rigid3d sample_from_cam;
  sample_from_cam.rotation = Eigen::Quaterniond(sample_from_cam_rot);
  sample_from_cam.translation = Eigen::Vector3d(grid.centre_m().x(), grid.centre_m().y(), height_m);
  return sample_from_cam.Inverse();
}

double FramingFovX(const SceneGrid& grid, const Rigid3d& cam_from_sample, int width, int height) {
  const double aspect = static_cast<double>(width) / height;
  double half_tan_x = 0;
  for (int corner = 0; corner < 4; ++corner) {
    const Eigen::Vector3d p(grid.min_m.x() + (corner & 1) * grid.size_m().x(),
                            grid.min_m.y() + ((corner >> 1) & 1) * grid.size_m().y(), 0);
    const Eigen::Vector3d c = cam_from_sample * p;
    const double z = std::max(c.z(), 1e-9);
    half_tan_x = std::max({half_tan_x, std::abs(c.x() / z), std::abs(c.y() / z) * aspect});
  }
  return 2 * std::atan(1.1 * half_tan_x);
}

double FovY(double fov_x_rad, int width, int height) {
  return 2 * std::atan(std::tan(0.5 * fov_x_rad) * height / width);
}

}  // namespace thinslab
