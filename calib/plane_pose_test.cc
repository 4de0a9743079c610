// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/plane_pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "thinslab/calib/board_rectification.h"
#include "thinslab/core/math.h"
#include "thinslab/sim/sim_chessboard.h"

namespace thinslab {
namespace {

// A camera 0.45 m from the sample, tilted 30 degrees, with barrel distortion.
CameraInfo TrueCamera() {
  CameraInfo cam;
  cam.id = "cam0";
  cam.width_px = 640;
  cam.height_px = 480;
  cam.fx_px = cam.fy_px = 700;
  cam.cx_px = 318.4;
  cam.cy_px = 242.7;
  cam.distortion = {-0.12, 0.05, 0, 0, 0};
  const Eigen::Vector3d target(0.1, 0.0625, 0);
  const double tilt = 30 * kPi / 180;
  cam.cam_from_sample = LookAt(target + 0.45 * Eigen::Vector3d(0, -std::sin(tilt), std::cos(tilt)), target,
                               Eigen::Vector3d(0, -1, 0));
  return cam;
}

Rigid3d Compose(const Rigid3d& a_from_b, const Rigid3d& b_from_c) {
  Rigid3d out;
  out.rotation = (a_from_b.rotation * b_from_c.rotation).normalized();
  out.translation = a_from_b * b_from_c.translation;
  return out;
}

double AngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return Eigen::AngleAxisd(a.inverse() * b).angle() * 180 / kPi;
}

TEST(PlanePoseTest, RecoversSamplePoseFromBoardOnSample) {
  const CameraInfo truth = TrueCamera();
  Rigid3d sample_from_board;
  sample_from_board.translation = Eigen::Vector3d(-0.004, 0.002, 0.003);  // 3 mm thick board, offset.
  sample_from_board.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ()));
  SimChessboardOptions sim;
  CameraInfo render_cam = truth;
  render_cam.cam_from_sample = Compose(truth.cam_from_sample, sample_from_board);
  Image image;
  ASSERT_TRUE(RenderChessboardView(sim, render_cam, 3, &image).ok());

  ChessboardSpec board;  // 9x6, 25 mm: the simulated board.
  PlanePoseResult pose;
  const Status s = EstimateSamplePoseFromChessboard(truth, image, board, sample_from_board, &pose);
  ASSERT_TRUE(s.ok()) << s.message();
  const double angle_deg = AngleDeg(pose.cam_from_plane.rotation, truth.cam_from_sample.rotation);
  const double shift_m = (pose.cam_from_plane.translation - truth.cam_from_sample.translation).norm();
  std::printf("pose: rotation error %.4f deg, translation error %.3f mm, rms %.3f px, std rot %.4f deg, std t %.3f mm\n",
              angle_deg, shift_m * 1e3, pose.rms_px, pose.rotation_std_rad.norm() * 180 / kPi,
              pose.translation_std_m.norm() * 1e3);
  // Tolerances: 0.05 degrees and 0.5 mm at 0.45 m (about 0.1 % of the distance).
  EXPECT_LT(angle_deg, 0.05);
  EXPECT_LT(shift_m, 0.5e-3);
  EXPECT_LT(pose.rms_px, 0.2);
  EXPECT_EQ(pose.num_points, 54);
  // The reported uncertainty is consistent with the actual error (within 5 sigma + 0.05 mm).
  EXPECT_GT(pose.translation_std_m.norm(), 0);
  EXPECT_LT(shift_m, 5 * pose.translation_std_m.norm() + 0.05e-3);
}

// With the estimated pose and the calibrated distortion, BoardRectifier maps the frame onto
// metric sample-plane coordinates: every 0.5 mm map pixel at least 1 mm from a square edge
// shows the right square colour.
TEST(PlanePoseTest, RectifiesOntoMetricPlane) {
  const CameraInfo truth = TrueCamera();
  SimChessboardOptions sim;
  Image image;
  ASSERT_TRUE(RenderChessboardView(sim, truth, 5, &image).ok());
  PlanePoseResult pose;
  ASSERT_TRUE(EstimateSamplePoseFromChessboard(truth, image, ChessboardSpec(), Rigid3d(), &pose).ok());
  CameraInfo calibrated = truth;
  calibrated.cam_from_sample = pose.cam_from_plane;
  BoardGrid grid;
  grid.grid_min_m = Eigen::Vector2d(-0.025, -0.025);
  grid.pixel_pitch_m = 0.5e-3;
  grid.width_px = 500;
  grid.height_px = 350;
  grid.plane_z_m = 0;
  grid.supersample = 3;
  const BoardRectifier rectifier(calibrated, grid);
  const Image map = rectifier.Rectify(image);
  const double mid = 0.5 * (sim.black_radiance + sim.white_radiance) * sim.electrons_per_radiance /
                     sim.sensor.gain_e_per_dn();
  int checked = 0, wrong = 0;
  for (int j = 0; j < grid.height_px; ++j) {
    for (int i = 0; i < grid.width_px; ++i) {
      const double x = grid.grid_min_m.x() + (i + 0.5) * grid.pixel_pitch_m;
      const double y = grid.grid_min_m.y() + (j + 0.5) * grid.pixel_pitch_m;
      const double a = x / sim.square_m, b = y / sim.square_m;
      if (a < -1 || b < -1 || a > 9 || b > 6) continue;  // Outside the squares.
      const double edge_m = std::min(std::abs(a - std::round(a)), std::abs(b - std::round(b))) * sim.square_m;
      if (edge_m < 1e-3 || rectifier.outside().at(i, j) != 0) continue;
      const bool black = (static_cast<long>(std::floor(a)) + static_cast<long>(std::floor(b))) % 2 == 0;
      ++checked;
      if ((map.at(i, j) < mid) != black) ++wrong;
    }
  }
  EXPECT_GT(checked, 20000);
  EXPECT_EQ(wrong, 0);
}

TEST(PlanePoseTest, BadInputsAreErrors) {
  const CameraInfo truth = TrueCamera();
  SimChessboardOptions sim;
  Image image;
  ASSERT_TRUE(RenderChessboardView(sim, truth, 5, &image).ok());
  PlanePoseResult pose;
  ChessboardSpec symmetric;
  symmetric.inner_cols = 7;
  symmetric.inner_rows = 5;
  Status s = EstimateSamplePoseFromChessboard(truth, image, symmetric, Rigid3d(), &pose);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("half turn"), std::string::npos) << s.message();

  CameraInfo wrong_size = truth;
  wrong_size.width_px = 800;
  EXPECT_FALSE(EstimateSamplePoseFromChessboard(wrong_size, image, ChessboardSpec(), Rigid3d(), &pose).ok());

  s = EstimateSamplePoseFromChessboard(truth, Image(640, 480, 10.0f), ChessboardSpec(), Rigid3d(), &pose);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("not found"), std::string::npos) << s.message();

  CameraInfo no_intrinsics = truth;
  no_intrinsics.fx_px = 0;
  EXPECT_FALSE(EstimatePlanePose(no_intrinsics, ChessboardSpec().CornersInBoard(),
                                 std::vector<Eigen::Vector2d>(54, Eigen::Vector2d(1, 1)), &pose).ok());
  EXPECT_FALSE(EstimatePlanePose(truth, {Eigen::Vector3d::Zero()}, {Eigen::Vector2d::Zero()}, &pose).ok());
}

}  // namespace
}  // namespace thinslab
