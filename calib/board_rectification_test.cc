// SPDX-License-Identifier: Apache-2.0
// BoardRectifier: the area-weighted mean of the camera pixels under a map pixel and its
// variance, checked on a nadir camera whose pixels are larger or much smaller than the map pixels;
// then metric accuracy and area weighting under an oblique camera with lens distortion.
#include "thinslab/calib/board_rectification.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "thinslab/calib/camera_calibration.h"
#include "thinslab/core/camera_model.h"
#include "thinslab/core/math.h"
#include "thinslab/sim/sim_chessboard.h"

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

// The inverse map: a nadir camera pixel covering 2 x 2 map pixels sends its 2 x 2 sub-pixel rays
// to four different map pixels, every map pixel is hit exactly once, and the pixels beside the
// grid hit none.
TEST(MapPixelOfCameraPixels, SubPixelRaysTileTheGridOnce) {
  const CameraInfo camera = NadirCamera(2 * kMapPitchM);
  const std::vector<int> cells = MapPixelOfCameraPixels(camera, Grid(), 2);
  ASSERT_EQ(cells.size(), 32u * 32u * 4u);
  std::vector<int> hits(64, 0);
  int camera_pixels_on_grid = 0;
  for (int k = 0; k < 32 * 32; ++k) {
    std::set<int> distinct;
    for (int s = 0; s < 4; ++s) {
      const int c = cells[k * 4 + s];
      if (c < 0) continue;
      ASSERT_LT(c, 64);
      ++hits[c];
      distinct.insert(c);
    }
    if (!distinct.empty()) {
      ++camera_pixels_on_grid;
      EXPECT_EQ(distinct.size(), 4u) << "camera pixel " << k;
    }
  }
  EXPECT_EQ(camera_pixels_on_grid, 16);  // The 8 mm grid is 4 x 4 camera pixels.
  for (int c = 0; c < 64; ++c) EXPECT_EQ(hits[c], 1) << "map pixel " << c;
}

