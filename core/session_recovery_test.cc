// SPDX-License-Identifier: Apache-2.0
// What a reader learns beyond the manifest: the camera frame-id audit (gaps, restarts, skips the
// discarded or failed captures do not explain) and ReadCapture's refusal of a capture whose
// acquisition did not complete. The journal recovery itself is tested with the writer
// (acquire/session_writer_test.cc) and through a killed `thinslab acquire`
// (tests/cli_acquire_test.cc).
#include "thinslab/core/session_recovery.h"

#include <gtest/gtest.h>

#include <string>

#include "thinslab/core/session_io.h"
#include "tests/testing/temp_dir.h"
#include "tests/testing/tiny_session.h"

namespace thinslab {
namespace {

// A failed frame needs no file, so these sessions are valid without images.
FrameRecord FailedFrame(int index, std::optional<uint64_t> camera_frame_id) {
  FrameRecord f;
  f.index = index;
  f.camera_id = "cam0";
  f.kind = "shadow";
  f.sample_state = "contaminated";
  f.exposure_time_us = 1000;
  f.timestamp_utc = "2026-12-02T00:00:00Z";
  f.status = FrameStatus::kFailed;
  f.error = "test";
  f.camera_frame_id = camera_frame_id;
  return f;
}

Session AcquiredSession(const std::string& state, int captures) {
  Session s = TinySessionHeader("shadow_map");
  s.acquisition.present = true;
  s.acquisition.state = state;
  s.acquisition.planned_frames = 10;
  s.acquisition.camera_captures = captures;
  AcquisitionEvent started;
  started.time_utc = "2026-12-02T00:00:00Z";
  started.event = "started";
  s.acquisition.events.push_back(started);
  return s;
}

TEST(CameraFrameIdAudit, CountsGapsAndRestartsAndWhatTheCapturesExplain) {
  // Ids 5 6 [7 8 skipped] 9 | restart 1 2 [3 skipped] 4: 3 ids skipped in 2 gaps, 1 restart.
  Session s = AcquiredSession("complete", 0);
  const uint64_t ids[] = {5, 6, 9, 1, 2, 4};
  for (int i = 0; i < 6; ++i) s.frames.push_back(FailedFrame(i, ids[i]));
  s.frames.push_back(FailedFrame(6, std::nullopt));  // Not stamped: not audited.

  s.acquisition.camera_captures = 7 + 3;  // 3 captures left no stamped frame: explains 3 skips.
  CaptureCompleteness c = AssessCapture(s, 0);
  ASSERT_EQ(c.frame_ids.size(), 1u);
  const CameraFrameIdAudit& a = c.frame_ids[0];
  EXPECT_EQ(a.stamped_frames, 6);
  EXPECT_EQ(a.first_id, 5u);
  EXPECT_EQ(a.last_id, 4u);
  EXPECT_EQ(a.gaps, 2);
  EXPECT_EQ(a.skipped_ids, 3u);
  EXPECT_EQ(a.restarts, 1);
  EXPECT_EQ(a.unstamped_captures, 4);  // 10 captures - 6 stamped.
  EXPECT_EQ(a.unexplained_skips, 0u);
  EXPECT_EQ(SummarizeCompleteness(c).find("WARNING"), std::string::npos);

  s.acquisition.camera_captures = 8;  // 2 unstamped captures explain 2 of the 3 skips.
  c = AssessCapture(s, 0);
  EXPECT_EQ(c.frame_ids[0].unexplained_skips, 1u);
  EXPECT_NE(SummarizeCompleteness(c).find("WARNING: 1 frame(s) the camera numbered"), std::string::npos)
      << SummarizeCompleteness(c);

  // Without an acquisition record the captures are unknown: nothing is called unexplained.
  s.acquisition = AcquisitionInfo();
  c = AssessCapture(s, 0);
  EXPECT_EQ(c.frame_ids[0].unstamped_captures, -1);
  EXPECT_EQ(c.frame_ids[0].unexplained_skips, 0u);
  EXPECT_TRUE(c.complete());
}

TEST(ReadCapture, RefusesAnUnfinishedAcquisitionUnlessAccepted) {
  TempDir dir;
  for (const std::string state : {"running", "failed", "interrupted"}) {
    const std::string session_dir = dir / state;
    Session s = AcquiredSession(state, 2);
    s.frames.push_back(FailedFrame(0, std::nullopt));
    AcquisitionEvent failed;
    failed.time_utc = "2026-12-02T00:00:01Z";
    failed.event = state == "running" ? "resumed" : state;
    failed.device = "camera 'cam0' (aravis:127.0.0.1)";
    failed.message = "timeout";
    failed.frames = 1;
    s.acquisition.events.push_back(failed);
    ASSERT_TRUE(WriteSession(session_dir, s).ok());

    Session read;
    CaptureCompleteness c;
    const Status refused = ReadCapture(session_dir, IncompleteCapture::kRefuse, &read, &c);
    ASSERT_FALSE(refused.ok()) << state;
    EXPECT_NE(refused.message().find(session_dir + "/session.json: acquisition"), std::string::npos) << refused.message();
    EXPECT_NE(refused.message().find("state " + state), std::string::npos) << refused.message();
    EXPECT_NE(refused.message().find("0 of 10 planned frames usable"), std::string::npos) << refused.message();
    EXPECT_NE(refused.message().find("camera 'cam0' (aravis:127.0.0.1): timeout"), std::string::npos)
        << refused.message();
    EXPECT_NE(refused.message().find("--resume"), std::string::npos) << refused.message();
    EXPECT_FALSE(c.complete());

    ASSERT_TRUE(ReadCapture(session_dir, IncompleteCapture::kAccept, &read, &c).ok()) << state;
    EXPECT_EQ(read.frames.size(), 1u);
    EXPECT_EQ(c.state, state);
  }
  // Complete, and captures not written by `thinslab acquire`, are read either way.
  for (const bool acquired : {true, false}) {
    const std::string session_dir = dir / (acquired ? "complete" : "simulated");
    Session s = AcquiredSession("complete", 1);
    if (!acquired) s.acquisition = AcquisitionInfo();
    s.frames.push_back(FailedFrame(0, std::nullopt));
    ASSERT_TRUE(WriteSession(session_dir, s).ok());
    Session read;
    CaptureCompleteness c;
    ASSERT_TRUE(ReadCapture(session_dir, IncompleteCapture::kRefuse, &read, &c).ok());
    EXPECT_TRUE(c.complete());
    EXPECT_EQ(c.acquired, acquired);
  }
}

}  // namespace
}  // namespace thinslab
