// SPDX-License-Identifier: Apache-2.0
// The smallest valid capture header, for tests and benchmarks of the session bookkeeping: one
// 8 x 6 px 12-bit camera "cam0" and a 2 x 2 mm sample region.
#pragma once

#include <string>

#include "thinslab/core/session.h"

namespace thinslab {

inline CameraInfo TinyCamera(const std::string& model = "test") {
  CameraInfo c;
  c.id = "cam0";
  c.model = model;
  c.width_px = 8;
  c.height_px = 6;
  c.fx_px = c.fy_px = 10;
  c.cx_px = 3.5;
  c.cy_px = 2.5;
  c.bit_depth = 12;
  c.saturation_dn = 4095;
  return c;
}

inline Session TinySessionHeader(const std::string& kind, const CameraInfo& camera = TinyCamera()) {
  Session header;
  header.name = "tiny";
  header.kind = kind;
  header.rig.cameras = {camera};
  header.rig.sample.region_min_m = Eigen::Vector2d(-1e-3, -1e-3);
  header.rig.sample.region_max_m = Eigen::Vector2d(1e-3, 1e-3);
  header.rig.sample.pixel_pitch_m = 1e-4;
  return header;
}

}  // namespace thinslab
