// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/rig_io.h"

#include <gtest/gtest.h>

#include "thinslab/core/file.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

RigCalibration Example() {
  RigCalibration rig;
  rig.camera.present = true;
  rig.camera.width_px = 640;
  rig.camera.height_px = 480;
  rig.camera.fx_px = 533.123456789012;
  rig.camera.fy_px = 533.9;
  rig.camera.cx_px = 341.2;
  rig.camera.cy_px = 235.1;
  rig.camera.distortion = {-0.28, 0.1, 1e-3, -2e-4, 0.05};
  rig.camera.distortion_std = {1e-3, 2e-3, 1e-4, 1e-4, 3e-3};
  rig.camera.fx_std_px = 0.6;
  rig.camera.rms_reprojection_px = 0.19;
  rig.camera.num_views = 13;
  rig.camera.board_inner_cols = 9;
  rig.camera.board_inner_rows = 6;
  rig.camera.board_square_m = 0.025;
  rig.pose.present = true;
  rig.pose.cam_from_sample.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 0.2, 0).normalized()));
  rig.pose.cam_from_sample.translation = Eigen::Vector3d(0.01, -0.02, 0.95);
  rig.pose.num_points = 54;
  rig.pose.rotation_std_rad = Eigen::Vector3d(1e-4, 2e-4, 3e-4);
  rig.monitor.present = true;
  rig.monitor.sample_from_monitor.translation = Eigen::Vector3d(-0.05, 0.09, -0.04);
  rig.monitor.pixel_pitch_m = 0.25e-3;
  rig.monitor.width_px = 400;
  rig.monitor.height_px = 400;
  rig.monitor.dot_radius_px = 2;
  DotRecord seen;
  seen.dot_px = Eigen::Vector2d(20.5, 20.5);
  seen.detected = true;
  seen.centroid_px = Eigen::Vector2d(100.25, 200.75);
  seen.position_in_sample_m = Eigen::Vector3d(-0.045, 0.085, -0.04);
  seen.radiance_dn_per_us = 4.5;
  seen.residual_m = 1e-5;
  DotRecord missed;
  missed.dot_px = Eigen::Vector2d(40.5, 20.5);
  rig.monitor.dots = {seen, missed};
  return rig;
}

TEST(RigIoTest, RoundTripsEveryField) {
  TempDir dir;
  const RigCalibration rig = Example();
  ASSERT_TRUE(WriteRigCalibration(dir / "rig.json", rig).ok());
  RigCalibration back;
  const Status s = ReadRigCalibration(dir / "rig.json", &back);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(back.camera.fx_px, rig.camera.fx_px);  // Exact: shortest round-trip decimal.
  EXPECT_EQ(back.camera.distortion, rig.camera.distortion);
  EXPECT_EQ(back.camera.distortion_std, rig.camera.distortion_std);
  EXPECT_EQ(back.camera.num_views, 13);
  EXPECT_EQ(back.camera.board_inner_cols, 9);
  EXPECT_TRUE(back.pose.present);
  EXPECT_LT((back.pose.cam_from_sample.translation - rig.pose.cam_from_sample.translation).norm(), 1e-15);
  EXPECT_LT(back.pose.cam_from_sample.rotation.angularDistance(rig.pose.cam_from_sample.rotation), 1e-12);
  EXPECT_EQ(back.pose.rotation_std_rad, rig.pose.rotation_std_rad);
  ASSERT_EQ(back.monitor.dots.size(), 2u);
  EXPECT_TRUE(back.monitor.dots[0].detected);
  EXPECT_EQ(back.monitor.dots[0].centroid_px, rig.monitor.dots[0].centroid_px);
  EXPECT_EQ(back.monitor.dots[0].radiance_dn_per_us, 4.5);
  EXPECT_FALSE(back.monitor.dots[1].detected);

  CameraInfo camera;
  camera.id = "cam0";
  camera.width_px = 640;
  camera.height_px = 480;
  ASSERT_TRUE(ApplyRigCalibration(back, &camera).ok());
  EXPECT_EQ(camera.fx_px, rig.camera.fx_px);
  EXPECT_EQ(camera.distortion.size(), 5u);
  camera.width_px = 800;
  EXPECT_FALSE(ApplyRigCalibration(back, &camera).ok());
}

// Each section keeps the provenance of the command that wrote it through a read and a write
// (another command rewriting the file keeps the sections it does not own, provenance included).
TEST(RigIoTest, EachSectionKeepsItsProvenance) {
  TempDir dir;
  RigCalibration rig;
  rig.pose.present = true;
  rig.pose.provenance_json = R"({"command":"calib pose","options_digest":"fnv1a64:0123456789abcdef"})";
  ASSERT_TRUE(WriteRigCalibration(dir / "rig.json", rig).ok());
  RigCalibration back;
  ASSERT_TRUE(ReadRigCalibration(dir / "rig.json", &back).ok());
  EXPECT_EQ(back.pose.provenance_json, rig.pose.provenance_json);
  back.pose.provenance_json = "";  // As written before provenance: none.
  ASSERT_TRUE(WriteRigCalibration(dir / "old.json", back).ok());
  ASSERT_TRUE(ReadRigCalibration(dir / "old.json", &back).ok());
  EXPECT_EQ(back.pose.provenance_json, "");
  ASSERT_TRUE(WriteFileAtomically(dir / "bad.json", R"({"format": "thinslab-rig-calibration", "format_version": "1.0",
      "pose": {"provenance": "calib pose"}})")
                  .ok());
  const Status bad = ReadRigCalibration(dir / "bad.json", &back);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("pose.provenance"), std::string::npos) << bad.message();
}

TEST(RigIoTest, SectionsAreOptionalAndErrorsNameTheField) {
  TempDir dir;
  RigCalibration only_pose;
  only_pose.pose.present = true;
  ASSERT_TRUE(WriteRigCalibration(dir / "rig.json", only_pose).ok());
  RigCalibration back;
  ASSERT_TRUE(ReadRigCalibration(dir / "rig.json", &back).ok());
  EXPECT_FALSE(back.camera.present);
  EXPECT_TRUE(back.pose.present);
  EXPECT_FALSE(back.monitor.present);
  ASSERT_TRUE(ReadRigCalibrationIfExists(dir / "absent.json", &back).ok());
  EXPECT_FALSE(back.pose.present);

  ASSERT_TRUE(WriteFileAtomically(dir / "bad.json",
                                  R"({"format": "thinslab-rig-calibration", "format_version": "1.0",
                                      "camera": {"width_px": 640, "height_px": 480, "fx_px": -5}})")
                  .ok());
  Status s = ReadRigCalibration(dir / "bad.json", &back);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("camera.fx_px"), std::string::npos) << s.message();
  ASSERT_TRUE(WriteFileAtomically(dir / "bad2.json", R"({"format": "other"})").ok());
  s = ReadRigCalibration(dir / "bad2.json", &back);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("format"), std::string::npos);
  ASSERT_TRUE(WriteFileAtomically(dir / "bad3.json", "{not json").ok());
  EXPECT_FALSE(ReadRigCalibration(dir / "bad3.json", &back).ok());
  EXPECT_FALSE(ReadRigCalibration(dir / "missing.json", &back).ok());
}

}  // namespace
}  // namespace thinslab
