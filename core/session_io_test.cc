// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/session_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "tests/testing/frame_record_matchers.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::AnyOf;
using ::testing::HasSubstr;

constexpr int kWidth = 16;
constexpr int kHeight = 12;

std::string MakeTempDir() {
  std::string pattern = ::testing::TempDir() + "thinslab_session_io_XXXXXX";
  char* dir = ::mkdtemp(pattern.data());
  CHECK(dir != nullptr) << pattern;
  return dir;
}

// A session using every field, optional ones included, with non-default values.
Session MakeFullSession() {
  Session s;
  s.name = "glass_a";
  s.kind = "shadow_map";
  s.created_utc = "2024-05-01T12:00:00Z";
  s.software = "thinslab 0.1.0";

  CameraInfo cam0;
  cam0.id = "cam0";
  cam0.model = "aravis";
  cam0.serial = "SN-1234";
  cam0.width_px = kWidth;
  cam0.height_px = kHeight;
  cam0.fx_px = 1000.25;
  cam0.fy_px = 1001.5;
  cam0.cx_px = 7.5;
  cam0.cy_px = 5.25;
  cam0.distortion = {-0.1, 0.01, 0.001, -0.002, 0.0003};
  cam0.cam_from_sample.rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  cam0.cam_from_sample.translation = Eigen::Vector3d(0.01, -0.02, 0.3);
  cam0.bit_depth = 12;
  cam0.black_level_dn = 64;
  cam0.saturation_dn = 4000;
  cam0.gain_e_per_dn = 0.37;
  s.rig.cameras.push_back(cam0);

  CameraInfo cam1 = cam0;
  cam1.id = "cam1";
  cam1.model = "sim";
  cam1.serial = "";
  cam1.distortion = {0.1, 0.2, 0.3, 0.4};
  cam1.bit_depth = 8;
  cam1.black_level_dn = 2;
  cam1.saturation_dn = 250;
  s.rig.cameras.push_back(cam1);

  s.rig.sample.region_min_m = Eigen::Vector2d(-0.01, -0.0075);
  s.rig.sample.region_max_m = Eigen::Vector2d(0.01, 0.0075);
  s.rig.sample.pixel_pitch_m = 1e-4;
  s.rig.sample.glass_thickness_m = 0.002;
  s.rig.sample.glass_ior = 1.52;
  s.rig.sample.contaminant_side = "projector";

  s.rig.board.present = true;
  s.rig.board.distance_m = 0.005;
  s.rig.board.albedo = 0.8;

  s.rig.projector.present = true;
  s.rig.projector.kind = "collimated";
  s.rig.projector.direction_in_sample = Eigen::Vector3d(0.1, 0.2, -1).normalized();

  s.rig.laser.present = true;
  s.rig.laser.origin_in_sample = Eigen::Vector3d(0, 0, 0.1);
  s.rig.laser.direction_in_sample = Eigen::Vector3d(0, 0, -1);
  s.rig.laser.beam_radius_m = 5e-4;
  s.rig.laser.wavelength_m = 532e-9;

  s.rig.monitor.present = true;
  s.rig.monitor.sample_from_monitor.rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(-1.1, Eigen::Vector3d(0, 1, 0)));
  s.rig.monitor.sample_from_monitor.translation = Eigen::Vector3d(0.1, 0.2, 0.5);
  s.rig.monitor.pixel_pitch_m = 2.5e-4;
  s.rig.monitor.width_px = 1920;
  s.rig.monitor.height_px = 1080;
  s.rig.monitor.dot_radius_px = 2.5;

  FrameRecord shadow;
  shadow.index = 0;
  shadow.camera_id = "cam0";
  shadow.kind = "shadow";
  shadow.sample_state = "contaminated";
  shadow.file = "frames/cam0/shadow/0.png";
  shadow.exposure_time_us = 12500.5;
  shadow.gain_db = 3.5;
  shadow.light.projector_pattern = "flat";
  shadow.timestamp_utc = "2024-05-01T12:00:01.250Z";
  shadow.camera_frame_id = 41;
  shadow.camera_timestamp_ns = (uint64_t(1) << 62) + 12345;  // Exact beyond the 2^53 of a double.
  s.frames.push_back(shadow);

  FrameRecord reference = shadow;
  reference.index = 1;
  reference.kind = "reference";
  reference.sample_state = "clean";
  reference.file = "frames/cam0/reference/1.png";
  reference.status = FrameStatus::kRetried;
  reference.error = "timeout, retried once";
  reference.camera_frame_id = 43;
  reference.camera_timestamp_ns.reset();  // A camera may give an id without a timestamp.
  s.frames.push_back(reference);

  FrameRecord dark = shadow;
  dark.index = 2;
  dark.camera_id = "cam1";
  dark.kind = "dark";
  dark.sample_state = "none";
  dark.file = "frames/cam1/dark/2.png";
  dark.light.projector_pattern = "";
  dark.camera_frame_id.reset();  // Neither (an imported capture).
  dark.camera_timestamp_ns.reset();
  s.frames.push_back(dark);

  FrameRecord dot = shadow;
  dot.index = 3;
  dot.kind = "dot";
  dot.file = "frames/cam0/dot/3.png";
  dot.light.projector_pattern = "";
  dot.light.laser_on = true;
  dot.light.dot_px = Eigen::Vector2d(960.5, 540.25);
  dot.light.dot_radiance = 0.75;
  s.frames.push_back(dot);

  FrameRecord failed = shadow;
  failed.index = 4;
  failed.file = "";
  failed.status = FrameStatus::kFailed;
  failed.error = "GigE packet loss";
  s.frames.push_back(failed);
  return s;
}

