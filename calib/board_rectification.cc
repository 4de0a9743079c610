// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/board_rectification.h"

#include <glog/logging.h>

#include <algorithm>
#include <cmath>

#include "thinslab/core/camera_model.h"
#include "thinslab/core/math.h"

namespace thinslab {

namespace {

// Longest side, in camera pixels, of the image of the map pixel's square (its projected
// corners); 0 if a corner does not project.
double FootprintSidePx(const CameraInfo& camera, const BoardGrid& grid, int i, int j) {
  Eigen::Vector2d uv[4];
  for (int c = 0; c < 4; ++c) {
    const Eigen::Vector3d corner(grid.grid_min_m.x() + (i + c % 2) * grid.pixel_pitch_m,
                                 grid.grid_min_m.y() + (j + c / 2) * grid.pixel_pitch_m, grid.plane_z_m);
    if (!ProjectSamplePoint(camera, corner, &uv[c])) return 0;
  }
  const double side =
      std::max({(uv[1] - uv[0]).norm(), (uv[3] - uv[2]).norm(), (uv[2] - uv[0]).norm(), (uv[3] - uv[1]).norm()});
  return std::isfinite(side) ? std::min(side, 1e6) : 0.0;  // int-convertible; NaN: seen as outside.
}

}  // namespace

BoardRectifier::BoardRectifier(const CameraInfo& camera, const BoardGrid& grid)
    : grid_(grid), camera_width_px_(camera.width_px) {
  CHECK_GT(grid.width_px, 0);
  CHECK_GT(grid.height_px, 0);
  CHECK_GE(grid.supersample, 1);
  const int w = grid.width_px, h = grid.height_px;
  outside_ = Image(w, h);
  offsets_.assign(1, 0);
  offsets_.reserve(static_cast<size_t>(w) * h + 1);
  std::vector<int> hits;
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const double side_px = grid.average_footprint ? FootprintSidePx(camera, grid, i, j) : 0.0;
      const int s =
          std::min(kMaxSubsamplesPerSide,
                   std::max(grid.supersample, static_cast<int>(std::ceil(kSubsamplesPerCameraPixel * side_px))));
      hits.clear();
      for (int a = 0; a < s; ++a) {
        for (int b = 0; b < s; ++b) {
          const Eigen::Vector3d x_in_sample(grid.grid_min_m.x() + (i + (b + 0.5) / s) * grid.pixel_pitch_m,
                                            grid.grid_min_m.y() + (j + (a + 0.5) / s) * grid.pixel_pitch_m,
                                            grid.plane_z_m);
          Eigen::Vector2d uv;
          // Written so that a NaN pixel (a board at 1e308 m) counts as outside.
          if (!ProjectSamplePoint(camera, x_in_sample, &uv) || !(uv.x() >= 0 && uv.y() >= 0 &&
                                                                 uv.x() < camera.width_px && uv.y() < camera.height_px)) {
            outside_.at(i, j) = 1;
            continue;
          }
          hits.push_back(static_cast<int>(uv.y()) * camera.width_px + static_cast<int>(uv.x()));
        }
      }
      std::sort(hits.begin(), hits.end());
      for (size_t k = 0; k < hits.size();) {
        size_t end = k;
        while (end < hits.size() && hits[end] == hits[k]) ++end;
        camera_pixel_.push_back(hits[k]);
        weight_.push_back(static_cast<float>(static_cast<double>(end - k) / hits.size()));
        k = end;
      }
      offsets_.push_back(static_cast<int>(camera_pixel_.size()));
    }
  }
}

Image BoardRectifier::Rectify(const Image& image) const {
  CHECK_EQ(image.width(), camera_width_px_);
  Image out(grid_.width_px, grid_.height_px);
  for (size_t p = 0; p < out.num_pixels(); ++p) {
    double sum = 0;
    for (int e = offsets_[p]; e < offsets_[p + 1]; ++e) sum += weight_[e] * image.data()[camera_pixel_[e]];
    out.data()[p] = static_cast<float>(sum);
  }
  return out;
}

