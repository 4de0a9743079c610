// SPDX-License-Identifier: Apache-2.0
// Writes a capture session as frames arrive: each frame file, then the manifest, each
// atomically, so the folder is a valid session after every frame. A failed device call is
// recorded as a frame with status "failed" and the device's message, never dropped.
// Opening an existing session resumes it: frames already on disk are kept.
#pragma once

#include <string>

#include "core/image.h"
#include "core/session.h"
#include "core/status.h"

namespace thinslab {

class SessionWriter {
 public:
  // Creates `session_dir` with `header` (rig, name, kind; frames ignored), or, if it already
  // holds a session.json, loads it so that new frames are appended (resume).
  Status Open(const std::string& session_dir, const Session& header);

  // Writes `raw_dn` to frames/<camera>/<kind>/<index>.png and appends `record` (index and
  // file are assigned here). Returns the index assigned.
  Status AddFrame(FrameRecord record, const Image& raw_dn, int* index = nullptr);
  // Appends a failed frame (no file) with the device error.
  Status AddFailedFrame(FrameRecord record, const std::string& error);

  const Session& session() const { return session_; }
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
  Session session_;
};

std::string UtcTimestampNow();

}  // namespace thinslab