// Writes the frame files of every usable frame.
void WriteFrameFiles(const std::string& dir, const Session& session) {
  for (const FrameRecord& f : session.frames) {
    if (f.status == FrameStatus::kFailed) continue;
    const CameraInfo* camera = session.FindCamera(f.camera_id);
    ASSERT_NE(camera, nullptr);
    Image raw(camera->width_px, camera->height_px, 100.0f);
    const Status status = WriteRawFrame(JoinPath(dir, f.file), raw, camera->bit_depth);
    ASSERT_TRUE(status.ok()) << status.message();
  }
}

void ExpectRigidEq(const Rigid3d& a, const Rigid3d& b) {
  EXPECT_EQ(a.rotation.coeffs(), b.rotation.coeffs());
  EXPECT_EQ(a.translation, b.translation);
}

void ExpectSessionsEqual(const Session& a, const Session& b) {
  EXPECT_EQ(a.format_major, b.format_major);
  EXPECT_EQ(a.format_minor, b.format_minor);
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.kind, b.kind);
  EXPECT_EQ(a.created_utc, b.created_utc);
  EXPECT_EQ(a.software, b.software);
  ASSERT_EQ(a.rig.cameras.size(), b.rig.cameras.size());
  for (size_t i = 0; i < a.rig.cameras.size(); ++i) {
    SCOPED_TRACE("camera " + std::to_string(i));
    const CameraInfo& ca = a.rig.cameras[i];
    const CameraInfo& cb = b.rig.cameras[i];
    EXPECT_EQ(ca.id, cb.id);
    EXPECT_EQ(ca.model, cb.model);
    EXPECT_EQ(ca.serial, cb.serial);
    EXPECT_EQ(ca.width_px, cb.width_px);
    EXPECT_EQ(ca.height_px, cb.height_px);
    EXPECT_EQ(ca.fx_px, cb.fx_px);
    EXPECT_EQ(ca.fy_px, cb.fy_px);
    EXPECT_EQ(ca.cx_px, cb.cx_px);
    EXPECT_EQ(ca.cy_px, cb.cy_px);
    EXPECT_EQ(ca.distortion, cb.distortion);
    ExpectRigidEq(ca.cam_from_sample, cb.cam_from_sample);
    EXPECT_EQ(ca.bit_depth, cb.bit_depth);
    EXPECT_EQ(ca.black_level_dn, cb.black_level_dn);
    EXPECT_EQ(ca.saturation_dn, cb.saturation_dn);
    EXPECT_EQ(ca.gain_e_per_dn, cb.gain_e_per_dn);
  }
  const SampleInfo& sa = a.rig.sample;
  const SampleInfo& sb = b.rig.sample;
  EXPECT_EQ(sa.region_min_m, sb.region_min_m);
  EXPECT_EQ(sa.region_max_m, sb.region_max_m);
  EXPECT_EQ(sa.pixel_pitch_m, sb.pixel_pitch_m);
  EXPECT_EQ(sa.glass_thickness_m, sb.glass_thickness_m);
  EXPECT_EQ(sa.glass_ior, sb.glass_ior);
  EXPECT_EQ(sa.contaminant_side, sb.contaminant_side);

  EXPECT_EQ(a.rig.board.present, b.rig.board.present);
  EXPECT_EQ(a.rig.board.distance_m, b.rig.board.distance_m);
  EXPECT_EQ(a.rig.board.albedo, b.rig.board.albedo);
  EXPECT_EQ(a.rig.projector.present, b.rig.projector.present);
  EXPECT_EQ(a.rig.projector.kind, b.rig.projector.kind);
  EXPECT_EQ(a.rig.projector.direction_in_sample, b.rig.projector.direction_in_sample);
  EXPECT_EQ(a.rig.laser.present, b.rig.laser.present);
  EXPECT_EQ(a.rig.laser.origin_in_sample, b.rig.laser.origin_in_sample);
  EXPECT_EQ(a.rig.laser.direction_in_sample, b.rig.laser.direction_in_sample);
  EXPECT_EQ(a.rig.laser.beam_radius_m, b.rig.laser.beam_radius_m);
  EXPECT_EQ(a.rig.laser.wavelength_m, b.rig.laser.wavelength_m);
  EXPECT_EQ(a.rig.monitor.present, b.rig.monitor.present);
  ExpectRigidEq(a.rig.monitor.sample_from_monitor, b.rig.monitor.sample_from_monitor);
  EXPECT_EQ(a.rig.monitor.pixel_pitch_m, b.rig.monitor.pixel_pitch_m);
  EXPECT_EQ(a.rig.monitor.width_px, b.rig.monitor.width_px);
  EXPECT_EQ(a.rig.monitor.height_px, b.rig.monitor.height_px);
  EXPECT_EQ(a.rig.monitor.dot_radius_px, b.rig.monitor.dot_radius_px);

  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (size_t i = 0; i < a.frames.size(); ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    const FrameRecord& fa = a.frames[i];
    const FrameRecord& fb = b.frames[i];
    ExpectSameFrame(fa, fb);
  }
}

class SessionIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = MakeTempDir();
    session_ = MakeFullSession();
    WriteFrameFiles(dir_, session_);
    const Status status = WriteSession(dir_, session_);
    ASSERT_TRUE(status.ok()) << status.message();
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string manifest() const { return JoinPath(dir_, "session.json"); }

  // Edits the written session.json as JSON, then reads the session back.
  Status ReadEdited(const std::function<void(nlohmann::json*)>& edit) {
    std::string text;
    Status status = ReadFileToString(manifest(), &text);
    if (!status.ok()) return status;
    nlohmann::json j = nlohmann::json::parse(text);
    edit(&j);
    status = WriteFileAtomically(manifest(), j.dump(2));
    if (!status.ok()) return status;
    Session session;
    return ReadSession(dir_, &session);
  }

  std::string dir_;
  Session session_;
};

TEST_F(SessionIoTest, WriteReadRoundTripKeepsEveryField) {
  Session read;
  const Status status = ReadSession(dir_, &read);
  ASSERT_TRUE(status.ok()) << status.message();
  ExpectSessionsEqual(session_, read);

  // Writing what was read gives the same bytes.
  const std::string dir2 = MakeTempDir();
  ASSERT_TRUE(WriteSession(dir2, read).ok());
  std::string a, b;
  ASSERT_TRUE(ReadFileToString(manifest(), &a).ok());
  ASSERT_TRUE(ReadFileToString(JoinPath(dir2, "session.json"), &b).ok());
  EXPECT_EQ(a, b);
  fs::remove_all(dir2);
}

TEST_F(SessionIoTest, WritesTheDocumentedLayout) {
  std::string text;
  ASSERT_TRUE(ReadFileToString(manifest(), &text).ok());
  const nlohmann::json j = nlohmann::json::parse(text);
  EXPECT_EQ(j["format"], "thinslab-session");
  EXPECT_EQ(j["format_version"], "1.4");
  EXPECT_EQ(j["rig"]["cameras"][0]["cam_from_sample"]["rotation_wxyz"].size(), 4u);
  EXPECT_EQ(j["rig"]["cameras"][0]["cam_from_sample"]["translation_m"].size(), 3u);
  EXPECT_EQ(j["frames"][0]["camera"], "cam0");
  EXPECT_EQ(j["frames"][0]["light"]["projector_pattern"], "flat");
  EXPECT_FALSE(j["frames"][0]["light"].contains("dot_px"));
  EXPECT_EQ(j["frames"][3]["light"]["dot_px"].size(), 2u);
  EXPECT_EQ(j["frames"][4]["status"], "failed");
  EXPECT_EQ(j["frames"][0]["camera_frame_id"], 41u);
  EXPECT_EQ(j["frames"][0]["camera_timestamp_ns"].get<uint64_t>(), (uint64_t(1) << 62) + 12345);
  EXPECT_EQ(j["frames"][1]["camera_frame_id"], 43u);
  EXPECT_FALSE(j["frames"][1].contains("camera_timestamp_ns"));  // Optional: absent when unknown.
  EXPECT_FALSE(j["frames"][2].contains("camera_frame_id"));
}

TEST_F(SessionIoTest, CameraFrameIdsMustBeNonNegativeIntegersBelow2To63) {
  // Each edit starts from the written session.
  auto read_with = [this](const std::function<void(nlohmann::json*)>& edit) {
    EXPECT_TRUE(WriteSession(dir_, session_).ok());
    return ReadEdited(edit).message();
  };
  EXPECT_THAT(read_with([](nlohmann::json* j) { (*j)["frames"][0]["camera_frame_id"] = -1; }),
              HasSubstr("frames[0].camera_frame_id: must be >= 0, got -1"));
  EXPECT_THAT(read_with([](nlohmann::json* j) { (*j)["frames"][0]["camera_frame_id"] = 4.5; }),
              HasSubstr("frames[0].camera_frame_id: expected an integer in [0, 2^53] when written as a float"));
  EXPECT_THAT(read_with([](nlohmann::json* j) { (*j)["frames"][1]["camera_timestamp_ns"] = "12"; }),
              HasSubstr("frames[1].camera_timestamp_ns: expected an integer, got string"));
  EXPECT_THAT(read_with([](nlohmann::json* j) { (*j)["frames"][0]["camera_timestamp_ns"] = uint64_t(1) << 63; }),
              HasSubstr("frames[0].camera_timestamp_ns: integer 9223372036854775808 is out of range (< 2^63)"));
  // 7.0 is an integer; null is absent.
  EXPECT_EQ(read_with([](nlohmann::json* j) {
              (*j)["frames"][0]["camera_frame_id"] = 7.0;
              (*j)["frames"][1]["camera_frame_id"] = nullptr;
            }),
            "");
  // The writer's validation refuses what the reader would.
  session_.frames[0].camera_frame_id = uint64_t(1) << 63;
  EXPECT_THAT(ValidateSession(session_, dir_).message(), HasSubstr("frames[0].camera_frame_id: must be < 2^63"));
}

