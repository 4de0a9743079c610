// SPDX-License-Identifier: Apache-2.0
// Shadow-map and laser-lobe sessions through a fake board rig whose camera shows a light change
// only some captures after it (queued buffers): retries, display-camera synchronisation, and
// exposures in whole refresh periods of the display.
#include "thinslab/acquire/shadow_map_session.h"

#include <gtest/gtest.h>

#include <functional>
#include <set>

#include "thinslab/acquire/laser_lobe_session.h"
#include "thinslab/core/session_io.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/tiny_session.h"

namespace thinslab {
namespace {

// Board seen by a 16 x 12 camera: the projector's flat field (halved on the left by the
// contaminated sample) and a laser spot (4 x 4 px at (10, 4)), in DN proportional to the
// exposure. Frame n shows the light state of capture n - latency (queued buffers). Captures
// whose attempt number is in `failing` fail (a device fault).
class FakeBoardRig : public Camera, public Projector, public Laser {
 public:
  static constexpr double kFlatDnPerUs = 0.06;
  static constexpr double kSpotDnPerUs = 0.1;

  FakeBoardRig(int latency, std::set<int> failing = {}, double refresh_period_s = 0)
      : latency_(latency), failing_(std::move(failing)), refresh_period_s_(refresh_period_s) {
    info_ = TinyCamera("fake board");
    info_.width_px = 16;
    info_.height_px = 12;
    info_.black_level_dn = 64;
    info_.gain_e_per_dn = 4;
  }
  // Camera.
  const CameraInfo& info() const override { return info_; }
  Status SetExposure(double requested_us, double* applied_us) override {
    exposure_us_ = std::round(requested_us);
    *applied_us = exposure_us_;
    return Status::Ok();
  }
  Status Capture(CapturedFrame* frame) override {
    const int n = captures_++;
    history_.push_back(state_);
    if (failing_.count(n) > 0 || failing_.count(-1) > 0) return Status::Error("camera 'cam0': timeout waiting for buffer");
    const State shown = n >= latency_ ? history_[n - latency_] : State();
    Image raw(info_.width_px, info_.height_px, static_cast<float>(info_.black_level_dn));
    for (int y = 0; y < raw.height(); ++y) {
      for (int x = 0; x < raw.width(); ++x) {
        double dn = 0;
        if (shown.pattern == "flat") dn += kFlatDnPerUs * exposure_us_ * (shown.contaminated && x < 8 ? 0.5 : 1.0);
        if (shown.laser_on && x >= 10 && x < 14 && y >= 4 && y < 8) dn += kSpotDnPerUs * exposure_us_;
        raw.at(x, y) = static_cast<float>(std::min(4095.0, info_.black_level_dn + std::round(dn)));
      }
    }
    frame->raw_dn = std::move(raw);
    frame->exposure_time_us = exposure_us_;
    frame->frame_id = static_cast<uint64_t>(n);
    frame->timestamp_utc = "2026-12-02T00:00:00Z";
    return Status::Ok();
  }
  // Projector.
  Status ShowPattern(const std::string& pattern) override {
    state_.pattern = pattern;
    return Status::Ok();
  }
  double refresh_period_s() const override { return refresh_period_s_; }
  // Laser.
  Status SetEmission(bool on) override {
    state_.laser_on = on;
    return Status::Ok();
  }
  SampleChanger sample_changer() {
    return [this](const std::string& sample_state) {
      state_.contaminated = sample_state == "contaminated";
      return Status::Ok();
    };
  }
  int captures() const { return captures_; }

  // What a frame of `f` must look like: flat DN in the left and right halves, spot DN.
  static void Expected(const FrameRecord& f, double* left, double* right, double* spot) {
    const double flat = f.light.projector_pattern == "flat" ? kFlatDnPerUs * f.exposure_time_us : 0;
    *left = f.sample_state == "contaminated" ? 0.5 * flat : flat;
    *right = flat;
    *spot = flat + (f.light.laser_on ? kSpotDnPerUs * f.exposure_time_us : 0);
  }

