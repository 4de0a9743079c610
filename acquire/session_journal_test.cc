// SPDX-License-Identifier: Apache-2.0
// Acquisition runs: a device failing mid-session leaves a manifest that says what happened,
// resume completes the plan without losing or duplicating a frame, and a resume with another
// plan is refused.
#include "thinslab/acquire/session_journal.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <set>
#include <sstream>

#include "thinslab/acquire/progress.h"
#include "thinslab/acquire/capture_with_retries.h"
#include "thinslab/acquire/session_lock.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/tiny_session.h"

namespace thinslab {
namespace {

// Returns a frame whose pixels encode the capture number; fails every capture from
// `fail_from` on (a camera unplugged mid-session).
class CountingFakeCamera : public Camera {
 public:
  explicit CountingFakeCamera(int fail_from = -1) : info_(TinyCamera("fake")), fail_from_(fail_from) {}
  const CameraInfo& info() const override { return info_; }
  Status SetExposure(double requested_us, double* applied_us) override {
    exposure_us_ = std::round(requested_us);
    *applied_us = exposure_us_;
    return Status::Ok();
  }
  Status Capture(CapturedFrame* frame) override {
    if (fail_from_ >= 0 && captures_ >= fail_from_) {
      ++timeouts_;
      return Status::Error("camera 'cam0' (fake): no buffer within 2 s (timeout)");
    }
    frame->raw_dn = Image(8, 6, static_cast<float>(100 + captures_++));
    frame->exposure_time_us = exposure_us_;
    frame->timestamp_utc = "2026-11-23T00:00:00Z";
    return Status::Ok();
  }
  std::map<std::string, double> statistics() const override {
    return {{"completed_buffers", captures_}, {"timeouts", timeouts_}};
  }

 private:
  CameraInfo info_;
  int fail_from_;
  int captures_ = 0;
  double timeouts_ = 0;
  double exposure_us_ = 1000;
};

Session Header(const CameraInfo& camera) {
  Session header = TinySessionHeader("shadow_map", camera);
  header.name = "journal";
  return header;
}

// The frames of a small shadow-map session (2 dark, 3 reference, 3 shadow), one capture each
// with retries: the bookkeeping of RunAcquisition under test, without display synchronisation
// (acquire/shadow_map_session_test.cc tests that).
Status CaptureShadowPlan(Camera* camera, SessionWriter* writer) {
  const struct {
    const char* kind;
    const char* sample_state;
    int count;
  } steps[] = {{"dark", "clean", 2}, {"reference", "clean", 3}, {"shadow", "contaminated", 3}};
  for (const auto& step : steps) {
    for (int i = 0; i < step.count; ++i) {
      FrameRecord templ;
      templ.camera_id = camera->info().id;
      templ.kind = step.kind;
      templ.sample_state = step.sample_state;
      templ.exposure_time_us = 1000;
      THINSLAB_RETURN_IF_ERROR(CaptureWithRetries(camera, templ, /*max_retries=*/2, writer));
    }
  }
  return Status::Ok();
}

Status RunShadow(const std::string& dir, bool resume, const std::string& plan, Camera* camera,
                 AcquisitionResult* result, std::function<std::string()> stop = nullptr) {
  AcquisitionRunOptions run;
  run.session_dir = dir;
  run.resume = resume;
  run.plan = plan;
  run.planned_frames = 8;
  run.camera_name = "fake";
  run.stop_check = std::move(stop);
  return RunAcquisition(run, Header(camera->info()), camera, CaptureShadowPlan, result);
}

TEST(AcquisitionRun, DeviceFailingMidSessionLeavesAManifestThatSaysWhatHappened) {
  TempDir dir;
  CountingFakeCamera camera(/*fail_from=*/5);
  AcquisitionResult result;
  const Status status = RunShadow(dir / "s", false, "shadow-maps frames=3", &camera, &result);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("camera 'cam0'"), std::string::npos) << status.message();
  EXPECT_EQ(result.state, "failed");
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());  // Still a valid capture.
  ASSERT_TRUE(session.acquisition.present);
  EXPECT_EQ(session.acquisition.state, "failed");
  ASSERT_GE(session.acquisition.events.size(), 2u);
  EXPECT_EQ(session.acquisition.events.front().event, "started");
  const AcquisitionEvent& last = session.acquisition.events.back();
  EXPECT_EQ(last.event, "failed");
  EXPECT_EQ(last.device, "camera 'cam0' (fake)");
  EXPECT_NE(last.message.find("timeout"), std::string::npos) << last.message;
  // Five usable frames, then the three attempts at frame 6, recorded as failed.
  ASSERT_EQ(session.frames.size(), 8u);
  for (int i = 0; i < 5; ++i) EXPECT_NE(session.frames[i].status, FrameStatus::kFailed);
  for (int i = 5; i < 8; ++i) {
    EXPECT_EQ(session.frames[i].status, FrameStatus::kFailed);
    EXPECT_NE(session.frames[i].error.find("timeout"), std::string::npos);
  }
  EXPECT_EQ(session.acquisition.camera_captures, 8);
  ASSERT_EQ(session.rig.cameras[0].stream_statistics.count("timeouts"), 1u);
  EXPECT_EQ(session.rig.cameras[0].stream_statistics.at("timeouts"), 3);
  // The journal tells the same story, line by line.
  std::string journal;
  ASSERT_TRUE(ReadFileToString(dir / "s/journal.log", &journal).ok());
  EXPECT_NE(journal.find("started at 0 frames"), std::string::npos) << journal;
  EXPECT_NE(journal.find("frame 4 ok"), std::string::npos) << journal;
  EXPECT_NE(journal.find("frame 7 failed"), std::string::npos) << journal;
  EXPECT_NE(journal.find("failed at 8 frames: camera 'cam0' (fake)"), std::string::npos) << journal;
}

