// SPDX-License-Identifier: Apache-2.0
#include "acquire/shadow_map_session.h"

#include <gtest/gtest.h>

#include "core/session_io.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/tiny_session.h"

namespace thinslab {
namespace {

// A camera that fails on chosen capture attempts (device faults mid-session).
class FlakyCamera : public Camera {
 public:
  explicit FlakyCamera(std::vector<int> failing_attempts)
      : info_(TinyCamera()), failing_(std::move(failing_attempts)) {}
  const CameraInfo& info() const override { return info_; }
  Status SetExposure(double requested_us, double* applied_us) override {
    *applied_us = std::round(requested_us);
    return Status::Ok();
  }
  Status Capture(CapturedFrame* frame) override {
    const int attempt = attempts_++;
    for (int f : failing_) {
      if (f == attempt || f < 0) return Status::Error("camera 'cam0': timeout waiting for buffer");
    }
    frame->raw_dn = Image(8, 6, 1000.0f);
    frame->exposure_time_us = 20000;
    frame->timestamp_utc = "2026-11-23T00:00:00Z";
    return Status::Ok();
  }

 private:
  CameraInfo info_;
  std::vector<int> failing_;
  int attempts_ = 0;
};

class NullProjector : public Projector {
 public:
  Status ShowPattern(const std::string&) override { return Status::Ok(); }
};

Session Header(const CameraInfo& camera) {
  Session header = TinySessionHeader("shadow_map", camera);
  header.name = "test";
  return header;
}

TEST(ShadowMapSession, FailedCaptureIsRecordedAndRetried) {
  TempDir dir;
  FlakyCamera camera({1});  // The second capture attempt fails once.
  NullProjector projector;
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(camera.info())).ok());
  ShadowMapSessionOptions options;
  options.frames_per_state = 2;
  options.dark_frames = 1;
  const Status status =
      RunShadowMapSession(options, &camera, &projector, [](const std::string&) { return Status::Ok(); }, &writer);
  ASSERT_TRUE(status.ok()) << status.message();
  ASSERT_TRUE(writer.Save().ok());
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  ASSERT_EQ(session.frames.size(), 6u);  // 1 dark + failed + retried + 1 reference + 2 shadow.
  EXPECT_EQ(session.frames[1].status, FrameStatus::kFailed);
  EXPECT_NE(session.frames[1].error.find("timeout"), std::string::npos);
  EXPECT_EQ(session.frames[2].status, FrameStatus::kRetried);
  EXPECT_EQ(session.UsableFrames("reference").size(), 2u);
  EXPECT_EQ(session.UsableFrames("shadow", "contaminated").size(), 2u);
}

TEST(ShadowMapSession, DeadCameraStopsWithClearErrorAndKeepsAValidSession) {
  TempDir dir;
  FlakyCamera camera({-1});
  NullProjector projector;
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(camera.info())).ok());
  ShadowMapSessionOptions options;
  const Status status =
      RunShadowMapSession(options, &camera, &projector, [](const std::string&) { return Status::Ok(); }, &writer);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("camera 'cam0'"), std::string::npos);
  ASSERT_TRUE(writer.Save().ok());
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  EXPECT_EQ(session.frames.size(), static_cast<size_t>(options.max_retries + 1));
  for (const auto& f : session.frames) EXPECT_EQ(f.status, FrameStatus::kFailed);
}

TEST(SessionWriter, ReopeningResumesAndKeepsFrames) {
  TempDir dir;
  FlakyCamera camera({});
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(camera.info())).ok());
  FrameRecord record;
  record.camera_id = "cam0";
  record.kind = "shadow";
  record.sample_state = "contaminated";
  record.exposure_time_us = 100;
  ASSERT_TRUE(writer.AddFrame(record, Image(8, 6, 10.0f)).ok());
  ASSERT_TRUE(writer.Save().ok());
  SessionWriter resumed;
  ASSERT_TRUE(resumed.Open(dir / "s", Header(camera.info())).ok());
  ASSERT_TRUE(resumed.AddFrame(record, Image(8, 6, 11.0f)).ok());
  ASSERT_TRUE(resumed.Save().ok());
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  ASSERT_EQ(session.frames.size(), 2u);
  EXPECT_EQ(session.frames[1].index, 1);
  Image frame;
  ASSERT_TRUE(LoadFrame(dir / "s", session, session.frames[0], &frame).ok());
  EXPECT_EQ(frame.at(0, 0), 10.0f);
}

}  // namespace
}  // namespace thinslab