TEST(FrameRecordJson, RoundTripKeepsTheCameraStampsAndNamesTheLine) {
  FrameRecord f;
  f.index = 7;
  f.camera_id = "cam0";
  f.kind = "dot";
  f.file = "frames/cam0/dot/0007.png";
  f.exposure_time_us = 33333.3;
  f.light.dot_px = Eigen::Vector2d(10.5, 20.5);
  f.timestamp_utc = "2026-12-02T00:00:00.000Z";
  f.camera_frame_id = 65536;
  f.camera_timestamp_ns = 1234567890123456789ull;
  f.status = FrameStatus::kRetried;
  f.error = "line\nbreak";
  std::string json;
  ASSERT_TRUE(FrameRecordToJson(f, &json).ok());
  EXPECT_EQ(json.find('\n'), std::string::npos) << "a journal record must be one line: " << json;
  FrameRecord back;
  ASSERT_TRUE(ParseFrameRecordJson(json, "j.log:3", &back).ok());
  EXPECT_EQ(back.index, 7);
  EXPECT_EQ(back.file, f.file);
  EXPECT_EQ(back.exposure_time_us, f.exposure_time_us);
  EXPECT_EQ(*back.light.dot_px, *f.light.dot_px);
  EXPECT_EQ(back.camera_frame_id, f.camera_frame_id);
  EXPECT_EQ(back.camera_timestamp_ns, f.camera_timestamp_ns);
  EXPECT_EQ(back.status, FrameStatus::kRetried);
  EXPECT_EQ(back.error, f.error);
  EXPECT_THAT(ParseFrameRecordJson("{\"index\": 1", "j.log:4", &back).message(), HasSubstr("j.log:4: malformed JSON"));
  EXPECT_THAT(ParseFrameRecordJson(R"({"index": 1, "camera": "cam0", "kind": "dot", "file": "", "exposure_time_us": 1,
                                       "timestamp_utc": "", "status": "ok", "camera_frame_id": -3})",
                                   "j.log:5", &back)
                  .message(),
              HasSubstr("j.log:5: frame.camera_frame_id: must be >= 0, got -3"));
}

TEST_F(SessionIoTest, OptionalDevicesAbsentAreNotWritten) {
  Session s = session_;
  s.rig.board = BoardInfo();
  s.rig.projector = ProjectorInfo();
  s.rig.laser = LaserInfo();
  s.rig.monitor = MonitorInfo();
  ASSERT_TRUE(WriteSession(dir_, s).ok());
  std::string text;
  ASSERT_TRUE(ReadFileToString(manifest(), &text).ok());
  const nlohmann::json j = nlohmann::json::parse(text);
  for (const char* key : {"board", "projector", "laser", "monitor"}) {
    EXPECT_FALSE(j["rig"].contains(key)) << key;
  }
  Session read;
  const Status status = ReadSession(dir_, &read);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_FALSE(read.rig.board.present);
  EXPECT_FALSE(read.rig.projector.present);
  EXPECT_FALSE(read.rig.laser.present);
  EXPECT_FALSE(read.rig.monitor.present);
}

// What another program, written from docs/format.md alone, might produce: only required
// fields, integer-valued numbers written as integers, an unknown newer minor version and
// an unknown extra field.
TEST(SessionIoHandWritten, ManifestFollowingTheDocumentLoads) {
  const std::string dir = MakeTempDir();
  const std::string json = R"({
  "format": "thinslab-session",
  "format_version": "1.3",
  "name": "example",
  "kind": "shadow_map",
  "created_utc": "2024-05-01T12:00:00Z",
  "written_by_a_newer_minor_version": {"anything": [1, 2, 3]},
  "rig": {
    "cameras": [{
      "id": "cam0", "model": "v4l2",
      "width_px": 16, "height_px": 12,
      "fx_px": 1200, "fy_px": 1200, "cx_px": 7.5, "cy_px": 5.5,
      "cam_from_sample": {"rotation_wxyz": [2, 0, 0, 0], "translation_m": [0, 0, 0.25]},
      "bit_depth": 12, "saturation_dn": 4095
    }],
    "sample": {"region_min_m": [-0.01, -0.01], "region_max_m": [0.01, 0.01], "pixel_pitch_m": 0.0001},
    "board": {"distance_m": 0.004, "albedo": 0.9},
    "projector": {"kind": "collimated", "direction_in_sample": [0, 0, -1]}
  },
  "frames": [
    {"index": 0, "camera": "cam0", "kind": "shadow", "sample_state": "contaminated",
     "file": "frames/cam0/shadow/0.png", "exposure_time_us": 20000,
     "light": {"projector_pattern": "flat", "laser_on": false},
     "timestamp_utc": "2024-05-01T12:00:01Z", "status": "ok"},
    {"index": 1, "camera": "cam0", "kind": "reference", "sample_state": "clean",
     "file": "frames/cam0/reference/1.png", "exposure_time_us": 20000,
     "light": {"projector_pattern": "flat", "laser_on": false},
     "timestamp_utc": "2024-05-01T12:00:02Z", "status": "ok"},
    {"index": 2, "camera": "cam0", "kind": "dark",
     "file": "frames/cam0/dark/2.png", "exposure_time_us": 20000,
     "timestamp_utc": "2024-05-01T12:00:03Z", "status": "ok"}
  ]
})";
  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "session.json"), json).ok());
  // Frames written with OpenCV directly, as another program would: 16-bit PNG, DN in the
  // low 12 bits.
  for (const char* file :
       {"frames/cam0/shadow/0.png", "frames/cam0/reference/1.png", "frames/cam0/dark/2.png"}) {
    ASSERT_TRUE(CreateDirectories(fs::path(JoinPath(dir, file)).parent_path().string()).ok());
    cv::Mat m(12, 16, CV_16U, cv::Scalar(3000));
    ASSERT_TRUE(cv::imwrite(JoinPath(dir, file), m));
  }

  Session s;
  const Status status = ReadSession(dir, &s);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(s.format_major, 1);
  EXPECT_EQ(s.format_minor, 3);
  ASSERT_EQ(s.rig.cameras.size(), 1u);
  const CameraInfo& c = s.rig.cameras[0];
  EXPECT_EQ(c.fx_px, 1200.0);
  EXPECT_EQ(c.serial, "");
  EXPECT_TRUE(c.distortion.empty());
  EXPECT_EQ(c.black_level_dn, 0.0);
  EXPECT_EQ(c.gain_e_per_dn, 0.0);
  // The quaternion is normalised on read.
  EXPECT_DOUBLE_EQ(c.cam_from_sample.rotation.w(), 1.0);
  EXPECT_EQ(s.software, "");
  EXPECT_EQ(s.rig.sample.glass_ior, 1.5);
  EXPECT_EQ(s.rig.sample.glass_thickness_m, 0.0);
  EXPECT_EQ(s.rig.sample.contaminant_side, "board");
  EXPECT_TRUE(s.rig.board.present);
  EXPECT_TRUE(s.rig.projector.present);
  EXPECT_FALSE(s.rig.laser.present);
  EXPECT_FALSE(s.rig.monitor.present);
  ASSERT_EQ(s.frames.size(), 3u);
  EXPECT_EQ(s.frames[2].sample_state, "none");
  EXPECT_EQ(s.frames[2].light.projector_pattern, "");
  EXPECT_EQ(s.frames[2].gain_db, 0.0);
  EXPECT_EQ(s.frames[2].error, "");
  EXPECT_EQ(s.UsableFrames("shadow", "contaminated").size(), 1u);

  Image image;
  const Status load = LoadFrame(dir, s, s.frames[0], &image);
  ASSERT_TRUE(load.ok()) << load.message();
  EXPECT_EQ(image.at(3, 4), 3000.0f);

  const std::string summary = SummarizeSession(s);
  EXPECT_THAT(summary, AllOf(HasSubstr("example"), HasSubstr("cam0"), HasSubstr("16x12"),
                             HasSubstr("format_version 1.3"), HasSubstr("Board: present"),
                             HasSubstr("Laser: absent"), HasSubstr("shadow / contaminated: 1")));
  fs::remove_all(dir);
}

