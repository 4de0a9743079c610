// SPDX-License-Identifier: Apache-2.0
// One acquisition run: opens a new session folder or resumes an interrupted one, runs a session
// script (shadow maps, laser lobe, dot scan, bracket) through the driver interfaces, and keeps
// the record of what happened:
//  - a frame exists once its file and its record line in journal.log (appended and fsync'd
//    after the file) are on disk; journal.log also logs the events, one line each;
//  - session.json is rewritten atomically at bounded intervals (SessionWriterOptions), at
//    every event and at the end of the run; a resume rebuilds the frames after its last write
//    from the journal (ReadSessionWithJournal), so a kill loses nothing;
//  - session.json "acquisition" holds the state ("running", "complete", "failed",
//    "interrupted"), the plan the frames follow, counters and the event list (started,
//    resumed, completed, failed with the device and its message).
// Resume (docs/acquisition.md): the script is run again from the start; every planned frame
// already usable on disk is claimed and skipped (SessionWriter::ClaimStep checks it is the same
// frame), so nothing is captured twice and frame indices continue where they stopped.
#pragma once

#include <functional>
#include <memory>
#include <ostream>
#include <string>

#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"
#include "thinslab/drivers/laser.h"

namespace thinslab {

// Remembers which device failed last, so the manifest can name it. The wrappers below report
// into it.
struct DeviceFailureTracker {
  std::string device;   // e.g. "camera 'cam0' (aravis:10.0.0.2)"
  std::string message;  // The device's error.
  void Record(const std::string& name, const Status& status) {
    if (!status.ok()) {
      device = name;
      message = status.message();
    }
  }
};

// Forwards to a Projector / Laser and records failures under `name`.
class TrackedProjector : public Projector {
 public:
  TrackedProjector(Projector* projector, std::string name, DeviceFailureTracker* tracker)
      : projector_(projector), name_(std::move(name)), tracker_(tracker) {}
  Status ShowPattern(const std::string& pattern) override;
  double refresh_period_s() const override { return projector_->refresh_period_s(); }

 private:
  Projector* projector_;
  std::string name_;
  DeviceFailureTracker* tracker_;
};

class TrackedLaser : public Laser {
 public:
  TrackedLaser(Laser* laser, std::string name, DeviceFailureTracker* tracker)
      : laser_(laser), name_(std::move(name)), tracker_(tracker) {}
  Status SetEmission(bool on) override;

 private:
  Laser* laser_;
  std::string name_;
  DeviceFailureTracker* tracker_;
};

struct AcquisitionRunOptions {
  std::string session_dir;
  bool resume = false;
  // Canonical text of the kind and the options that fix the frame plan; a resume must give the
  // same plan.
  std::string plan;
  int planned_frames = 0;  // Usable frames the script will produce (progress and the record).
  std::string camera_name;  // How the camera was opened, e.g. "sim" or "aravis:10.0.0.2".
  std::string label = "acquire";  // Progress line prefix.
  std::ostream* progress = nullptr;  // Null: quiet.
  bool progress_is_terminal = false;
  // Polled between frames; a non-empty reason stops the run as "interrupted".
  std::function<std::string()> stop_check;
  DeviceFailureTracker* tracker = nullptr;  // Optional: projector/laser failures.
  // When session.json is rewritten; `journal` is always on for an acquisition.
  SessionWriterOptions writer;

  bool Check(std::string* error) const;
};

struct AcquisitionResult {
  std::string state;         // Final acquisition.state.
  int frames_on_disk_before = 0;  // Usable frames found when resuming.
  int frames_captured = 0;   // Usable frames captured in this run.
  int camera_captures = 0;   // Capture calls in this run.
  bool already_complete = false;  // --resume of a complete session: nothing done.
};

// `header` describes the rig (cameras[0] must be `camera`'s info) and the session name and kind;
// its frames are ignored. The script receives a camera wrapper that counts captures and
// records failures, and the writer to pass to the session functions. Returns the script's
// error (device failures name the device); the manifest then says what happened.
using SessionScript = std::function<Status(Camera* camera, SessionWriter* writer)>;
Status RunAcquisition(const AcquisitionRunOptions& options, const Session& header, Camera* camera,
                      const SessionScript& script, AcquisitionResult* result);

// `thinslab acquire fold-journal`: writes into session.json the frame records that only
// journal.log holds (the recovery rule of docs/format.md 10.2), without the devices and without
// capturing, so that tools which read session.json alone see every frame of a killed capture.
// Takes the session folder's lock (refused while a capture runs in it) and repairs what a kill
// leaves as a resume does; the acquisition state and events are kept as they are.
struct JournalFoldResult {
  int folded_frames = 0;  // Records taken from the journal (0: session.json had them all).
  int frames = 0;         // Records in session.json now.
  std::string state;      // acquisition.state, unchanged.
};
Status FoldJournalIntoManifest(const std::string& session_dir, JournalFoldResult* result);

}  // namespace thinslab

