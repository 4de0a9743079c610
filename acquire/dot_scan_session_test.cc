// SPDX-License-Identifier: Apache-2.0
// Dot scans, exposure brackets and display-camera synchronisation against in-test fakes: a
// monitor whose changes reach the camera only after a few frames (queued buffers), as a
// streaming camera behind a display does.
#include "thinslab/acquire/dot_scan_session.h"

#include <gtest/gtest.h>

#include <cmath>
#include <deque>

#include "thinslab/acquire/session_journal.h"
#include "thinslab/core/session_io.h"
#include "thinslab/drivers/pattern_id.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

// Monitor of 160x120 px seen by a 80x60 camera at half scale (camera = monitor / 2), each lit
// monitor dot a Gaussian blob. Pattern changes become visible `latency` captures after
// ShowPattern, and a new exposure applies one capture late when `late_exposure`.
class FakeDotRig : public Projector, public Camera {
 public:
  explicit FakeDotRig(int latency, bool late_exposure = false) : latency_(latency), late_exposure_(late_exposure) {
    info_.id = "cam0";
    info_.model = "fake";
    info_.width_px = 80;
    info_.height_px = 60;
    info_.fx_px = info_.fy_px = 100;
    info_.cx_px = 39.5;
    info_.cy_px = 29.5;
    info_.bit_depth = 12;
    info_.black_level_dn = 64;
    info_.saturation_dn = 4095;
    info_.gain_e_per_dn = 4;
  }
  // Projector.
  Status ShowPattern(const std::string& pattern) override {
    PatternSpec spec;
    THINSLAB_RETURN_IF_ERROR(ParsePatternId(pattern, &spec));
    queue_.push_back({captures_ + latency_, spec});
    ++shows_;
    return Status::Ok();
  }
  double refresh_period_s() const override { return 1.0 / 60; }
  // Camera.
  const CameraInfo& info() const override { return info_; }
  Status SetExposure(double requested_us, double* applied_us) override {
    pending_exposure_us_ = std::round(requested_us / 10) * 10;  // 10 us granularity.
    if (!late_exposure_) exposure_us_ = pending_exposure_us_;
    *applied_us = pending_exposure_us_;
    return Status::Ok();
  }
  Status Capture(CapturedFrame* frame) override {
    while (!queue_.empty() && queue_.front().first <= captures_) {
      visible_ = queue_.front().second;
      queue_.pop_front();
    }
    Image img(80, 60, 64.0f);
    // Signal: 0.02 DN per us at a dot's peak (saturates above ~200 ms).
    for (const auto& dot : visible_.dots) {
      const double cx = dot.x_px / 2, cy = dot.y_px / 2;
      for (int y = 0; y < 60; ++y) {
        for (int x = 0; x < 80; ++x) {
          const double r2 = std::pow(x + 0.5 - cx, 2) + std::pow(y + 0.5 - cy, 2);
          img.at(x, y) += static_cast<float>(0.02 * exposure_us_ * std::exp(-r2 / 2));
        }
      }
    }
    // Deterministic small noise, +-1 DN.
    for (size_t i = 0; i < img.data().size(); ++i) {
      img.data()[i] = std::min(4095.0f, std::round(img.data()[i] + static_cast<float>((i * 7 + captures_ * 13) % 3) - 1));
    }
    frame->raw_dn = std::move(img);
    frame->exposure_time_us = exposure_us_;
    frame->frame_id = captures_++;
    frame->timestamp_utc = "2026-11-23T00:00:00Z";
    exposure_us_ = pending_exposure_us_;
    return Status::Ok();
  }

  int captures() const { return captures_; }

 private:
  CameraInfo info_;
  int latency_;
  bool late_exposure_;
  int captures_ = 0, shows_ = 0;
  double exposure_us_ = 1000, pending_exposure_us_ = 1000;
  std::deque<std::pair<int, PatternSpec>> queue_;
  PatternSpec visible_;
};

Session Header(const CameraInfo& camera) {
  Session header;
  header.name = "dots";
  header.kind = "dot_scan";
  header.rig.cameras = {camera};
  header.rig.sample.region_min_m = Eigen::Vector2d(-1e-2, -1e-2);
  header.rig.sample.region_max_m = Eigen::Vector2d(1e-2, 1e-2);
  header.rig.sample.pixel_pitch_m = 1e-4;
  return header;
}

