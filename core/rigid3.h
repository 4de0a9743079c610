// SPDX-License-Identifier: Apache-2.0
// Rigid transform target_from_source: x_in_target = rotation * x_in_source + translation.
// Stored as a unit quaternion (w, x, y, z in JSON) and a translation in metres.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace thinslab {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& x) const { return rotation * x + translation; }
  Rigid3d Inverse() const {
    Rigid3d inv;
    inv.rotation = rotation.conjugate();
    inv.translation = -(inv.rotation * translation);
    return inv;
  }
};

// Camera looking from `eye` at `target` with `up` roughly up in the image: cam_from_world
// for the OpenCV camera frame (x right, y down, z forward).
inline Rigid3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                      const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d world_from_cam_rot;
  world_from_cam_rot.col(0) = x;
  world_from_cam_rot.col(1) = y;
  world_from_cam_rot.col(2) = z;
  Rigid3d cam_from_world;
  cam_from_world.rotation = Eigen::Quaterniond(world_from_cam_rot.transpose()).normalized();
  cam_from_world.translation = -(cam_from_world.rotation * eye);
  return cam_from_world;
}

}  // namespace thinslab