// The camera's footprint on the board: what one nadir camera pixel covers, whether it is larger
// (2 mm) or smaller (0.25 mm) than the 1 mm map pixel.
TEST(CameraFootprintM, IsTheBoardSideOfOneCameraPixel) {
  for (double footprint_m : {2 * kMapPitchM, 0.25 * kMapPitchM}) {
    const Image footprint = CameraFootprintM(NadirCamera(footprint_m), Grid());
    ASSERT_EQ(footprint.width(), 8);
    for (float f : footprint.data()) EXPECT_NEAR(f, footprint_m, 1e-9) << footprint_m;
  }
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

// A fine chessboard (4 mm squares, 31 x 23 inner corners) whose board frame is the sample frame
// (the plane z = 0), for the oblique tests below.
SimChessboardOptions FineBoard() {
  SimChessboardOptions board;
  board.inner_cols = 31;
  board.inner_rows = 23;
  board.square_m = 4e-3;
  return board;
}

// An OpenCV camera 0.30 m from the board centre, tilted 45 degrees from the board normal, with
// an off-centre principal point and barrel distortion (k1 = -0.2, k2 = 0.08: ~20 px at the
// image corners). Its pixels cover ~0.2 mm across and ~0.3 mm along the tilt, varying by ~1.6x
// from the near to the far edge of the board, so map pixels see trapezoids of different sizes.
CameraInfo ObliqueDistortedCamera() {
  CameraInfo cam;
  cam.id = "cam0";
  cam.width_px = 1024;
  cam.height_px = 768;
  cam.fx_px = 1450;
  cam.fy_px = 1440;
  cam.cx_px = 515.2;
  cam.cy_px = 379.8;
  cam.distortion = {-0.2, 0.08, 0, 0, 0};
  const SimChessboardOptions board = FineBoard();
  const Eigen::Vector3d target((board.inner_cols - 1) * board.square_m / 2, (board.inner_rows - 1) * board.square_m / 2,
                               0);
  const double tilt = 45 * kPi / 180;
  // Turned 20 degrees about the board normal, so the board's edges cross the pixel rows. With
  // edges along the rows the renderer's 4 x 4 point sub-samples quantise every edge to a quarter
  // pixel (up to 0.04 mm here, the same with 64 x 64 sub-samples in the rectifier); the errors
  // below were then 0.06 mm (edge locator) and 0.08 mm (cornerSubPix), from the renderer.
  const double azimuth = 20 * kPi / 180;
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(azimuth, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  cam.cam_from_sample = LookAt(target + 0.30 * turn * Eigen::Vector3d(0, -std::sin(tilt), std::cos(tilt)), target,
                               turn * Eigen::Vector3d(0, -1, 0));
  return cam;
}

// 0.25 mm map pixels over the board and its margin (-8..132 mm x -8..97 mm).
BoardGrid FineBoardGrid() {
  BoardGrid grid;
  grid.grid_min_m = Eigen::Vector2d(-8e-3, -8e-3);
  grid.pixel_pitch_m = 0.25e-3;
  grid.width_px = 560;
  grid.height_px = 420;
  grid.plane_z_m = 0;
  grid.supersample = 4;
  return grid;
}

// Median map value over the centres (middle third) of the black or the white squares.
double SquareLevel(const Image& map, const BoardGrid& grid, const SimChessboardOptions& board, bool black) {
  std::vector<float> values;
  for (int j = 0; j < grid.height_px; ++j) {
    for (int i = 0; i < grid.width_px; ++i) {
      const double a = (grid.grid_min_m.x() + (i + 0.5) * grid.pixel_pitch_m) / board.square_m;
      const double b = (grid.grid_min_m.y() + (j + 0.5) * grid.pixel_pitch_m) / board.square_m;
      if (a < -1 || b < -1 || a >= board.inner_cols || b >= board.inner_rows) continue;
      if (std::abs(a - std::floor(a) - 0.5) > 1.0 / 6 || std::abs(b - std::floor(b) - 0.5) > 1.0 / 6) continue;
      const bool is_black = (static_cast<long>(std::floor(a)) + static_cast<long>(std::floor(b))) % 2 == 0;
      if (is_black == black) values.push_back(map.at(i, j));
    }
  }
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

// Position of the board edge through inner corner `corner_m` seen in `map`: with `vertical`,
// the x of the edge x = corner.x (from map rows), else the y of the edge y = corner.y (from map
// columns); averaged over the map lines crossing the two square sides that meet at the corner,
// at least 1 mm from the corner and from the far corners. Each line's estimate is the integral
// of its normalised profile over a window of +-1.5 mm around the true edge; being an integral,
// it measures any displacement that leaves the blurred edge inside the window (~1 mm).
double EdgePosition(const Image& map, const BoardGrid& grid, const SimChessboardOptions& board,
                    const Eigen::Vector2d& corner_m, double black, double white, bool vertical) {
  const int along = vertical ? 1 : 0, across = vertical ? 0 : 1;  // Axes along and across the edge.
  const double pitch = grid.pixel_pitch_m, window_m = 1.5e-3, clear_m = 1e-3;
  // Window [first, last] of map pixels across the edge.
  const int first = static_cast<int>(std::floor((corner_m[across] - window_m - grid.grid_min_m[across]) / pitch));
  const int last = static_cast<int>(std::ceil((corner_m[across] + window_m - grid.grid_min_m[across]) / pitch)) - 1;
  const double window_end_m = grid.grid_min_m[across] + (last + 1) * pitch;
  double sum = 0;
  int lines = 0;
  for (int side = -1; side <= 1; side += 2) {
    // Square index along the edge on this side of the corner, and the colour on the low side.
    const long square_along = std::lround(corner_m[along] / board.square_m) + (side < 0 ? -1 : 0);
    const long square_low_across = std::lround(corner_m[across] / board.square_m) - 1;
    const bool low_is_black = (square_along + square_low_across) % 2 == 0;
    const double low = low_is_black ? black : white, high = low_is_black ? white : black;
    const double lo_m = side < 0 ? corner_m[along] - board.square_m + clear_m : corner_m[along] + clear_m;
    const double hi_m = side < 0 ? corner_m[along] - clear_m : corner_m[along] + board.square_m - clear_m;
    for (int k = 0; k < (vertical ? grid.height_px : grid.width_px); ++k) {
      const double centre_m = grid.grid_min_m[along] + (k + 0.5) * pitch;
      if (centre_m < lo_m || centre_m > hi_m) continue;
      double fraction_high = 0;
      for (int q = first; q <= last; ++q) {
        const float v = vertical ? map.at(q, k) : map.at(k, q);
        fraction_high += (v - low) / (high - low);
      }
      sum += window_end_m - fraction_high * pitch;
      ++lines;
    }
  }
  return sum / lines;
}

// Rectifies a rendered photograph of the fine board (blur, shot and read noise, 8-bit
// quantisation: sim/sim_chessboard.h) taken by the oblique, distorted camera, with the exact pose
// and intrinsics, and finds the inner corners in the metric map with the calibration's own
// detector (findChessboardCorners + cornerSubPix). Each must lie at its true board position:
// any error of the rectifier's geometry (pose, distortion, the half-pixel conventions of the
// camera or the map) moves the corners by its size in mm.
TEST(BoardRectifier, ObliqueDistortedCameraPutsCornersAtTheirMetricPositions) {
  const SimChessboardOptions board = FineBoard();
  const CameraInfo camera = ObliqueDistortedCamera();
  // The whole board and its margin must be seen, away from the image edges.
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(-8e-3, -8e-3), Eigen::Vector2d(132e-3, -8e-3),
                                    Eigen::Vector2d(-8e-3, 97e-3), Eigen::Vector2d(132e-3, 97e-3)}) {
    Eigen::Vector2d px;
    ASSERT_TRUE(ProjectSamplePoint(camera, Eigen::Vector3d(xy.x(), xy.y(), 0), &px));
    ASSERT_GT(px.minCoeff(), 4) << px.transpose();
    ASSERT_LT(px.x(), camera.width_px - 4) << px.transpose();
    ASSERT_LT(px.y(), camera.height_px - 4) << px.transpose();
  }
  Image photo;
  ASSERT_TRUE(RenderChessboardView(board, camera, 11, &photo).ok());
  const auto start = std::chrono::steady_clock::now();
  const BoardGrid grid = FineBoardGrid();
  const BoardRectifier rectifier(camera, grid);
  const Image map = rectifier.Rectify(photo);
  const double rectify_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (float v : rectifier.outside().data()) ASSERT_EQ(v, 0.0f);

  ChessboardSpec spec;
  spec.inner_cols = board.inner_cols;
  spec.inner_rows = board.inner_rows;
  spec.square_m = board.square_m;
  std::vector<Eigen::Vector2d> corners_px;
  const Status found = DetectChessboard(map, spec, "rectified map", &corners_px);
  ASSERT_TRUE(found.ok()) << found.message();
  // Detection order is ambiguous (mirror, half turn): match each corner to the nearest lattice
  // point, and require every lattice point to be matched once.
  std::set<std::pair<long, long>> matched;
  double worst_m = 0, sum_sq_m2 = 0;
  for (const Eigen::Vector2d& c : corners_px) {
    // Map pixel (i, j) covers [i, i + 1) x [j, j + 1) in thinslab pixel coordinates.
    const Eigen::Vector2d xy = grid.grid_min_m + c * grid.pixel_pitch_m;
    const long i = std::lround(xy.x() / board.square_m), j = std::lround(xy.y() / board.square_m);
    ASSERT_TRUE(i >= 0 && i < board.inner_cols && j >= 0 && j < board.inner_rows) << xy.transpose();
    matched.insert({i, j});
    const double error_m = (xy - Eigen::Vector2d(i, j) * board.square_m).norm();
    worst_m = std::max(worst_m, error_m);
    sum_sq_m2 += Sqr(error_m);
  }
  std::printf("oblique rectification: %zu corners, metric error rms %.4f mm, max %.4f mm (map pixel %.2f mm); "
              "rectifier %.2f s\n",
              corners_px.size(), std::sqrt(sum_sq_m2 / corners_px.size()) * 1e3, worst_m * 1e3,
              grid.pixel_pitch_m * 1e3, rectify_s);
  EXPECT_EQ(matched.size(), static_cast<size_t>(board.inner_cols * board.inner_rows));
  // Measured: max 0.028 mm, rms 0.010 mm (cornerSubPix on the noisy 8-bit map). Asserted < 0.05 mm,
  // a fifth of a map pixel; one camera pixel of pose error moves the corners by 0.2-0.4 mm.
  EXPECT_LT(worst_m, 0.05e-3);

  // Exact edge locator, free of that bias: across a straight edge, the map values normalised to
  // 0 (the level on the low side) .. 1 (the high side) sum, times the pitch, to the distance from
  // the edge to the window's far end, whatever the (symmetric or not) blur and pixel integration,
  // as long as resampling preserves area (which is what BoardRectifier claims). Per inner corner
  // (i, j): the horizontal edge y = j * square from the map columns over the two squares' sides
  // next to the corner (1 mm clear of the vertical edges), and the vertical edge likewise.
  const double black = SquareLevel(map, grid, board, true), white = SquareLevel(map, grid, board, false);
  double worst_edge_m = 0, sum_sq_edge_m2 = 0;
  for (int j = 0; j < board.inner_rows; ++j) {
    for (int i = 0; i < board.inner_cols; ++i) {
      const Eigen::Vector2d corner(i * board.square_m, j * board.square_m);
      const Eigen::Vector2d estimate(EdgePosition(map, grid, board, corner, black, white, /*vertical=*/true),
                                     EdgePosition(map, grid, board, corner, black, white, /*vertical=*/false));
      const double error_m = (estimate - corner).norm();
      worst_edge_m = std::max(worst_edge_m, error_m);
      sum_sq_edge_m2 += Sqr(error_m);
    }
  }
  std::printf("edge locator: %d corners, metric error rms %.4f mm, max %.4f mm (black %.1f, white %.1f DN)\n",
              board.inner_cols * board.inner_rows,
              std::sqrt(sum_sq_edge_m2 / (board.inner_cols * board.inner_rows)) * 1e3, worst_edge_m * 1e3, black,
              white);
  // Measured: max 0.0105 mm, rms 0.0028 mm. Asserted < 0.02 mm (< 0.1 map pixel).
  EXPECT_LT(worst_edge_m, 0.02e-3);
}

// Brute force: the mean of `image` over map pixel (i, j) from n x n point samples of the cell,
// each taking the camera pixel it projects into (the area integral as n grows).
double BruteForceCellMean(const CameraInfo& camera, const BoardGrid& grid, const Image& image, int i, int j, int n) {
  double sum = 0;
  int hits = 0;
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      const Eigen::Vector3d x(grid.grid_min_m.x() + (i + (b + 0.5) / n) * grid.pixel_pitch_m,
                              grid.grid_min_m.y() + (j + (a + 0.5) / n) * grid.pixel_pitch_m, grid.plane_z_m);
      Eigen::Vector2d uv;
      if (!ProjectSamplePoint(camera, x, &uv) || uv.x() < 0 || uv.y() < 0 || uv.x() >= image.width() ||
          uv.y() >= image.height()) {
        continue;
      }
      sum += image.at(static_cast<int>(uv.x()), static_cast<int>(uv.y()));
      ++hits;
    }
  }
  return sum / hits;
}