 private:
  struct State {
    std::string pattern;
    bool contaminated = false;
    bool laser_on = false;
  };
  CameraInfo info_;
  int latency_;
  std::set<int> failing_;
  double refresh_period_s_;
  double exposure_us_ = 1000;
  int captures_ = 0;
  State state_;
  std::vector<State> history_;
};

Session Header(const CameraInfo& camera) {
  Session header = TinySessionHeader("shadow_map", camera);
  header.name = "test";
  return header;
}

// Every usable frame shows the light state its record says (to the DN, below saturation).
void ExpectFramesShowTheirLight(const std::string& dir, const Session& session) {
  for (const FrameRecord& f : session.frames) {
    if (f.status == FrameStatus::kFailed) continue;
    Image dn;
    ASSERT_TRUE(LoadFrame(dir, session, f, &dn).ok());
    double left = 0, right = 0, spot = 0;
    FakeBoardRig::Expected(f, &left, &right, &spot);
    const double saturated = 4095 - 64;
    EXPECT_NEAR(dn.at(2, 2), std::min(left, saturated), 0.5) << "frame " << f.index << " (" << f.kind << ")";
    EXPECT_NEAR(dn.at(15, 10), std::min(right, saturated), 0.5) << "frame " << f.index << " (" << f.kind << ")";
    EXPECT_NEAR(dn.at(11, 5), std::min(spot, saturated), 0.5) << "frame " << f.index << " (" << f.kind << ")";
  }
}

ShadowMapSessionOptions SmallShadowPlan() {
  ShadowMapSessionOptions options;
  options.frames_per_state = 2;
  options.dark_frames = 1;
  return options;
}

// Runs `script` into a new session at `dir`; *session receives what the writer holds at the end
// (discarded_frames included), and the manifest is saved whatever the outcome.
Status RunIntoSession(const std::string& dir, FakeBoardRig* rig, Session* session,
                      const std::function<Status(SessionWriter*)>& script) {
  SessionWriter writer;
  THINSLAB_RETURN_IF_ERROR(writer.Open(dir, Header(rig->info())));
  const Status status = script(&writer);
  *session = writer.session();
  THINSLAB_RETURN_IF_ERROR(writer.Save());
  return status;
}

Status RunShadow(const ShadowMapSessionOptions& options, FakeBoardRig* rig, const std::string& dir, Session* session) {
  return RunIntoSession(dir, rig, session, [&](SessionWriter* writer) {
    return RunShadowMapSession(options, rig, rig, rig->sample_changer(), writer);
  });
}

TEST(ShadowMapSession, FailedCaptureIsRecordedAndRetried) {
  TempDir dir;
  // Captures 0-2 settle the first (dark) frame, 3 sees the flat field; attempt 4 fails once.
  FakeBoardRig rig(/*latency=*/0, /*failing=*/{4});
  Session session;
  const Status status = RunShadow(SmallShadowPlan(), &rig, dir / "s", &session);
  ASSERT_TRUE(status.ok()) << status.message();
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  ASSERT_EQ(session.frames.size(), 6u);  // 1 dark + 1 reference + failed + retried + 2 shadow.
  EXPECT_EQ(session.frames[2].status, FrameStatus::kFailed);
  EXPECT_NE(session.frames[2].error.find("timeout"), std::string::npos);
  EXPECT_EQ(session.frames[3].status, FrameStatus::kRetried);
  EXPECT_EQ(session.UsableFrames("reference").size(), 2u);
  EXPECT_EQ(session.UsableFrames("shadow", "contaminated").size(), 2u);
  ExpectFramesShowTheirLight(dir / "s", session);
}

TEST(ShadowMapSession, DeadCameraStopsWithClearErrorAndKeepsAValidSession) {
  TempDir dir;
  FakeBoardRig rig(0, {-1});
  Session session;
  const ShadowMapSessionOptions options;
  const Status status = RunShadow(options, &rig, dir / "s", &session);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("camera 'cam0'"), std::string::npos);
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  EXPECT_EQ(session.frames.size(), static_cast<size_t>(options.sync.max_retries + 1));
  for (const auto& f : session.frames) EXPECT_EQ(f.status, FrameStatus::kFailed);
}

// The projector's and the sample's changes reach the camera two captures late: every recorded
// frame must still show its own state (a fixed "first frame after the change" would record the
// dark state as the first reference frame and the clean board as the first shadow frame).
TEST(ShadowMapSession, OnlyFramesShowingTheNewProjectorAndSampleStateAreRecorded) {
  TempDir dir;
  FakeBoardRig rig(/*latency=*/2);
  Session session;
  const Status status = RunShadow(SmallShadowPlan(), &rig, dir / "s", &session);
  ASSERT_TRUE(status.ok()) << status.message();
  ASSERT_EQ(session.frames.size(), 5u);
  ExpectFramesShowTheirLight(dir / "s", session);
  // Two stale frames discarded at each of the two changes, and the settle of the first frame.
  EXPECT_GE(session.acquisition.discarded_frames, 2 * 2 + 2);
  EXPECT_EQ(rig.captures(), 5 + session.acquisition.discarded_frames);
}

TEST(ShadowMapSession, ExposureIsAWholeNumberOfProjectorRefreshPeriods) {
  TempDir dir;
  FakeBoardRig rig(0, {}, /*refresh_period_s=*/1.0 / 60);
  ShadowMapSessionOptions options = SmallShadowPlan();
  options.exposure_time_us = 40000;  // 2.4 periods -> 2 periods.
  Session session;
  ASSERT_TRUE(RunShadow(options, &rig, dir / "s", &session).ok());
  for (const FrameRecord& f : session.frames) EXPECT_EQ(f.exposure_time_us, 33333) << f.kind;
  // A camera that cannot follow the display is refused, naming it.
  options.max_refresh_mismatch = 1e-6;  // The camera's whole microseconds are 1e-5 periods off.
  const Status status = RunShadow(options, &rig, dir / "t", &session);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("camera 'cam0': applied exposure 33333 us"), std::string::npos) << status.message();
}