// Format 1.3: frames another program wrote already linear (a renderer's EXR output), one
// exposure, no saturation, no exposure time, no gain; a per-pixel variance file.
TEST(SessionIoHandWritten, LinearFramesNeedOnlyTheirOwnFields) {
  const std::string dir = MakeTempDir();
  auto manifest = [](const std::string& camera_extra, const std::string& frame_extra) {
    return R"({"format": "thinslab-session", "format_version": "1.3", "name": "render", "kind": "shadow_map",
  "created_utc": "2024-05-01T12:00:00Z",
  "rig": {"cameras": [{"id": "cam0", "model": "renderer", "width_px": 8, "height_px": 6,
      "fx_px": 1200, "fy_px": 1200, "cx_px": 3.5, "cy_px": 2.5,
      "cam_from_sample": {"rotation_wxyz": [1, 0, 0, 0], "translation_m": [0, 0, 0.25]},
      "bit_depth": 32, "frame_values": "linear")" + camera_extra + R"(}],
    "sample": {"region_min_m": [-0.01, -0.01], "region_max_m": [0.01, 0.01], "pixel_pitch_m": 0.0001},
    "board": {"distance_m": 0.004, "albedo": 0.9},
    "projector": {"kind": "collimated", "direction_in_sample": [0, 0, -1]}},
  "frames": [{"index": 0, "camera": "cam0", "kind": "shadow", "sample_state": "contaminated",
     "file": "frames/0.exr", "light": {"projector_pattern": "flat", "laser_on": false},
     "timestamp_utc": "2024-05-01T12:00:01Z", "status": "ok")" + frame_extra + "}]}";
  };
  ASSERT_TRUE(CreateDirectories(JoinPath(dir, "frames")).ok());
  Image frame(8, 6, 0.125f), variance(8, 6, 0.0025f);
  ASSERT_TRUE(WriteExr(JoinPath(dir, "frames/0.exr"), frame).ok());
  ASSERT_TRUE(WriteExr(JoinPath(dir, "frames/0_var.exr"), variance).ok());

  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "session.json"), manifest("", R"(, "variance_file": "frames/0_var.exr")")).ok());
  Session s;
  Status status = ReadSession(dir, &s);
  ASSERT_TRUE(status.ok()) << status.message();
  const CameraInfo& c = s.rig.cameras[0];
  EXPECT_TRUE(c.linear_frames());
  EXPECT_TRUE(std::isinf(c.saturation_dn));  // Absent: nothing saturates.
  EXPECT_FALSE(c.read_noise_dn.has_value());
  EXPECT_EQ(s.frames[0].exposure_time_us, 1.0);  // Absent: 1 us, the frames' own units.
  Image loaded, loaded_variance;
  ASSERT_TRUE(LoadFrame(dir, s, s.frames[0], &loaded).ok());
  EXPECT_EQ(loaded.at(2, 3), 0.125f);
  status = LoadFrameVariance(dir, s, s.frames[0], &loaded_variance);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(loaded_variance.at(2, 3), 0.0025f);
  EXPECT_THAT(SummarizeSession(s), AllOf(HasSubstr("linear frames"), HasSubstr("saturation none")));
  // Written back, the optional fields stay absent and the manifest reads the same.
  const std::string copy = MakeTempDir();
  ASSERT_TRUE(WriteSession(copy, s).ok());
  std::string text;
  ASSERT_TRUE(ReadFileToString(JoinPath(copy, "session.json"), &text).ok());
  const nlohmann::json written = nlohmann::json::parse(text);
  EXPECT_EQ(written["rig"]["cameras"][0]["frame_values"], "linear");
  EXPECT_FALSE(written["rig"]["cameras"][0].contains("saturation_dn"));
  EXPECT_EQ(written["frames"][0]["variance_file"], "frames/0_var.exr");
  fs::remove_all(copy);

  // A declared noise model reads back; bad values are named by field.
  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "session.json"),
                                  manifest(R"(, "read_noise_dn": 0.01, "gain_e_per_dn": 4000)", "")).ok());
  ASSERT_TRUE(ReadSession(dir, &s).ok());
  EXPECT_EQ(s.rig.cameras[0].read_noise_dn.value_or(-1), 0.01);
  const std::pair<std::string, std::string> bad[] = {
      {R"(, "read_noise_dn": -1)", "read_noise_dn"},
      {R"(, "frame_values": "srgb")", "frame_values"},
  };
  for (const auto& [extra, field] : bad) {
    ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "session.json"), manifest(extra, "")).ok());
    status = ReadSession(dir, &s);
    EXPECT_FALSE(status.ok()) << extra;
    EXPECT_THAT(status.message(), HasSubstr(field)) << extra;
  }
  // Raw frames still need an exposure and a saturation level.
  std::string raw = manifest("", "");
  raw.replace(raw.find(R"("bit_depth": 32, "frame_values": "linear")"), 41, R"("bit_depth": 32)");
  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "session.json"), raw).ok());
  status = ReadSession(dir, &s);
  EXPECT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AnyOf(HasSubstr("exposure_time_us"), HasSubstr("saturation_dn")));
  // A variance file that is not an EXR, or holds a negative variance, is refused by name.
  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "session.json"), manifest("", R"(, "variance_file": "frames/0.png")")).ok());
  status = ReadSession(dir, &s);
  EXPECT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr("variance_file"));
  variance.at(1, 1) = -1;
  ASSERT_TRUE(WriteExr(JoinPath(dir, "frames/0_var.exr"), variance).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "session.json"), manifest("", R"(, "variance_file": "frames/0_var.exr")")).ok());
  ASSERT_TRUE(ReadSession(dir, &s).ok());
  status = LoadFrameVariance(dir, s, s.frames[0], &loaded_variance);
  EXPECT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr("0_var.exr"), HasSubstr("negative variance")));
  fs::remove_all(dir);
}

