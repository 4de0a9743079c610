// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/live_preview.h"

#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/core/rigid3.h"

namespace thinslab {
namespace {

// A camera 1 m above the sample looking straight down: 1 mm = 1 px at the image centre.
CameraInfo DownwardCamera() {
  CameraInfo camera;
  camera.id = "cam0";
  camera.width_px = 120;
  camera.height_px = 100;
  camera.fx_px = camera.fy_px = 1000;
  camera.cx_px = 59.5;
  camera.cy_px = 49.5;
  camera.bit_depth = 12;
  camera.black_level_dn = 64;
  camera.saturation_dn = 4095;
  camera.cam_from_sample = LookAt(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1, 0));
  return camera;
}

// A sharp checkerboard (4 px squares) at `contrast` of half the range, blurred over `blur` px.
Image Checkerboard(const CameraInfo& camera, double blur) {
  Image image(camera.width_px, camera.height_px);
  for (int y = 0; y < camera.height_px; ++y) {
    for (int x = 0; x < camera.width_px; ++x) {
      double sum = 0;
      int n = 0;
      for (int dy = -static_cast<int>(blur); dy <= static_cast<int>(blur); ++dy) {
        for (int dx = -static_cast<int>(blur); dx <= static_cast<int>(blur); ++dx) {
          sum += (((x + dx) / 4 + (y + dy) / 4) % 2 == 0) ? 1 : 0;
          ++n;
        }
      }
      image.at(x, y) = static_cast<float>(camera.black_level_dn + 200 + 1500 * sum / n);
    }
  }
  return image;
}

TEST(LivePreview, SaturationHistogramAndARegionOutline) {
  const CameraInfo camera = DownwardCamera();
  Image raw = Checkerboard(camera, 0);
  for (int y = 0; y < 5; ++y) {
    for (int x = 0; x < 10; ++x) raw.at(x, y) = 4095;  // 50 saturated pixels.
  }
  const PreviewStatistics statistics = MeasurePreview(raw, camera);
  EXPECT_NEAR(statistics.saturated_fraction, 50.0 / (120 * 100), 1e-12);
  EXPECT_NEAR(statistics.peak_fraction, 1.0, 1e-12);
  EXPECT_EQ(statistics.histogram[255], 50);
  RigInfo rig;
  rig.sample.region_min_m = Eigen::Vector2d(-0.02, -0.02);  // 40 x 40 px around the centre.
  rig.sample.region_max_m = Eigen::Vector2d(0.02, 0.02);
  const PreviewPicture picture = ComposePreview(raw, camera, rig, statistics, statistics.focus);
  ASSERT_EQ(picture.width, 120);
  ASSERT_EQ(picture.height, 100 + kPreviewHistogramHeight + kPreviewFocusBarHeight);
  auto is = [&](int x, int y, int r, int g, int b) {
    const uint8_t* p = picture.at(x, y);
    return p[0] == r && p[1] == g && p[2] == b;
  };
  EXPECT_TRUE(is(3, 3, 255, 0, 0));
  // The outline: the region's edges 20 mm from the centre, 20 px at 1 px/mm.
  int green_on_edges = 0, green_elsewhere = 0;
  for (int y = 0; y < 100; ++y) {
    for (int x = 0; x < 120; ++x) {
      if (!is(x, y, 0, 255, 0)) continue;
      const bool edge =
          (std::abs(x - 40) <= 1 || std::abs(x - 80) <= 1) || (std::abs(y - 30) <= 1 || std::abs(y - 70) <= 1);
      (edge ? green_on_edges : green_elsewhere)++;
    }
  }
  EXPECT_GE(green_on_edges, 150);
  EXPECT_EQ(green_elsewhere, 0);
  // Histogram foot: the saturated bin red at the right end.
  EXPECT_TRUE(is(119, 100 + kPreviewHistogramHeight - 1, 255, 0, 0));
}

// The focus measure falls as the image blurs and does not change with the exposure (scale).
TEST(LivePreview, FocusFallsWithBlurAndIgnoresTheScale) {
  const CameraInfo camera = DownwardCamera();
  const double sharp = MeasurePreview(Checkerboard(camera, 0), camera).focus;
  const double blurred = MeasurePreview(Checkerboard(camera, 2), camera).focus;
  EXPECT_LT(blurred, 0.5 * sharp);
  Image brighter = Checkerboard(camera, 0);
  for (float& v : brighter.data()) v = static_cast<float>(camera.black_level_dn + 1.5 * (v - camera.black_level_dn));
  EXPECT_NEAR(MeasurePreview(brighter, camera).focus, sharp, 1e-3 * sharp);
}

}  // namespace
}  // namespace thinslab