// A display or a laser that fails mid-session (window lost, USB relay unplugged): the frames
// before stay, and the manifest's failed event names that device, not the camera.
class FailingProjector : public Projector {
 public:
  explicit FailingProjector(int fail_from) : fail_from_(fail_from) {}
  Status ShowPattern(const std::string& pattern) override {
    if (calls_++ >= fail_from_) return Status::Error("SDL_RenderPresent failed showing '" + pattern + "'");
    return Status::Ok();
  }

 private:
  int fail_from_;
  int calls_ = 0;
};

class FailingLaser : public Laser {
 public:
  explicit FailingLaser(int fail_from) : fail_from_(fail_from) {}
  Status SetEmission(bool on) override {
    if (calls_++ >= fail_from_) return Status::Error(std::string("LIBUSB_ERROR_NO_DEVICE switching ") + (on ? "on" : "off"));
    return Status::Ok();
  }

 private:
  int fail_from_;
  int calls_ = 0;
};

TEST(AcquisitionRun, DisplayOrLaserFailingMidSessionIsTheDeviceTheManifestNames) {
  for (const bool laser_fails : {false, true}) {
    SCOPED_TRACE(laser_fails ? "laser" : "display");
    TempDir dir;
    CountingFakeCamera camera;
    FailingProjector failing_display(laser_fails ? 1000 : 3);
    FailingLaser failing_laser(laser_fails ? 3 : 1000);
    DeviceFailureTracker tracker;
    TrackedProjector display(&failing_display, "display 1", &tracker);
    TrackedLaser laser(&failing_laser, "laser 16c0:05df (hid-relay)", &tracker);
    // One pattern and one laser state per frame, as the sessions do.
    const SessionScript script = [&](Camera* recording, SessionWriter* writer) {
      for (int i = 0; i < 8; ++i) {
        THINSLAB_RETURN_IF_ERROR(display.ShowPattern(i % 2 ? "flat" : ""));
        THINSLAB_RETURN_IF_ERROR(laser.SetEmission(i % 2 == 1));
        FrameRecord templ;
        templ.camera_id = recording->info().id;
        templ.kind = i % 2 ? "reference" : "dark";
        templ.sample_state = "clean";
        THINSLAB_RETURN_IF_ERROR(CaptureWithRetries(recording, templ, /*max_retries=*/2, writer));
      }
      return Status::Ok();
    };
    AcquisitionRunOptions run;
    run.session_dir = dir / "s";
    run.plan = "p";
    run.planned_frames = 8;
    run.camera_name = "fake";
    run.tracker = &tracker;
    AcquisitionResult result;
    const Status status = RunAcquisition(run, Header(camera.info()), &camera, script, &result);
    ASSERT_FALSE(status.ok());
    EXPECT_EQ(result.state, "failed");
    Session session;
    ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
    EXPECT_EQ(session.acquisition.state, "failed");
    const AcquisitionEvent& last = session.acquisition.events.back();
    EXPECT_EQ(last.event, "failed");
    EXPECT_EQ(last.device, laser_fails ? "laser 16c0:05df (hid-relay)" : "display 1");
    EXPECT_NE(last.message.find(laser_fails ? "LIBUSB_ERROR_NO_DEVICE" : "SDL_RenderPresent"), std::string::npos)
        << last.message;
    // Three frames were taken before the fourth light state failed; none was captured under it.
    ASSERT_EQ(session.frames.size(), 3u);
    for (const FrameRecord& f : session.frames) EXPECT_EQ(f.status, FrameStatus::kOk);
    EXPECT_EQ(session.acquisition.camera_captures, 3);
  }
}

