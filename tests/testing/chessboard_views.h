// SPDX-License-Identifier: Apache-2.0
// Rendered calibration photographs for tests: `count` views of a simulated chessboard
// (sim/sim_chessboard.h) in varied poses, named "view<k>", ready for CalibrateCameraFromImages.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "thinslab/calib/camera_calibration.h"
#include "thinslab/sim/sim_chessboard.h"

namespace thinslab {

// Poses from MakeChessboardViewPoses(seed); view k is rendered with noise seed `seed + k`.
inline std::vector<NamedImage> RenderChessboardViews(const SimChessboardOptions& options, const CameraInfo& truth,
                                                     int count, double max_tilt_deg, uint64_t seed) {
  std::vector<Rigid3d> poses;
  EXPECT_TRUE(MakeChessboardViewPoses(options, truth, count, max_tilt_deg, seed, &poses).ok());
  std::vector<NamedImage> images;
  for (size_t v = 0; v < poses.size(); ++v) {
    CameraInfo cam = truth;
    cam.cam_from_sample = poses[v];
    NamedImage named;
    named.name = "view" + std::to_string(v);
    EXPECT_TRUE(RenderChessboardView(options, cam, seed + v, &named.image).ok());
    images.push_back(std::move(named));
  }
  return images;
}

}  // namespace thinslab