// Area weighting on the oblique, distorted footprint: a uniform frame rectifies to the same
// uniform map (also where a map pixel is partly outside the image), and a map pixel of random
// camera pixels equals their area-weighted mean, computed by brute force with 256 x 256
// samples per map pixel. Two maps: 0.25 mm (about one camera pixel per map pixel) and 2 mm
// (7 x 10 camera pixels, trapezoids whose size varies across the board).
TEST(BoardRectifier, ObliqueDistortedFootprintIsAreaWeighted) {
  const CameraInfo camera = ObliqueDistortedCamera();
  Image random(camera.width_px, camera.height_px);
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (float& v : random.data()) v = unit(rng);
  const Image uniform(camera.width_px, camera.height_px, 7.0f);

  // |rectified - brute force| for camera values uniform in [0, 1]. The rectifier takes
  // n x n sub-samples per map pixel (n = 4 for the fine map, ~20 for the coarse one), so the
  // shares of the camera pixels cut by a map pixel's edges are approximate: measured mean 0.012,
  // largest 0.058 (0.25 mm), mean 0.0037, largest 0.0165 (2 mm). Asserted at about twice that;
  // a map pixel point-sampled at 4 x 4 instead of averaged (footprint growth off) gives
  // 0.047 / 0.21 on the coarse map, a half-pixel shift of the camera lookup 0.15 / 0.49 on the
  // fine one, and shares normalised by all sub-samples instead of the in-image ones a map of 0.03
  // instead of 7 where a map pixel is partly outside the image.
  struct Case {
    double pitch_m;
    int size_px;
    double max_mean_error, max_error;
  };
  for (const Case& c : {Case{0.25e-3, 64, 0.025, 0.1}, Case{2e-3, 150, 0.008, 0.035}}) {
    BoardGrid grid;
    grid.pixel_pitch_m = c.pitch_m;
    grid.width_px = grid.height_px = c.size_px;
    // Centred on the board, and for the coarse map reaching past the image on every side, so
    // some map pixels are cut by the image edge.
    grid.grid_min_m = Eigen::Vector2d(0.060, 0.044) - 0.5 * c.size_px * c.pitch_m * Eigen::Vector2d::Ones();
    grid.plane_z_m = 0;
    grid.supersample = 4;
    const BoardRectifier rectifier(camera, grid);
    const Image flat = rectifier.Rectify(uniform), mean = rectifier.Rectify(random);
    int partly_outside = 0, compared = 0;
    double worst = 0, sum_abs = 0;
    for (int j = 0; j < grid.height_px; ++j) {
      for (int i = 0; i < grid.width_px; ++i) {
        const size_t p = static_cast<size_t>(j) * grid.width_px + i;
        if (rectifier.NumCameraPixels(p) == 0) continue;  // Entirely outside the image.
        EXPECT_NEAR(flat.at(i, j), 7.0f, 7.0f * 1e-6f) << i << "," << j;
        if (rectifier.outside().at(i, j) != 0) {
          ++partly_outside;
          continue;
        }
        if ((i * 7 + j * 3) % 23 != 0) continue;  // A spread subset: brute force is slow.
        const double diff = std::abs(mean.at(i, j) - BruteForceCellMean(camera, grid, random, i, j, 256));
        worst = std::max(worst, diff);
        sum_abs += diff;
        ++compared;
      }
    }
    std::printf("pitch %.2f mm: %d map pixels compared, |rectified - brute force| mean %.4f, largest %.4f, %d partly "
                "outside\n",
                c.pitch_m * 1e3, compared, sum_abs / compared, worst, partly_outside);
    EXPECT_GT(compared, 100);
    EXPECT_LT(sum_abs / compared, c.max_mean_error);
    EXPECT_LT(worst, c.max_error);
    if (c.pitch_m > 1e-3) {
      EXPECT_GT(partly_outside, 0);
    }
  }
}

}  // namespace
}  // namespace thinslab
