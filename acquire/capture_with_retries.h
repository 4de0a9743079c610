// SPDX-License-Identifier: Apache-2.0
#pragma once

#include "thinslab/acquire/session_writer.h"
#include "thinslab/drivers/camera.h"

namespace thinslab {

// Captures one frame described by `templ` (camera, kind, sample state, light) and appends it.
// A failed attempt is recorded as a "failed" frame with the device's message; the frame that
// finally succeeds is "retried" if any attempt failed. After max_retries + 1 failures the error
// names the camera and the last device message.
// The frame is first claimed (SessionWriter::ClaimStep): on a resumed session a frame of the
// plan that is already on disk is not captured again.
Status CaptureWithRetries(Camera* camera, const FrameRecord& templ, int max_retries, SessionWriter* writer);

// The manifest record of a successful capture of `templ`: what the camera reports (applied
// exposure, UTC time, its frame id and device timestamp) and `status`.
FrameRecord CapturedRecord(const FrameRecord& templ, const CapturedFrame& frame, FrameStatus status);

}  // namespace thinslab
