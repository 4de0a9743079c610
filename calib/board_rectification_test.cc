// SPDX-License-Identifier: Apache-2.0
// BoardRectifier: the area-weighted mean of the camera pixels under a map pixel and its
// variance, checked on a nadir camera whose pixels are larger or much smaller than the map pixels.
#include "calib/board_rectification.h"

#include <gtest/gtest.h>

namespace thinslab {
namespace {

constexpr double kMapPitchM = 1e-3;
constexpr double kBoardDistanceM = 0.5;
constexpr double kCameraHeightM = 0.5;  // Above the sample plane; the board is 1 m away.

// Nadir camera over the origin (optical axis -z in the sample frame) whose pixel covers
// `footprint_m` of the board, with pixel edges on multiples of the footprint.
CameraInfo NadirCamera(double footprint_m, int size_px = 32) {
  CameraInfo camera;
  camera.id = "cam0";
  camera.width_px = camera.height_px = size_px;
  camera.fx_px = camera.fy_px = (kCameraHeightM + kBoardDistanceM) / footprint_m;
  camera.cx_px = camera.cy_px = camera.width_px / 2.0 - 0.5;
  camera.cam_from_sample.rotation = Eigen::Quaterniond(0, 1, 0, 0);  // 180 deg about x.
  camera.cam_from_sample.translation = Eigen::Vector3d(0, 0, kCameraHeightM);
  return camera;
}

BoardGrid Grid() {
  BoardGrid grid;
  grid.grid_min_m = Eigen::Vector2d(-4 * kMapPitchM, -4 * kMapPitchM);
  grid.pixel_pitch_m = kMapPitchM;
  grid.width_px = grid.height_px = 8;
  grid.plane_z_m = -kBoardDistanceM;
  grid.supersample = 4;
  return grid;
}

TEST(BoardRectifier, VarianceOfOneCameraPixelIsItsOwn) {
  const BoardRectifier rectifier(NadirCamera(2 * kMapPitchM), Grid());
  const Image variance(32, 32, 3.0f);
  const Image out = rectifier.RectifyVariance(variance);
  for (float v : out.data()) EXPECT_FLOAT_EQ(v, 3.0f);
  for (float v : rectifier.outside().data()) EXPECT_EQ(v, 0.0f);
}

// Four camera pixels per map pixel, four sub-samples each: variance / 4, where the mean of the
// sub-sample variances (Rectify) would keep it.
TEST(BoardRectifier, VarianceOfFourCameraPixelsIsAQuarter) {
  const BoardRectifier rectifier(NadirCamera(0.5 * kMapPitchM), Grid());
  Image variance(32, 32, 2.0f);
  const Image out = rectifier.RectifyVariance(variance);
  for (float v : out.data()) EXPECT_FLOAT_EQ(v, 0.5f);
  // Unequal variances: each camera pixel holds 4 of the 16 sub-samples, so the variance of the
  // mean is sum_j v_j / 16, a quarter of the mean of the sub-samples' variances.
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) variance.at(x, y) = static_cast<float>(1 + (x * 7 + y * 3) % 5);
  }
  const Image exact = rectifier.RectifyVariance(variance), mean = rectifier.Rectify(variance);
  for (size_t i = 0; i < exact.data().size(); ++i) {
    EXPECT_GT(exact.data()[i], 0.0f);
    EXPECT_NEAR(exact.data()[i], mean.data()[i] / 4, 1e-6);
  }
}

// 8 x 8 camera pixels per map pixel: every one of them counts with weight 1/64 (the map pixel
// averages all of them, not a few point samples), so a checkerboard of camera pixels rectifies
// to exactly 0.5 and the variance of independent pixels drops 64-fold.
TEST(BoardRectifier, CoarseMapPixelAveragesEveryCameraPixelUnderIt) {
  BoardGrid grid = Grid();
  grid.grid_min_m = Eigen::Vector2d(-2 * kMapPitchM, -2 * kMapPitchM);
  grid.width_px = grid.height_px = 4;
  const BoardRectifier rectifier(NadirCamera(kMapPitchM / 8, 64), grid);
  Image checker(64, 64), variance(64, 64, 1.0f);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) checker.at(x, y) = static_cast<float>((x + y) % 2);
  }
  const Image mean = rectifier.Rectify(checker), var = rectifier.RectifyVariance(variance);
  for (size_t p = 0; p < mean.num_pixels(); ++p) {
    EXPECT_EQ(rectifier.NumCameraPixels(p), 64);
    EXPECT_FLOAT_EQ(mean.data()[p], 0.5f);
    EXPECT_FLOAT_EQ(var.data()[p], 1.0f / 64);
    EXPECT_EQ(rectifier.outside().data()[p], 0.0f);
  }
}

}  // namespace
}  // namespace thinslab