// Intensity centroid (camera px, centres at +0.5) of the black-subtracted frame.
Eigen::Vector2d Centroid(const Image& dn) {
  double sx = 0, sy = 0, s = 0;
  for (int y = 0; y < dn.height(); ++y) {
    for (int x = 0; x < dn.width(); ++x) {
      const double v = std::max(0.0f, dn.at(x, y) - 2.0f);
      sx += v * (x + 0.5);
      sy += v * (y + 0.5);
      s += v;
    }
  }
  return s > 0 ? Eigen::Vector2d(sx / s, sy / s) : Eigen::Vector2d(-1, -1);
}

DotScanSessionOptions SmallScan() {
  DotScanSessionOptions options;
  options.grid_nx = 4;
  options.grid_ny = 4;
  options.monitor_width_px = 160;
  options.monitor_height_px = 120;
  options.bracket.exposures_us = {20000, 50000};
  return options;
}

SampleChanger NoSample() {
  return [](const std::string&) { return Status::Ok(); };
}

TEST(ExposureBracket, GeometricPlanSnapsToRefreshMultiplesAndDeduplicates) {
  ExposureBracketOptions options;
  options.min_exposure_us = 100;
  options.max_exposure_us = 1e6;
  options.steps = 5;
  std::vector<double> plan = PlanExposureBracket(options);
  ASSERT_EQ(plan.size(), 5u);
  EXPECT_NEAR(plan[0], 100, 1e-9);
  EXPECT_NEAR(plan[2], 1e4, 1e-6);
  EXPECT_NEAR(plan[4], 1e6, 1e-3);
  options.refresh_period_s = 1.0 / 60;  // 16667 us: 100, 1000 and 10000 us all become one period.
  plan = PlanExposureBracket(options);
  ASSERT_EQ(plan.size(), 3u);
  const double period_us = 1e6 / 60;
  for (double t : plan) EXPECT_NEAR(t / period_us, std::round(t / period_us), 1e-9) << t;
  EXPECT_NEAR(plan[0], period_us, 1e-9);
  EXPECT_NEAR(plan[1], 6 * period_us, 1e-9);
  EXPECT_NEAR(plan[2], 60 * period_us, 1e-6);
}

TEST(ExposureBracket, CameraThatCannotFollowTheRefreshPeriodIsAnError) {
  class CoarseCamera : public FakeDotRig {
   public:
    CoarseCamera() : FakeDotRig(0) {}
    Status SetExposure(double requested_us, double* applied_us) override {
      *applied_us = std::round(requested_us / 10000) * 10000;  // 10 ms steps.
      return Status::Ok();
    }
  } camera;
  ExposureBracketOptions options;
  options.refresh_period_s = 1.0 / 85;  // 11765 us: 10 ms steps land 0.15 periods off.
  double applied = 0;
  const Status status = ApplyBracketExposure(&camera, 11765, options, &applied);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("camera 'cam0'"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("refresh"), std::string::npos) << status.message();
  FakeDotRig fine(0);  // 10 us steps: within 2 % of a period.
  EXPECT_TRUE(ApplyBracketExposure(&fine, 11765, options, &applied).ok());
  EXPECT_NEAR(applied, 11760, 1e-9);
}

TEST(DotScan, GridSpansTheMonitorOnPixelCentres) {
  DotScanSessionOptions options = SmallScan();
  const auto grid = DotScanGrid(options);
  ASSERT_EQ(grid.size(), 16u);
  for (const auto& d : grid) {
    EXPECT_EQ(d.x() - std::floor(d.x()), 0.5);
    EXPECT_GE(d.x(), 0.1 * 160 - 1);
    EXPECT_LE(d.x(), 0.9 * 160 + 1);
    EXPECT_GE(d.y(), 0.1 * 120 - 1);
    EXPECT_LE(d.y(), 0.9 * 120 + 1);
  }
  EXPECT_LT(grid[0].x(), grid[1].x());  // Row-major, x fastest.
  EXPECT_EQ(grid[0].y(), grid[1].y());
  PatternSpec spec;
  ASSERT_TRUE(ParsePatternId(DotScanGridPattern(options), &spec).ok());
  ASSERT_EQ(spec.dots.size(), 16u);
  EXPECT_NEAR(spec.dots[5].x_px, grid[5].x(), 1e-12);
  EXPECT_NEAR(spec.dots[5].y_px, grid[5].y(), 1e-12);
}