TEST_F(SessionIoTest, MissingFrameFileIsNamed) {
  fs::remove(JoinPath(dir_, "frames/cam0/reference/1.png"));
  Session s;
  const Status status = ReadSession(dir_, &s);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(manifest()), HasSubstr("frames[1].file"),
                                      HasSubstr("frames/cam0/reference/1.png")));
}

TEST_F(SessionIoTest, UnknownMajorVersionIsRefused) {
  const Status status = ReadEdited([](nlohmann::json* j) {
    (*j)["format_version"] = "2.0";
    (*j)["rig"] = "something else entirely";
  });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(
      status.message(),
      AllOf(HasSubstr(manifest()),
            HasSubstr("format_version 2.0 is not supported by this reader (supports 1.x)")));
}

TEST_F(SessionIoTest, UnknownMinorVersionIsAccepted) {
  const Status status = ReadEdited([](nlohmann::json* j) { (*j)["format_version"] = "1.42"; });
  EXPECT_TRUE(status.ok()) << status.message();
}

TEST_F(SessionIoTest, MalformedVersionIsNamed) {
  const Status status = ReadEdited([](nlohmann::json* j) { (*j)["format_version"] = "one"; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(manifest()), HasSubstr("format_version")));
}

TEST_F(SessionIoTest, WrongJsonTypeIsNamed) {
  const Status status =
      ReadEdited([](nlohmann::json* j) { (*j)["rig"]["cameras"][0]["fx_px"] = "1000"; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              AllOf(HasSubstr(manifest()),
                    HasSubstr("rig.cameras[0].fx_px: expected a number, got string")));
}

TEST_F(SessionIoTest, NonIntegerWidthIsNamed) {
  const Status status =
      ReadEdited([](nlohmann::json* j) { (*j)["rig"]["cameras"][1]["width_px"] = 16.5; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr("rig.cameras[1].width_px: expected an integer"));
}

TEST_F(SessionIoTest, MissingRequiredFieldIsNamed) {
  const Status status =
      ReadEdited([](nlohmann::json* j) { (*j)["rig"]["sample"].erase("pixel_pitch_m"); });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              AllOf(HasSubstr(manifest()),
                    HasSubstr("rig.sample.pixel_pitch_m: required field is missing")));
}

TEST_F(SessionIoTest, NegativeExposureIsNamed) {
  const Status status =
      ReadEdited([](nlohmann::json* j) { (*j)["frames"][3]["exposure_time_us"] = -5; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(
      status.message(),
      AllOf(HasSubstr(manifest()), HasSubstr("frames[3].exposure_time_us: must be > 0, got -5")));
}

TEST_F(SessionIoTest, UnknownCameraIsNamed) {
  const Status status = ReadEdited([](nlohmann::json* j) { (*j)["frames"][0]["camera"] = "cam9"; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              AllOf(HasSubstr(manifest()), HasSubstr("frames[0].camera"), HasSubstr("cam9")));
}

TEST_F(SessionIoTest, UnknownStatusIsNamed) {
  const Status status = ReadEdited([](nlohmann::json* j) { (*j)["frames"][2]["status"] = "OK"; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(manifest()), HasSubstr("frames[2].status")));
}

TEST_F(SessionIoTest, FramePathsMustStayInsideTheSession) {
  for (const std::string& file : {std::string("/etc/passwd"), std::string("../outside.png"),
                                  std::string("frames/../../outside.png")}) {
    const Status status =
        ReadEdited([&file](nlohmann::json* j) { (*j)["frames"][0]["file"] = file; });
    ASSERT_FALSE(status.ok()) << file;
    EXPECT_THAT(status.message(), AllOf(HasSubstr(manifest()), HasSubstr("frames[0].file")));
  }
}

TEST_F(SessionIoTest, FrameIndicesMustBeUniqueAndContiguous) {
  Status status = ReadEdited([](nlohmann::json* j) { (*j)["frames"][1]["index"] = 0; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr("frames[1].index"), HasSubstr("duplicate")));
  status = ReadEdited([](nlohmann::json* j) { (*j)["frames"][1]["index"] = 7; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr("frames[1].index"), HasSubstr("contiguous")));
}

TEST_F(SessionIoTest, SemanticChecksNameTheField) {
  struct Case {
    std::function<void(nlohmann::json*)> edit;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {[](nlohmann::json* j) { (*j)["rig"]["cameras"] = nlohmann::json::array(); }, "rig.cameras"},
      {[](nlohmann::json* j) { (*j)["rig"]["cameras"][1]["id"] = "cam0"; }, "rig.cameras[1].id"},
      {[](nlohmann::json* j) { (*j)["rig"]["cameras"][0]["bit_depth"] = 11; },
       "rig.cameras[0].bit_depth"},
      {[](nlohmann::json* j) { (*j)["rig"]["cameras"][0]["saturation_dn"] = 10; },
       "rig.cameras[0].saturation_dn"},
      {[](nlohmann::json* j) {
         (*j)["rig"]["cameras"][0]["distortion"] = {1.0, 2.0};
       },
       "rig.cameras[0].distortion"},
      {[](nlohmann::json* j) {
         (*j)["rig"]["cameras"][0]["cam_from_sample"]["rotation_wxyz"] = {0, 0, 0, 0};
       },
       "rig.cameras[0].cam_from_sample.rotation_wxyz"},
      {[](nlohmann::json* j) {
         (*j)["rig"]["sample"]["region_max_m"] = {-1, 1};
       },
       "rig.sample.region_max_m[0]"},
      {[](nlohmann::json* j) { (*j)["rig"]["board"]["albedo"] = 1.5; }, "rig.board.albedo"},
      {[](nlohmann::json* j) { (*j)["rig"]["board"]["distance_m"] = 0; }, "rig.board.distance_m"},
      {[](nlohmann::json* j) { (*j)["frames"][0]["sample_state"] = "dirty"; },
       "frames[0].sample_state"},
      {[](nlohmann::json* j) { (*j)["frames"][0]["light"]["laser_on"] = 1; },
       "frames[0].light.laser_on: expected a boolean"},
      {[](nlohmann::json* j) { (*j)["format"] = "other"; }, "format"},
  };
  for (const Case& c : cases) {
    const Status status = ReadEdited(c.edit);
    ASSERT_FALSE(status.ok()) << c.expected;
    EXPECT_THAT(status.message(), AllOf(HasSubstr(manifest()), HasSubstr(c.expected)));
    ASSERT_TRUE(WriteSession(dir_, session_).ok());
  }
}

TEST_F(SessionIoTest, MalformedJsonGivesBytePosition) {
  std::string text;
  ASSERT_TRUE(ReadFileToString(manifest(), &text).ok());
  ASSERT_TRUE(WriteFileAtomically(manifest(), text.substr(0, text.size() / 2)).ok());
  Session s;
  const Status status = ReadSession(dir_, &s);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(manifest()), HasSubstr("malformed JSON at byte")));
}

TEST_F(SessionIoTest, MissingManifestIsNamed) {
  fs::remove(manifest());
  Session s;
  const Status status = ReadSession(dir_, &s);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr(manifest()));
}

TEST_F(SessionIoTest, WriteRefusesNonFiniteNumbers) {
  Session s = session_;
  s.rig.cameras[1].fx_px = std::nan("");
  const Status status = WriteSession(dir_, s);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(manifest()), HasSubstr("rig.cameras[1].fx_px")));
}

