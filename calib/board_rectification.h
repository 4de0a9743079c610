// SPDX-License-Identifier: Apache-2.0
// Rectification of camera images onto a plane parallel to the sample (the board at
// z = -distance in the sample frame): map pixel (i, j) is the plane point
// (grid_min + (i + 0.5, j + 0.5) * pitch, -distance). Resampling is area-weighted: each map
// pixel averages n x n sub-samples, each taking the camera pixel it falls in, so no
// interpolation blur is added and every camera pixel counts in proportion to the area of the
// map pixel it covers. n = supersample where a map pixel covers at most one camera pixel; where
// it covers more, n grows with its footprint (kSubsamplesPerCameraPixel per camera pixel side,
// at most kMaxSubsamplesPerSide), so coarse maps average all the camera pixels under them
// instead of point-sampling a few; only the shares of the camera pixels cut by the map pixel's
// edges are approximate (to about 1 / (2 kSubsamplesPerCameraPixel)).
#pragma once

#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"

namespace thinslab {

struct BoardGrid {
  Eigen::Vector2d grid_min_m = Eigen::Vector2d::Zero();
  double pixel_pitch_m = 0;
  int width_px = 0;
  int height_px = 0;
  double plane_z_m = 0;  // z of the plane in the sample frame (the board: -distance).
  int supersample = 4;
  // true: n grows with the footprint (the cell average). false: n = supersample always, i.e.
  // supersample^2 point samples spread over the cell, for consumers that treat each map pixel
  // as a point (the dot-scan BTDF slices, fit/dmf_processing.h).
  bool average_footprint = true;
};

// Where the ray through camera pixel coordinate `pixel` (centres at +0.5) meets the plane
// z = plane_z_m of the sample frame: false when it runs parallel or the plane is behind the camera.
bool CameraRayOnPlane(const CameraInfo& camera, const Eigen::Vector2d& pixel, double plane_z_m, Eigen::Vector2d* xy);

// The inverse direction: for each camera pixel (row-major) and each of its n x n sub-pixel
// rays (n = `subsamples`, row-major inside the pixel), the index of the map pixel the ray meets
// on the grid's plane, or -1 (behind the camera, or off the grid): entry (k n + s) n + t.
std::vector<int> MapPixelOfCameraPixels(const CameraInfo& camera, const BoardGrid& grid, int subsamples = 1);

// The camera's footprint on the grid's plane per map pixel: the side (m) of the board square
// one camera pixel covers there, pitch / sqrt(area in camera pixels of the map pixel's
// projected square); 0 where a corner does not project. Larger than the pitch: the map is finer
// than the camera resolves (neighbouring map pixels share camera pixels).
Image CameraFootprintM(const CameraInfo& camera, const BoardGrid& grid);

// Precomputed (camera pixel, weight) lists per map pixel: the share of the map pixel's in-image
// sub-samples that fall in each camera pixel.
class BoardRectifier {
 public:
  static constexpr int kSubsamplesPerCameraPixel = 2;
  static constexpr int kMaxSubsamplesPerSide = 64;

  BoardRectifier(const CameraInfo& camera, const BoardGrid& grid);

  // Mean of `image` (camera-sized, single channel) over each map pixel.
  Image Rectify(const Image& image) const;
  // Variance of Rectify(image) given the per-camera-pixel `variance` of independent pixels:
  // sum over the distinct camera pixels j of w_j^2 variance_j, w_j the share of the map
  // pixel's sub-samples in pixel j.
  Image RectifyVariance(const Image& variance) const;
  // 1 where any sub-sample of the map pixel hits a non-zero pixel of `mask`.
  Image RectifyAny(const Image& mask) const;
  // 1 where a sub-sample falls outside the camera image.
  const Image& outside() const { return outside_; }
  const BoardGrid& grid() const { return grid_; }
  // Distinct camera pixels summed into map pixel p (for tests and memory figures).
  int NumCameraPixels(size_t p) const { return offsets_[p + 1] - offsets_[p]; }

 private:
  BoardGrid grid_;
  int camera_width_px_ = 0;
  std::vector<int> offsets_;        // Map pixel p owns entries [offsets_[p], offsets_[p + 1]).
  std::vector<int> camera_pixel_;   // Camera pixel index of each entry.
  std::vector<float> weight_;       // Its share; the shares of a map pixel sum to 1.
  Image outside_;
};

}  // namespace thinslab