LaserLobeSessionOptions SmallLaserPlan() {
  LaserLobeSessionOptions options;
  options.exposure_times_us = {2000, 20000};
  return options;
}

Status RunLaser(const LaserLobeSessionOptions& options, FakeBoardRig* rig, const std::string& dir, Session* session) {
  return RunIntoSession(dir, rig, session, [&](SessionWriter* writer) {
    return RunLaserLobeSession(options, rig, rig, rig, rig->sample_changer(), writer);
  });
}

TEST(LaserLobeSession, OnlyFramesShowingTheNewLaserFlatAndSampleStateAreRecorded) {
  TempDir dir;
  FakeBoardRig rig(/*latency=*/2);
  Session session;
  const Status status = RunLaser(SmallLaserPlan(), &rig, dir / "s", &session);
  ASSERT_TRUE(status.ok()) << status.message();
  ASSERT_EQ(session.frames.size(), 4u * 2u);  // flat, dark, laser contaminated, laser clean.
  EXPECT_EQ(session.UsableFrames("flat").size(), 2u);
  EXPECT_EQ(session.UsableFrames("laser", "contaminated").size(), 2u);
  EXPECT_EQ(session.UsableFrames("laser", "clean").size(), 2u);
  ExpectFramesShowTheirLight(dir / "s", session);
  EXPECT_GE(session.acquisition.discarded_frames, 2);  // At least the stale flat after "flat" -> dark.
}

TEST(LaserLobeSession, OnlyTheFlatBracketIsLockedToTheDisplayRefresh) {
  const LaserLobeSessionOptions options = []() {
    LaserLobeSessionOptions o;
    o.exposure_times_us = {20, 2000, 20000, 40000};
    return o;
  }();
  const std::vector<PlannedFrame> plan = PlanLaserLobeSession(options, 1.0 / 60);
  std::vector<double> flat, laser;
  for (const PlannedFrame& p : plan) {
    (p.kind == "flat" ? flat : laser).push_back(p.requested_exposure_us);
    EXPECT_EQ(p.refresh_locked, p.kind == "flat") << p.kind;
  }
  // 20, 2000 and 20000 us all round to one period and merge; 40000 us to two periods.
  ASSERT_EQ(flat.size(), 2u);
  EXPECT_NEAR(flat[0], 1e6 / 60, 1e-6);
  EXPECT_NEAR(flat[1], 2e6 / 60, 1e-6);
  EXPECT_EQ(laser.size(), 3u * 4u);  // dark, laser contaminated, laser clean: the bracket as asked.
  EXPECT_EQ(laser.front(), 20);

  TempDir dir;
  FakeBoardRig rig(0, {}, 1.0 / 60);
  Session session;
  ASSERT_TRUE(RunLaser(options, &rig, dir / "s", &session).ok());
  ASSERT_EQ(session.frames.size(), plan.size());
  for (size_t k = 0; k < plan.size(); ++k) {
    EXPECT_NEAR(session.frames[k].exposure_time_us, std::round(plan[k].requested_exposure_us), 0.5) << "frame " << k;
  }
}

TEST(SessionWriter, ReopeningResumesAndKeepsFrames) {
  TempDir dir;
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(TinyCamera())).ok());
  FrameRecord record;
  record.camera_id = "cam0";
  record.kind = "shadow";
  record.sample_state = "contaminated";
  record.exposure_time_us = 100;
  ASSERT_TRUE(writer.AddFrame(record, Image(8, 6, 10.0f)).ok());
  ASSERT_TRUE(writer.Save().ok());
  SessionWriter resumed;
  ASSERT_TRUE(resumed.Open(dir / "s", Header(TinyCamera())).ok());
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
