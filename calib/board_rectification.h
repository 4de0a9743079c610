// SPDX-License-Identifier: Apache-2.0
// Rectification of camera images onto a plane parallel to the sample (the board at
// z = -distance in the sample frame): map pixel (i, j) is the plane point
// (grid_min + (i + 0.5, j + 0.5) * pitch, -distance). Resampling is area-weighted: each map
// pixel averages n x n sub-samples, each taking the camera pixel it falls in, so no
// interpolation blur is added and every camera pixel counts in proportion to the area it covers.
#pragma once

#include <vector>

#include "core/image.h"
#include "core/session.h"

namespace thinslab {

struct BoardGrid {
  Eigen::Vector2d grid_min_m = Eigen::Vector2d::Zero();
  double pixel_pitch_m = 0;
  int width_px = 0;
  int height_px = 0;
  double plane_z_m = 0;  // z of the plane in the sample frame (the board: -distance).
  int supersample = 4;
};

// Precomputed camera pixel of every sub-sample; -1 where it falls outside the image.
class BoardRectifier {
 public:
  BoardRectifier(const CameraInfo& camera, const BoardGrid& grid);

  // Mean of `image` (camera-sized, single channel) over each map pixel.
  Image Rectify(const Image& image) const;
  // Variance of Rectify(image) given the per-camera-pixel `variance` of independent pixels:
  // sum over the distinct camera pixels j of (c_j / n)^2 variance_j, where c_j of the n
  // sub-samples fall in pixel j.
  Image RectifyVariance(const Image& variance) const;
  // 1 where any sub-sample of the map pixel hits a non-zero pixel of `mask`.
  Image RectifyAny(const Image& mask) const;
  // 1 where a sub-sample falls outside the camera image.
  const Image& outside() const { return outside_; }
  const BoardGrid& grid() const { return grid_; }

 private:
  BoardGrid grid_;
  int camera_width_px_ = 0;
  std::vector<int> sample_pixel_;  // (map pixel, sub-sample) -> camera pixel index or -1.
  Image outside_;
};

}  // namespace thinslab