TEST_F(SessionIoTest, LoadFrameRejectsWrongSize) {
  const FrameRecord& frame = session_.frames[0];
  const std::string path = JoinPath(dir_, frame.file);
  ASSERT_TRUE(WriteRawFrame(path, Image(kWidth / 2, kHeight - 1, 10.0f), 12).ok());
  Image image;
  const Status status = LoadFrame(dir_, session_, frame, &image);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              AllOf(HasSubstr(path), HasSubstr("8x11"), HasSubstr("16x12"), HasSubstr("cam0")));
}

TEST_F(SessionIoTest, LoadFrameRejectsTruncatedPng) {
  const FrameRecord& frame = session_.frames[0];
  const std::string path = JoinPath(dir_, frame.file);
  Image raw(kWidth, kHeight);
  for (size_t i = 0; i < raw.data().size(); ++i)
    raw.data()[i] = static_cast<float>((i * 37) % 4096);
  ASSERT_TRUE(WriteRawFrame(path, raw, 12).ok());
  std::string bytes;
  ASSERT_TRUE(ReadFileToString(path, &bytes).ok());
  ASSERT_TRUE(WriteFileAtomically(path, bytes.substr(0, bytes.size() / 2)).ok());
  Image image;
  const Status status = LoadFrame(dir_, session_, frame, &image);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), HasSubstr(path));

  ASSERT_TRUE(WriteFileAtomically(path, "not a png at all").ok());
  const Status garbage = LoadFrame(dir_, session_, frame, &image);
  ASSERT_FALSE(garbage.ok());
  EXPECT_THAT(garbage.message(), HasSubstr(path));
}

