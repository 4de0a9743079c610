// SPDX-License-Identifier: Apache-2.0
// Writes a capture session as frames arrive: each frame file, then the manifest, each
// atomically, so the folder is a valid session after every frame. A failed device call is
// recorded as a frame with status "failed" and the device's message, never dropped.
// Opening an existing session resumes it: frames already on disk are kept.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

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
  // Replaces the transport statistics recorded for camera `camera_id` (Camera::statistics());
  // they are written with the next frame, so the manifest holds them as of its last frame.
  void SetCameraStatistics(const std::string& camera_id, const std::map<std::string, double>& statistics);

  const Session& session() const { return session_; }
  const std::string& dir() const { return dir_; }

  // Resume (docs/acquisition.md): a session script claims each planned capture, in plan order,
  // before taking it. The first steps_on_disk() claims are the usable frames already in the
  // manifest: ClaimStep checks that the plan asks for the same frame (camera, kind, sample
  // state, light, exposure) and sets *already_on_disk, so the script skips it; later claims
  // are new captures. A mismatch is an error (the session was started with another plan).
  // The stop predicate, if set, is polled here so a signal stops the script between frames.
  Status ClaimStep(const FrameRecord& planned, bool* already_on_disk);
  int steps_on_disk() const { return static_cast<int>(on_disk_.size()); }
  int steps_claimed() const { return steps_claimed_; }
  // Usable frame on disk for a claimed step < steps_on_disk() (nullptr otherwise).
  const FrameRecord* FrameOnDisk(int step) const;
  // Called after every claim and every frame written (progress reporting).
  void set_observer(std::function<void()> observer) { observer_ = std::move(observer); }
  // Returns a non-empty reason when the script must stop (e.g. "interrupted by SIGINT").
  void set_stop_check(std::function<std::string()> stop_check) { stop_check_ = std::move(stop_check); }
  // Bookkeeping outside the frame list (acquisition record, camera statistics); Save() writes
  // the manifest atomically.
  Session* mutable_session() { return &session_; }
  Status Save();

 private:
  void Notify() {
    if (observer_) observer_();
  }

  std::string dir_;
  Session session_;
  std::vector<int> on_disk_;  // Positions in session_.frames of usable frames, by index.
  int steps_claimed_ = 0;
  std::function<void()> observer_;
  std::function<std::string()> stop_check_;
};

std::string UtcTimestampNow();

}  // namespace thinslab