TEST(AcquisitionRun, ResumeAfterFailureCompletesWithoutLosingOrDuplicatingFrames) {
  TempDir dir;
  AcquisitionResult result;
  CountingFakeCamera dying(/*fail_from=*/5);
  ASSERT_FALSE(RunShadow(dir / "s", false, "p", &dying, &result).ok());
  std::string frame3_before;
  Session before;
  ASSERT_TRUE(ReadSession(dir / "s", &before).ok());
  ASSERT_TRUE(ReadFileToString(dir / ("s/" + before.frames[3].file), &frame3_before).ok());

  CountingFakeCamera healthy;
  const Status status = RunShadow(dir / "s", true, "p", &healthy, &result);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(result.frames_on_disk_before, 5);
  EXPECT_EQ(result.frames_captured, 3);
  EXPECT_EQ(result.camera_captures, 3);  // Nothing captured twice.
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  EXPECT_EQ(session.acquisition.state, "complete");
  ASSERT_EQ(session.frames.size(), 11u);  // 5 + 3 failed + 3 new.
  std::set<std::string> files;
  for (const auto& f : session.frames) {
    if (f.status != FrameStatus::kFailed) {
      EXPECT_TRUE(files.insert(f.file).second) << "duplicate " << f.file;
    }
  }
  EXPECT_EQ(files.size(), 8u);
  EXPECT_EQ(session.UsableFrames("dark").size(), 2u);
  EXPECT_EQ(session.UsableFrames("reference", "clean").size(), 3u);
  EXPECT_EQ(session.UsableFrames("shadow", "contaminated").size(), 3u);
  // The frames before the failure are untouched; the new ones come from the new camera.
  std::string frame3_after;
  ASSERT_TRUE(ReadFileToString(dir / ("s/" + session.frames[3].file), &frame3_after).ok());
  EXPECT_EQ(frame3_before, frame3_after);
  Image first_new;
  ASSERT_TRUE(LoadFrame(dir / "s", session, session.frames[8], &first_new).ok());
  EXPECT_EQ(first_new.at(0, 0), 100.0f);
  std::vector<std::string> events;
  for (const auto& e : session.acquisition.events) events.push_back(e.event);
  EXPECT_EQ(events, (std::vector<std::string>{"started", "failed", "resumed", "completed"}));

  // Resuming a complete session captures nothing.
  CountingFakeCamera idle;
  ASSERT_TRUE(RunShadow(dir / "s", true, "p", &idle, &result).ok());
  EXPECT_TRUE(result.already_complete);
  EXPECT_EQ(result.camera_captures, 0);
}

