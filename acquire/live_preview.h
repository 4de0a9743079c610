// SPDX-License-Identifier: Apache-2.0
// What the live preview shows (issue #28, item 1), composed from one camera frame without any
// device code, so the same picture is drawn by the SDL window (`thinslab acquire preview`) and
// tested without one:
//  - the frame, black level removed, scaled to the camera's range with a display gamma of 2.2
//    (dim lobes stay visible), saturated pixels in red;
//  - the expected sample region (the manifest's rig.sample rectangle on the plane z = 0, and its
//    image on the board plane when there is a board), projected through the camera, in green;
//  - a histogram strip below the frame: 256 bins over the range, log counts, the last bin red;
//  - a focus bar: the frame's focus measure (mean squared Laplacian over the mean squared
//    value: scale invariant, larger when sharper) against the largest seen in this preview.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"

namespace thinslab {

inline constexpr int kPreviewHistogramHeight = 64;
inline constexpr int kPreviewFocusBarHeight = 8;

struct PreviewStatistics {
  double saturated_fraction = 0;  // Pixels at or above saturation.
  double peak_fraction = 0;       // Brightest pixel over the range.
  double mean_fraction = 0;
  double focus = 0;                // Mean squared Laplacian / mean squared value.
  std::vector<int64_t> histogram;  // 256 bins over [0, range].
  // "saturated 0.31 %, peak 100 % of range, mean 12.4 %, focus 0.0123".
  std::string Describe() const;
};

PreviewStatistics MeasurePreview(const Image& raw_dn, const CameraInfo& camera);

// An RGB8 picture, row-major, width x height x 3.
struct PreviewPicture {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
  uint8_t* at(int x, int y) { return &rgb[3 * (static_cast<size_t>(y) * width + x)]; }
  const uint8_t* at(int x, int y) const { return &rgb[3 * (static_cast<size_t>(y) * width + x)]; }
};

// The picture: the frame (camera size) above the histogram strip and the focus bar.
// `best_focus`: the largest focus measure seen so far (the bar's full length).
PreviewPicture ComposePreview(const Image& raw_dn, const CameraInfo& camera, const RigInfo& rig,
                              const PreviewStatistics& statistics, double best_focus);

}  // namespace thinslab
