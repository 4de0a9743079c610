// SPDX-License-Identifier: Apache-2.0
#include "calib/board_rectification.h"

#include <glog/logging.h>

#include <algorithm>
#include <cmath>

#include "core/camera_model.h"
#include "core/math.h"

namespace thinslab {

BoardRectifier::BoardRectifier(const CameraInfo& camera, const BoardGrid& grid)
    : grid_(grid), camera_width_px_(camera.width_px) {
  CHECK_GT(grid.width_px, 0);
  CHECK_GT(grid.height_px, 0);
  CHECK_GE(grid.supersample, 1);
  const int s = grid.supersample, w = grid.width_px, h = grid.height_px;
  sample_pixel_.assign(static_cast<size_t>(w) * h * s * s, -1);
  outside_ = Image(w, h);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const size_t base = (static_cast<size_t>(j) * w + i) * s * s;
      for (int a = 0; a < s; ++a) {
        for (int b = 0; b < s; ++b) {
          const Eigen::Vector3d x_in_sample(grid.grid_min_m.x() + (i + (b + 0.5) / s) * grid.pixel_pitch_m,
                                            grid.grid_min_m.y() + (j + (a + 0.5) / s) * grid.pixel_pitch_m,
                                            grid.plane_z_m);
          Eigen::Vector2d uv;
          if (!ProjectSamplePoint(camera, x_in_sample, &uv) || uv.x() < 0 || uv.y() < 0 ||
              uv.x() >= camera.width_px || uv.y() >= camera.height_px) {
            outside_.at(i, j) = 1;
            continue;
          }
          sample_pixel_[base + a * s + b] = static_cast<int>(uv.y()) * camera.width_px + static_cast<int>(uv.x());
        }
      }
    }
  }
}

Image BoardRectifier::Rectify(const Image& image) const {
  CHECK_EQ(image.width(), camera_width_px_);
  const int s2 = grid_.supersample * grid_.supersample;
  Image out(grid_.width_px, grid_.height_px);
  for (size_t p = 0; p < out.num_pixels(); ++p) {
    double sum = 0;
    int n = 0;
    for (int k = 0; k < s2; ++k) {
      const int idx = sample_pixel_[p * s2 + k];
      if (idx < 0) continue;
      sum += image.data()[idx];
      ++n;
    }
    out.data()[p] = n > 0 ? static_cast<float>(sum / n) : 0.0f;
  }
  return out;
}

Image BoardRectifier::RectifyVariance(const Image& variance) const {
  CHECK_EQ(variance.width(), camera_width_px_);
  const int s2 = grid_.supersample * grid_.supersample;
  Image out(grid_.width_px, grid_.height_px);
  std::vector<int> pixels;
  for (size_t p = 0; p < out.num_pixels(); ++p) {
    pixels.clear();
    for (int k = 0; k < s2; ++k) {
      const int idx = sample_pixel_[p * s2 + k];
      if (idx >= 0) pixels.push_back(idx);
    }
    if (pixels.empty()) continue;
    std::sort(pixels.begin(), pixels.end());
    const double n = static_cast<double>(pixels.size());
    double sum = 0;
    for (size_t a = 0; a < pixels.size();) {
      size_t b = a;
      while (b < pixels.size() && pixels[b] == pixels[a]) ++b;
      sum += Sqr((b - a) / n) * variance.data()[pixels[a]];
      a = b;
    }
    out.data()[p] = static_cast<float>(sum);
  }
  return out;
}

Image BoardRectifier::RectifyAny(const Image& mask) const {
  CHECK_EQ(mask.width(), camera_width_px_);
  const int s2 = grid_.supersample * grid_.supersample;
  Image out(grid_.width_px, grid_.height_px);
  for (size_t p = 0; p < out.num_pixels(); ++p) {
    for (int k = 0; k < s2; ++k) {
      const int idx = sample_pixel_[p * s2 + k];
      if (idx >= 0 && mask.data()[idx] != 0) {
        out.data()[p] = 1;
        break;
      }
    }
  }
  return out;
}

}  // namespace thinslab