TEST(AcquisitionRun, RefusesAnotherPlanANonEmptyFolderAndNothingToResume) {
  TempDir dir;
  AcquisitionResult result;
  CountingFakeCamera dying(3);
  ASSERT_FALSE(RunShadow(dir / "s", false, "shadow-maps frames=3", &dying, &result).ok());
  CountingFakeCamera camera;
  Status status = RunShadow(dir / "s", true, "shadow-maps frames=4", &camera, &result);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("acquisition.plan"), std::string::npos) << status.message();
  status = RunShadow(dir / "s", false, "shadow-maps frames=3", &camera, &result);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("--resume"), std::string::npos) << status.message();
  status = RunShadow(dir / "nothing", true, "shadow-maps frames=3", &camera, &result);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("nothing to resume"), std::string::npos) << status.message();
  // Refused runs leave the folder as it was.
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  EXPECT_EQ(session.acquisition.state, "failed");
  EXPECT_EQ(session.frames.size(), 6u);
}

TEST(AcquisitionRun, StopRequestEndsAsInterruptedAndResumes) {
  TempDir dir;
  AcquisitionResult result;
  CountingFakeCamera camera;
  int polls = 0;
  const Status status =
      RunShadow(dir / "s", false, "p", &camera, &result, [&]() { return ++polls > 4 ? "interrupted by SIGINT" : ""; });
  ASSERT_FALSE(status.ok());
  Session session;
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  EXPECT_EQ(session.acquisition.state, "interrupted");
  EXPECT_EQ(session.frames.size(), 4u);
  CountingFakeCamera again;
  ASSERT_TRUE(RunShadow(dir / "s", true, "p", &again, &result).ok());
  ASSERT_TRUE(ReadSession(dir / "s", &session).ok());
  EXPECT_EQ(session.frames.size(), 8u);
  EXPECT_EQ(result.camera_captures, 4);
}

TEST(AcquisitionRun, ResumeRemovesTemporariesOfAKilledWrite) {
  TempDir dir;
  AcquisitionResult result;
  CountingFakeCamera dying(2);
  ASSERT_FALSE(RunShadow(dir / "s", false, "p", &dying, &result).ok());
  ASSERT_TRUE(WriteFileAtomically(dir / "s/frames/cam0/dark/0002.png.tmp-123", "partial").ok());
  CountingFakeCamera camera;
  ASSERT_TRUE(RunShadow(dir / "s", true, "p", &camera, &result).ok());
  EXPECT_FALSE(FileExists(dir / "s/frames/cam0/dark/0002.png.tmp-123"));
}