// Several frames at the longest exposure: every dot and validation dot takes them, the dark
// bracket four times as many there (its noise is every dot's), the all-dots frame one.
TEST(DotScan, FramesAtTheLongestExposureRepeatOnlyThere) {
  DotScanSessionOptions options = SmallScan();
  options.bracket.exposures_us = {1000, 8000};
  options.validation_dots_px = {{50.5, 50.5}};
  options.longest_exposure_frames = 3;
  const std::vector<PlannedFrame> plan = PlanDotScan(options, 0);
  auto count = [&](const std::string& kind, double t, bool validation) {
    int n = 0;
    for (const PlannedFrame& f : plan)
      n += f.kind == kind && f.requested_exposure_us == t && f.validation == validation;
    return n;
  };
  EXPECT_EQ(count("all_dots", 1000, false), 1);
  EXPECT_EQ(count("all_dots", 8000, false), 1);
  EXPECT_EQ(count("dark", 1000, false), 1);
  EXPECT_EQ(count("dark", 8000, false), 12);
  EXPECT_EQ(count("dot", 1000, false), 16);
  EXPECT_EQ(count("dot", 8000, false), 16 * 3);
  EXPECT_EQ(count("dot", 8000, true), 3);
  // One frame each by default, the dark included.
  options.longest_exposure_frames = 1;
  const std::vector<PlannedFrame> single = PlanDotScan(options, 0);
  EXPECT_EQ(single.size(), 2u + 2u + 16u * 2 + 2u);
  options.longest_exposure_frames = 0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("longest_exposure_frames"), std::string::npos) << error;
}

// With frames arriving two captures late, every accepted dot frame must show its own dot.
TEST(DotScan, SynchronisationAcceptsOnlyFramesShowingTheNewPattern) {
  TempDir dir;
  FakeDotRig rig(/*latency=*/2, /*late_exposure=*/true);
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(rig.info())).ok());
  const DotScanSessionOptions options = SmallScan();
  const Status status = RunDotScanSession(options, &rig, &rig, NoSample(), &writer);
  ASSERT_TRUE(status.ok()) << status.message();
  ASSERT_TRUE(writer.Save().ok());
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  const size_t expected = 2 + 2 + 16 * 2;
  ASSERT_EQ(session.frames.size(), expected);
  EXPECT_EQ(session.UsableFrames("all_dots", "none").size(), 2u);
  EXPECT_EQ(session.UsableFrames("dark", "contaminated").size(), 2u);
  const auto dots = session.UsableFrames("dot", "contaminated");
  ASSERT_EQ(dots.size(), 32u);
  const double period_us = 1e6 / 60;
  for (const FrameRecord* f : dots) {
    ASSERT_TRUE(f->light.dot_px.has_value());
    EXPECT_EQ(f->light.projector_pattern, DotPatternId(f->light.dot_px->x(), f->light.dot_px->y()));
    // Whole refresh periods, to the camera's 10 us granularity.
    EXPECT_NEAR(f->exposure_time_us / period_us, std::round(f->exposure_time_us / period_us), 10 / period_us);
    Image dn;
    ASSERT_TRUE(LoadFrame(dir / "s", session, *f, &dn).ok());
    const Eigen::Vector2d c = Centroid(dn);
    EXPECT_NEAR(c.x(), f->light.dot_px->x() / 2, 0.2) << "frame " << f->index << " shows another pattern";
    EXPECT_NEAR(c.y(), f->light.dot_px->y() / 2, 0.2) << "frame " << f->index;
  }
  // Stale frames were seen and discarded: at least `latency` per pattern change after the first.
  // (The count lives in the writer; RunAcquisition puts it in the manifest.)
  const int discarded = writer.session().acquisition.discarded_frames;
  EXPECT_GE(discarded, 2 * 17);
  EXPECT_EQ(rig.captures(), static_cast<int>(expected) + discarded);
}

