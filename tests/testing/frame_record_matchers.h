// SPDX-License-Identifier: Apache-2.0
// gtest comparison of two manifest frame entries (core/session.h FrameRecord).
#pragma once

#include <gtest/gtest.h>

#include "thinslab/core/session.h"

namespace thinslab {

// Everything but the capture's own stamps (UTC time, camera frame id and timestamp) is equal:
// what a plan fixes, plus status, error and file. Resumed and uninterrupted runs must agree so.
inline void ExpectSamePlannedFrame(const FrameRecord& fa, const FrameRecord& fb) {
  EXPECT_EQ(fa.index, fb.index);
  EXPECT_EQ(fa.camera_id, fb.camera_id);
  EXPECT_EQ(fa.kind, fb.kind);
  EXPECT_EQ(fa.sample_state, fb.sample_state);
  EXPECT_EQ(fa.file, fb.file);
  EXPECT_EQ(fa.exposure_time_us, fb.exposure_time_us);
  EXPECT_EQ(fa.gain_db, fb.gain_db);
  EXPECT_EQ(fa.status, fb.status);
  EXPECT_EQ(fa.error, fb.error);
  EXPECT_EQ(fa.light.projector_pattern, fb.light.projector_pattern);
  EXPECT_EQ(fa.light.laser_on, fb.light.laser_on);
  EXPECT_EQ(fa.light.dot_radiance, fb.light.dot_radiance);
  ASSERT_EQ(fa.light.dot_px.has_value(), fb.light.dot_px.has_value());
  if (fa.light.dot_px) {
    EXPECT_EQ(*fa.light.dot_px, *fb.light.dot_px);
  }
}

// Every field equal (a write/read round trip).
inline void ExpectSameFrame(const FrameRecord& fa, const FrameRecord& fb) {
  ExpectSamePlannedFrame(fa, fb);
  EXPECT_EQ(fa.timestamp_utc, fb.timestamp_utc);
  EXPECT_EQ(fa.camera_frame_id, fb.camera_frame_id);
  EXPECT_EQ(fa.camera_timestamp_ns, fb.camera_timestamp_ns);
}

}  // namespace thinslab