TEST(AcquisitionRun, AFolderLockedByAnotherRunIsRefusedAndLeftUntouched) {
  TempDir dir;
  AcquisitionResult result;
  CountingFakeCamera dying(3);
  ASSERT_FALSE(RunShadow(dir / "s", false, "p", &dying, &result).ok());
  // What a kill mid-write leaves, and a running capture is still writing: a temporary and a
  // journal line without its newline. A second process must not "repair" them.
  ASSERT_TRUE(WriteFileAtomically(dir / "s/frames/cam0/dark/0009.png.tmp-77", "being written").ok());
  { std::ofstream(dir / "s/journal.log", std::ios::app) << "2026-12-02T00:00:00.000Z frame 6 ok capt"; }
  std::string journal_before;
  ASSERT_TRUE(ReadFileToString(dir / "s/journal.log", &journal_before).ok());

  SessionFolderLock running;  // Another capture in the folder (here: this process).
  ASSERT_TRUE(running.Acquire(dir / "s").ok());
  const std::string in_use = "in use by another thinslab acquire (process " + std::to_string(::getpid()) + ")";
  CountingFakeCamera camera;
  Status status = RunShadow(dir / "s", true, "p", &camera, &result);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find(dir / "s"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find(in_use), std::string::npos) << status.message();
  JournalFoldResult fold;
  status = FoldJournalIntoManifest(dir / "s", &fold);
  EXPECT_NE(status.message().find(in_use), std::string::npos) << status.message();
  SessionFolderLock second;
  EXPECT_NE(second.Acquire(dir / "s").message().find(in_use), std::string::npos);
  EXPECT_EQ(camera.statistics().at("completed_buffers"), 0);
  EXPECT_TRUE(FileExists(dir / "s/frames/cam0/dark/0009.png.tmp-77"));
  std::string journal_after;
  ASSERT_TRUE(ReadFileToString(dir / "s/journal.log", &journal_after).ok());
  EXPECT_EQ(journal_after, journal_before);

  // A new session whose folder another run has just locked (it holds only the lock file).
  SessionFolderLock other;
  ASSERT_TRUE(other.Acquire(dir / "new").ok());
  status = RunShadow(dir / "new", false, "p", &camera, &result);
  EXPECT_NE(status.message().find(in_use), std::string::npos) << status.message();
  EXPECT_FALSE(FileExists(dir / "new/session.json"));
  other.Release();
  // Once released (the holder ended or was killed), the folder is ours.
  ASSERT_TRUE(RunShadow(dir / "new", false, "p", &camera, &result).ok());
  running.Release();
  CountingFakeCamera healthy;
  status = RunShadow(dir / "s", true, "p", &healthy, &result);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_FALSE(FileExists(dir / "s/frames/cam0/dark/0009.png.tmp-77"));
}

TEST(AcquisitionRun, ReaderRefusesAnUnknownAcquisitionState) {
  TempDir dir;
  AcquisitionResult result;
  CountingFakeCamera camera;
  ASSERT_TRUE(RunShadow(dir / "s", false, "p", &camera, &result).ok());
  std::string text;
  ASSERT_TRUE(ReadFileToString(dir / "s/session.json", &text).ok());
  const size_t at = text.find("\"state\": \"complete\"");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, std::string("\"state\": \"complete\"").size(), "\"state\": \"paused\"");
  ASSERT_TRUE(WriteFileAtomically(dir / "s/session.json", text).ok());
  Session session;
  const Status status = ReadSession(dir / "s", &session);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("acquisition.state"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("paused"), std::string::npos) << status.message();
}

TEST(Progress, FormatsDoneTotalRateAndEta) {
  EXPECT_EQ(FormatProgress(0, 40, 0, 0), "0/40 frames (0%), ETA ?");
  EXPECT_EQ(FormatProgress(10, 40, 10, 5), "10/40 frames (25%), 2.00 frames/s, ETA 0:15");
  // Frames skipped on resume do not count towards the rate.
  EXPECT_EQ(FormatProgress(30, 40, 5, 10), "30/40 frames (75%), 0.50 frames/s, ETA 0:20");
  EXPECT_EQ(FormatProgress(40, 40, 40, 20), "40/40 frames (100%), 2.00 frames/s, ETA 0:00");
  std::ostringstream out;
  ProgressReporter reporter("acquire test", 4, &out, /*is_terminal=*/false, /*line_interval_s=*/0);
  reporter.Update(1, 0);
  reporter.Update(4, 0);
  reporter.Finish("complete");
  EXPECT_NE(out.str().find("acquire test: 4/4 frames (100%)"), std::string::npos) << out.str();
  EXPECT_NE(out.str().find("acquire test: complete"), std::string::npos) << out.str();
}

}  // namespace
}  // namespace thinslab
