// SPDX-License-Identifier: Apache-2.0
// Writes a capture session as frames arrive. A failed device call is recorded as a frame with
// status "failed" and the device's message, never dropped. Opening an existing session resumes
// it: frames already on disk are kept.
//
// What is durable when (docs/acquisition.md, "Atomic frames, the journal and the manifest"):
// each frame file is written atomically; then, with SessionWriterOptions::journal, its record
// is appended to journal.log as one fsync'd line. That pair is the durable record of the frame.
// session.json is rewritten atomically only at bounded intervals (ManifestIsDue) and by Save(),
// so its cost per frame is O(1) amortised instead of O(frames). A session killed between two
// manifest writes loses nothing: ReadSessionWithJournal (and Open on resume) rebuild the frame
// list from the manifest plus the journal lines after it.
#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/session_recovery.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct SessionWriterOptions {
  // Append every frame record to journal.log (fsync'd) after its file: what makes frames
  // between manifest writes durable and resumable. `thinslab acquire` turns it on; simulated
  // captures, which are never resumed, leave it off.
  bool journal = false;
  // session.json is rewritten once the records added since its last write number at least
  // max(manifest_min_new_frames, manifest_growth_fraction x records it held): a geometric
  // schedule, so the bytes written over a session are O(frames) ...
  int manifest_min_new_frames = 32;
  double manifest_growth_fraction = 0.25;  // >= 0; 0 = every manifest_min_new_frames records.
  // ... and at least every manifest_max_age_s seconds while records arrive, so that a reader
  // of a running capture (`thinslab info`) is never more than that behind.
  double manifest_max_age_s = 10;

  bool Check(std::string* error) const;
};

class SessionWriter {
 public:
  SessionWriter() = default;
  ~SessionWriter();  // Closes journal.log; does not write the manifest (call Save()).
  SessionWriter(const SessionWriter&) = delete;
  SessionWriter& operator=(const SessionWriter&) = delete;

  // Creates `session_dir` with `header` (rig, name, kind; frames ignored), or, if it already
  // holds a session.json, loads it so that new frames are appended (resume). With
  // options.journal a resume also takes the frames journaled after the last manifest write
  // (ReadSessionWithJournal), drops a journal line a kill left incomplete, and removes frame
  // files no record names (written, then killed before their journal line).
  Status Open(const std::string& session_dir, const Session& header,
              const SessionWriterOptions& options = SessionWriterOptions());

  // Writes `raw_dn` to frames/<camera>/<kind>/<index>.png and appends `record` (index and
  // file are assigned here). Returns the index assigned.
  Status AddFrame(FrameRecord record, const Image& raw_dn, int* index = nullptr);
  // Appends a failed frame (no file) with the device error.
  Status AddFailedFrame(FrameRecord record, const std::string& error);
  // Replaces the transport statistics recorded for camera `camera_id` (Camera::statistics());
  // they are written with the next manifest write.
  void SetCameraStatistics(const std::string& camera_id, const std::map<std::string, double>& statistics);
  // Appends `text` as a line "<UTC time> <text>" to journal.log (fsync'd). Event lines of
  // RunAcquisition; a no-op without options.journal.
  Status AppendJournalLine(const std::string& text);

  const Session& session() const { return session_; }
  const std::string& dir() const { return dir_; }

  // Resume (docs/acquisition.md): a session script claims each planned capture, in plan order,
  // before taking it. The first steps_on_disk() claims are the usable frames already in the
  // session: ClaimStep checks that the plan asks for the same frame (camera, kind, sample
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
  // Bookkeeping outside the frame list (acquisition record, camera statistics).
  Session* mutable_session() { return &session_; }
  // Writes the manifest atomically now. Call it when the script ends, whatever its outcome
  // (RunAcquisition does): frames added since the last write are in the manifest only then.
  Status Save();
  // Records added since the manifest was last written.
  int unsaved_frames() const { return static_cast<int>(session_.frames.size()) - frames_in_manifest_; }

 private:
  void Notify() {
    if (observer_) observer_();
  }
  // Journals the newest record, then rewrites the manifest if it is due.
  Status Record();
  bool ManifestIsDue() const;
  Status RemoveUnrecordedFrameFiles() const;

  std::string dir_;
  SessionWriterOptions options_;
  Session session_;
  std::vector<int> on_disk_;  // Positions in session_.frames of usable frames, by index.
  int steps_claimed_ = 0;
  int frames_in_manifest_ = 0;
  std::chrono::steady_clock::time_point manifest_written_at_;
  int journal_fd_ = -1;
  std::function<void()> observer_;
  std::function<std::string()> stop_check_;
};

std::string UtcTimestampNow();

}  // namespace thinslab