// Control: the same rig without synchronisation (first frame after each change) records stale
// frames, which is what the rule above prevents.
TEST(DotScan, WithoutSynchronisationStaleFramesWouldBeRecorded) {
  FakeDotRig rig(2);
  const auto grid = DotScanGrid(SmallScan());
  int wrong = 0;
  for (const auto& dot : grid) {
    ASSERT_TRUE(rig.ShowPattern(DotPatternId(dot.x(), dot.y())).ok());
    CapturedFrame frame;
    ASSERT_TRUE(rig.Capture(&frame).ok());
    for (float& v : frame.raw_dn.data()) v -= 64;
    wrong += (Centroid(frame.raw_dn) - dot / 2).norm() > 0.2;
  }
  EXPECT_EQ(wrong, 16);
}

TEST(DotScan, DotOutsideTheCameraViewIsAcceptedAfterAConfirmedSettle) {
  TempDir dir;
  FakeDotRig rig(1);
  SessionWriter writer;
  ASSERT_TRUE(writer.Open(dir / "s", Header(rig.info())).ok());
  DotScanSessionOptions options = SmallScan();
  options.capture_all_dots = false;
  options.capture_dark = false;
  options.grid_nx = 2;
  options.grid_ny = 1;
  // Both dots far outside the camera's view (monitor x = 1000 and 1200 px; the camera sees
  // x < 160): no change is ever visible.
  options.first_x_px = 1000.5;
  options.first_y_px = 60.5;
  options.step_x_px = 200;
  options.step_y_px = 1;
  options.bracket.exposures_us = {20000};
  const Status status = RunDotScanSession(options, &rig, &rig, NoSample(), &writer);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(writer.session().frames.size(), 2u);
  // Both patterns are invisible: each is accepted only after settle_captures captures.
  EXPECT_EQ(rig.captures(), 2 * options.sync.settle_captures);
}

TEST(DotScan, ResumeSkipsFramesOnDiskAndCompletesThePlan) {
  TempDir dir;
  const DotScanSessionOptions options = SmallScan();
  const int planned = static_cast<int>(PlanDotScan(options, 1.0 / 60).size());
  // First run: the camera dies after 15 frames.
  class DyingRig : public FakeDotRig {
   public:
    DyingRig() : FakeDotRig(1) {}
    Status Capture(CapturedFrame* frame) override {
      if (captures() >= 15) return Status::Error("camera 'cam0': GigE link down (timeout 2 s)");
      return FakeDotRig::Capture(frame);
    }
  } dying;
  AcquisitionRunOptions run;
  run.session_dir = dir / "s";
  run.plan = "dot-scan 4x4";
  run.planned_frames = planned;
  run.camera_name = "fake";
  AcquisitionResult result;
  Status status = RunAcquisition(run, Header(dying.info()), &dying,
                                 [&](Camera* camera, SessionWriter* writer) {
                                   return RunDotScanSession(options, camera, &dying, NoSample(), writer);
                                 },
                                 &result);
  ASSERT_FALSE(status.ok());
  Session failed;
  ASSERT_TRUE(ReadSession(dir / "s", &failed).ok());
  EXPECT_EQ(failed.acquisition.state, "failed");
  const int usable_before = static_cast<int>(failed.frames.size()) - 3;  // 3 failed attempts.
  EXPECT_EQ(failed.frames.back().status, FrameStatus::kFailed);
  // Resume with a working rig.
  FakeDotRig healthy(1);
  run.resume = true;
  status = RunAcquisition(run, Header(healthy.info()), &healthy,
                          [&](Camera* camera, SessionWriter* writer) {
                            return RunDotScanSession(options, camera, &healthy, NoSample(), writer);
                          },
                          &result);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(result.state, "complete");
  EXPECT_EQ(result.frames_on_disk_before, usable_before);
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  int usable = 0;
  for (const auto& f : session.frames) usable += f.status != FrameStatus::kFailed;
  EXPECT_EQ(usable, planned);
  // Each planned dot frame exactly once, and the resumed frames show the right dot.
  const auto dots = session.UsableFrames("dot", "contaminated");
  ASSERT_EQ(dots.size(), 32u);
  for (size_t k = 0; k < dots.size(); ++k) {
    const auto grid = DotScanGrid(options);
    EXPECT_NEAR((*dots[k]->light.dot_px - grid[k / 2]).norm(), 0, 1e-9);
    Image dn;
    ASSERT_TRUE(LoadFrame(dir / "s", session, *dots[k], &dn).ok());
    EXPECT_NEAR((Centroid(dn) - grid[k / 2] / 2).norm(), 0, 0.2) << "frame " << dots[k]->index;
  }
}

}  // namespace
}  // namespace thinslab