Image BoardRectifier::RectifyVariance(const Image& variance) const {
  CHECK_EQ(variance.width(), camera_width_px_);
  Image out(grid_.width_px, grid_.height_px);
  for (size_t p = 0; p < out.num_pixels(); ++p) {
    double sum = 0;
    for (int e = offsets_[p]; e < offsets_[p + 1]; ++e) sum += Sqr(weight_[e]) * variance.data()[camera_pixel_[e]];
    out.data()[p] = static_cast<float>(sum);
  }
  return out;
}

Image BoardRectifier::RectifyAny(const Image& mask) const {
  CHECK_EQ(mask.width(), camera_width_px_);
  Image out(grid_.width_px, grid_.height_px);
  for (size_t p = 0; p < out.num_pixels(); ++p) {
    for (int e = offsets_[p]; e < offsets_[p + 1]; ++e) {
      if (mask.data()[camera_pixel_[e]] != 0) {
        out.data()[p] = 1;
        break;
      }
    }
  }
  return out;
}

Image CameraFootprintM(const CameraInfo& camera, const BoardGrid& grid) {
  Image out(grid.width_px, grid.height_px);
  for (int j = 0; j < grid.height_px; ++j) {
    for (int i = 0; i < grid.width_px; ++i) {
      Eigen::Vector2d uv[4];  // Corners in order around the square.
      bool ok = true;
      for (int c = 0; c < 4 && ok; ++c) {
        const int dx = (c == 1 || c == 2) ? 1 : 0, dy = c >= 2 ? 1 : 0;
        const Eigen::Vector3d corner(grid.grid_min_m.x() + (i + dx) * grid.pixel_pitch_m,
                                     grid.grid_min_m.y() + (j + dy) * grid.pixel_pitch_m, grid.plane_z_m);
        ok = ProjectSamplePoint(camera, corner, &uv[c]);
      }
      if (!ok) continue;
      double area = 0;  // Shoelace formula over the projected quadrilateral.
      for (int c = 0; c < 4; ++c) {
        const Eigen::Vector2d& a = uv[c];
        const Eigen::Vector2d& b = uv[(c + 1) % 4];
        area += a.x() * b.y() - b.x() * a.y();
      }
      area = std::abs(area) / 2;
      if (area > 0 && std::isfinite(area)) out.at(i, j) = static_cast<float>(grid.pixel_pitch_m / std::sqrt(area));
    }
  }
  return out;
}

bool CameraRayOnPlane(const CameraInfo& camera, const Eigen::Vector2d& pixel, double plane_z_m, Eigen::Vector2d* xy) {
  const Rigid3d sample_from_cam = camera.cam_from_sample.Inverse();
  const Eigen::Vector3d eye = sample_from_cam.translation;
  const Eigen::Vector3d ray = sample_from_cam.rotation * PixelToCameraRay(camera, pixel);
  if (!(std::abs(ray.z()) > 1e-12)) return false;
  const double along = (plane_z_m - eye.z()) / ray.z();
  if (!(along > 0)) return false;
  *xy = (eye + along * ray).head<2>();
  return true;
}

std::vector<int> MapPixelOfCameraPixels(const CameraInfo& camera, const BoardGrid& grid, int subsamples) {
  const int n = std::max(1, subsamples);
  std::vector<int> cell(static_cast<size_t>(camera.width_px) * camera.height_px * n * n, -1);
  for (int v = 0; v < camera.height_px; ++v) {
    for (int u = 0; u < camera.width_px; ++u) {
      for (int s = 0; s < n; ++s) {
        for (int t = 0; t < n; ++t) {
          Eigen::Vector2d x;
          if (!CameraRayOnPlane(camera, Eigen::Vector2d(u + (t + 0.5) / n, v + (s + 0.5) / n), grid.plane_z_m, &x)) {
            continue;
          }
          const double col = std::floor((x.x() - grid.grid_min_m.x()) / grid.pixel_pitch_m);
          const double row = std::floor((x.y() - grid.grid_min_m.y()) / grid.pixel_pitch_m);
          if (!(col >= 0 && row >= 0 && col < grid.width_px && row < grid.height_px)) continue;
          const size_t k = static_cast<size_t>(v) * camera.width_px + u;
          cell[(k * n + s) * n + t] = static_cast<int>(row) * grid.width_px + static_cast<int>(col);
        }
      }
    }
  }
  return cell;
}

}  // namespace thinslab