TEST_F(SessionIoTest, LoadFrameRejectsColourAndWrongSampleDepth) {
  const FrameRecord& frame = session_.frames[0];  // cam0, 12-bit.
  const std::string path = JoinPath(dir_, frame.file);
  Image image;

  ASSERT_TRUE(cv::imwrite(path, cv::Mat(kHeight, kWidth, CV_16UC3, cv::Scalar(1, 2, 3))));
  Status status = LoadFrame(dir_, session_, frame, &image);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(path), HasSubstr("3 channels")));

  ASSERT_TRUE(WriteRawFrame(path, Image(kWidth, kHeight, 10.0f), 8).ok());
  status = LoadFrame(dir_, session_, frame, &image);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              AllOf(HasSubstr(path), HasSubstr("8-bit"), HasSubstr("bit_depth 12")));

  // DN shifted to the top of 16 bits is not what a 12-bit camera declares.
  ASSERT_TRUE(cv::imwrite(path, cv::Mat(kHeight, kWidth, CV_16U, cv::Scalar(4000 << 4))));
  status = LoadFrame(dir_, session_, frame, &image);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(path), HasSubstr("low bits")));
}

TEST_F(SessionIoTest, RawFrameRoundTripSubtractsBlackLevel) {
  for (const int camera_idx : {0, 1}) {  // 12-bit, then 8-bit.
    const CameraInfo& camera = session_.rig.cameras[camera_idx];
    SCOPED_TRACE(camera.bit_depth);
    const double max_dn = std::ldexp(1.0, camera.bit_depth) - 1;
    Image raw(kWidth, kHeight);
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        raw.at(x, y) = static_cast<float>(std::fmod(x * 97.0 + y * 331.0, max_dn + 1));
      }
    }
    raw.at(0, 0) = -3.0f;                              // Clamped to 0.
    raw.at(1, 0) = static_cast<float>(max_dn + 1000);  // Clamped to full scale.
    raw.at(2, 0) = 10.6f;                              // Rounded to 11.
    FrameRecord frame = session_.frames[0];
    frame.camera_id = camera.id;
    frame.file = "frames/" + camera.id + "/test/round_trip.png";
    ASSERT_TRUE(WriteRawFrame(JoinPath(dir_, frame.file), raw, camera.bit_depth).ok());
    Image loaded;
    const Status status = LoadFrame(dir_, session_, frame, &loaded);
    ASSERT_TRUE(status.ok()) << status.message();
    ASSERT_EQ(loaded.width(), kWidth);
    ASSERT_EQ(loaded.height(), kHeight);
    const float black = static_cast<float>(camera.black_level_dn);
    EXPECT_EQ(loaded.at(0, 0), 0.0f - black);  // Negative after black subtraction; not clamped.
    EXPECT_EQ(loaded.at(1, 0), static_cast<float>(max_dn) - black);
    EXPECT_EQ(loaded.at(2, 0), 11.0f - black);
    for (int y = 1; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        ASSERT_EQ(loaded.at(x, y), raw.at(x, y) - black) << x << "," << y;
      }
    }
  }
}

TEST_F(SessionIoTest, LoadFrameReadsFloatExr) {
  FrameRecord frame = session_.frames[0];
  frame.file = "frames/cam0/shadow/0.exr";
  Image raw(kWidth, kHeight);
  for (size_t i = 0; i < raw.data().size(); ++i) raw.data()[i] = 100.25f + static_cast<float>(i);
  ASSERT_TRUE(WriteExr(JoinPath(dir_, frame.file), raw).ok());
  Image loaded;
  const Status status = LoadFrame(dir_, session_, frame, &loaded);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(loaded.at(5, 3), raw.at(5, 3) - 64.0f);
}

TEST_F(SessionIoTest, WriteRawFrameRefusesBadInput) {
  const std::string path = JoinPath(dir_, "x.png");
  EXPECT_FALSE(WriteRawFrame(path, Image(4, 4), 32).ok());
  EXPECT_FALSE(WriteRawFrame(JoinPath(dir_, "x.tif"), Image(4, 4), 12).ok());
  Image nan_image(4, 4);
  nan_image.at(2, 1) = std::nanf("");
  const Status status = WriteRawFrame(path, nan_image, 12);
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(), AllOf(HasSubstr(path), HasSubstr("(2, 1)")));
  EXPECT_FALSE(FileExists(path));
}

TEST_F(SessionIoTest, StreamStatisticsRoundTripAndAreOptional) {
  session_.rig.cameras[0].stream_statistics = {{"completed_buffers", 12}, {"missing_packets", 3}};
  ASSERT_TRUE(WriteSession(dir_, session_).ok());
  Session read;
  const Status read_status = ReadSession(dir_, &read);
  ASSERT_TRUE(read_status.ok()) << read_status.message();
  EXPECT_EQ(read.rig.cameras[0].stream_statistics, session_.rig.cameras[0].stream_statistics);
  EXPECT_TRUE(read.rig.cameras[1].stream_statistics.empty());  // Absent: still a valid manifest.
  const Status status = ReadEdited(
      [](nlohmann::json* j) { (*j)["rig"]["cameras"][0]["stream_statistics"]["missing_packets"] = "3"; });
  ASSERT_FALSE(status.ok());
  EXPECT_THAT(status.message(),
              HasSubstr("rig.cameras[0].stream_statistics.missing_packets: expected a number, got string"));
}

}  // namespace
}  // namespace thinslab
