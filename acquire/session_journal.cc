// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/session_journal.h"

#include <algorithm>
#include <exception>
#include <filesystem>
#include <new>
#include <regex>
#include <sstream>

#include "thinslab/acquire/progress.h"
#include "thinslab/acquire/session_lock.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

// Temporary siblings WriteFileAtomically leaves behind when the process is killed between
// writing and renaming ("<name>.tmp-<pid>"); never part of a session.
void RemoveStaleTemporaries(const std::string& session_dir) {
  static const std::regex tmp_name(R"(.*\.tmp-[0-9]+$)");
  std::error_code ec;
  std::vector<fs::path> stale;
  for (auto it = fs::recursive_directory_iterator(session_dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (it->is_regular_file(ec) && std::regex_match(it->path().filename().string(), tmp_name)) {
      stale.push_back(it->path());
    }
  }
  for (const auto& p : stale) fs::remove(p, ec);
}

bool OnlyTheLockIn(const std::string& dir) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.path().filename() != kSessionLockName) return false;
  }
  return !ec;
}

void AddEvent(Session* session, const std::string& event, const std::string& device, const std::string& message) {
  AcquisitionEvent e;
  e.time_utc = UtcTimestampNow();
  e.event = event;
  e.device = device;
  e.message = message;
  e.frames = static_cast<int>(session->frames.size());
  session->acquisition.events.push_back(e);
}

std::string EventLine(const AcquisitionEvent& e) {
  std::string line = e.event + " at " + std::to_string(e.frames) + " frames";
  if (!e.device.empty()) line += ": " + e.device;
  if (!e.message.empty()) line += ": " + e.message;
  return line;
}

// Counts captures into the manifest's record and remembers a failing camera.
class RecordingCamera : public Camera {
 public:
  RecordingCamera(Camera* camera, std::string name, SessionWriter* writer, DeviceFailureTracker* tracker)
      : camera_(camera), name_(std::move(name)), writer_(writer), tracker_(tracker) {}
  const CameraInfo& info() const override { return camera_->info(); }
  Status SetExposure(double requested_us, double* applied_us) override {
    const Status status = camera_->SetExposure(requested_us, applied_us);
    tracker_->Record(name_, status);
    return status;
  }
  Status Capture(CapturedFrame* frame) override {
    ++writer_->mutable_session()->acquisition.camera_captures;
    ++captures_;
    const Status status = camera_->Capture(frame);
    tracker_->Record(name_, status);
    return status;
  }
  std::map<std::string, double> statistics() const override { return camera_->statistics(); }
  int captures() const { return captures_; }

 private:
  Camera* camera_;
  std::string name_;
  SessionWriter* writer_;
  DeviceFailureTracker* tracker_;
  int captures_ = 0;
};

bool SameCamera(const CameraInfo& a, const CameraInfo& b) {
  return a.id == b.id && a.model == b.model && a.width_px == b.width_px && a.height_px == b.height_px &&
         a.bit_depth == b.bit_depth && (a.serial.empty() || b.serial.empty() || a.serial == b.serial);
}

std::string DescribeCamera(const CameraInfo& c) {
  return "'" + c.id + "' (" + c.model + (c.serial.empty() ? "" : " " + c.serial) + ", " + std::to_string(c.width_px) +
         "x" + std::to_string(c.height_px) + " px, " + std::to_string(c.bit_depth) + "-bit)";
}

}  // namespace

Status TrackedProjector::ShowPattern(const std::string& pattern) {
  const Status status = projector_->ShowPattern(pattern);
  tracker_->Record(name_, status);
  return status;
}

Status TrackedLaser::SetEmission(bool on) {
  const Status status = laser_->SetEmission(on);
  tracker_->Record(name_, status);
  return status;
}

bool AcquisitionRunOptions::Check(std::string* error) const {
  if (session_dir.empty()) {
    *error = "AcquisitionRunOptions::session_dir is empty";
  } else if (planned_frames < 0) {
    *error = "AcquisitionRunOptions::planned_frames = " + std::to_string(planned_frames) + ". Violated constraint: >= 0";
  } else if (!writer.Check(error)) {
    *error = "AcquisitionRunOptions::writer: " + *error;
  } else {
    return true;
  }
  return false;
}

Status RunAcquisition(const AcquisitionRunOptions& options, const Session& header, Camera* camera,
                      const SessionScript& script, AcquisitionResult* result) {
  *result = AcquisitionResult();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (header.rig.cameras.empty() || !SameCamera(header.rig.cameras[0], camera->info())) {
    return Status::Error("RunAcquisition: header.rig.cameras[0] must describe the camera '" + camera->info().id + "'");
  }
  const std::string& dir = options.session_dir;
  const std::string manifest = JoinPath(dir, kSessionManifestName);
  {
    // A header that would make an invalid manifest is refused before anything is written.
    Session check = header;
    check.frames.clear();
    THINSLAB_RETURN_IF_ERROR(ValidateSession(check, dir).WithContext("session header"));
  }
  std::error_code ec;
  SessionFolderLock lock;  // Held until the run ends (declared before the writer: released after it).
  SessionWriter writer;
  SessionWriterOptions writer_options = options.writer;
  writer_options.journal = true;  // The durable record of every frame (docs/acquisition.md).
  if (!options.resume) {
    const auto refuse_non_empty = [&]() {
      return Status::Error(dir + ": output session folder exists and is not empty (add --resume to continue the "
                                 "capture in it)");
    };
    // Checked before the lock, so that a folder that is not ours is not touched ...
    if (fs::exists(dir, ec) && !OnlyTheLockIn(dir)) return refuse_non_empty();
    THINSLAB_RETURN_IF_ERROR(lock.Acquire(dir));
    // ... and again under it: another run may have started between the check and the lock.
    if (!OnlyTheLockIn(dir)) return refuse_non_empty();
    Session start = header;
    start.frames.clear();
    start.acquisition = AcquisitionInfo();
    start.acquisition.present = true;
    start.acquisition.state = "running";
    start.acquisition.plan = options.plan;
    start.acquisition.planned_frames = options.planned_frames;
    AddEvent(&start, "started", "", "camera " + options.camera_name);
    THINSLAB_RETURN_IF_ERROR(writer.Open(dir, start, writer_options));
    THINSLAB_RETURN_IF_ERROR(writer.AppendJournalLine(EventLine(start.acquisition.events.back())));
  } else {
    if (!FileExists(manifest)) return Status::Error(dir + ": nothing to resume (no " + kSessionManifestName + ")");
    THINSLAB_RETURN_IF_ERROR(lock.Acquire(dir));
    RemoveStaleTemporaries(dir);
    THINSLAB_RETURN_IF_ERROR(writer.Open(dir, header, writer_options));
    Session* s = writer.mutable_session();
    if (!s->acquisition.present) {
      return Status::Error(manifest + ": no \"acquisition\" record: the session was not written by `thinslab "
                                      "acquire` and cannot be resumed");
    }
    if (s->acquisition.plan != options.plan) {
      return Status::Error(manifest + ": acquisition.plan: the session was started with \"" + s->acquisition.plan +
                           "\", this command asks for \"" + options.plan +
                           "\"; resume with the same kind and options");
    }
    const CameraInfo* recorded = s->FindCamera(camera->info().id);
    if (recorded == nullptr || !SameCamera(*recorded, camera->info())) {
      return Status::Error(manifest + ": rig.cameras: the session was captured with camera " +
                           (recorded ? DescribeCamera(*recorded) : "(none with id '" + camera->info().id + "')") +
                           ", not " + DescribeCamera(camera->info()));
    }
    result->frames_on_disk_before = writer.steps_on_disk();
    if (s->acquisition.state == "complete") {
      result->already_complete = true;
      result->state = "complete";
      return Status::Ok();
    }
    const std::string previous = s->acquisition.state;
    const std::string how = previous == "running" ? "the previous run stopped without a record (killed or crashed)"
                                                  : "the previous run ended as '" + previous + "'";
    s->acquisition.state = "running";
    AddEvent(s, "resumed", "", how + "; " + std::to_string(writer.steps_on_disk()) + " usable frames on disk; camera " +
                                   options.camera_name);
    THINSLAB_RETURN_IF_ERROR(writer.Save());
    THINSLAB_RETURN_IF_ERROR(writer.AppendJournalLine(EventLine(s->acquisition.events.back())));
  }

  DeviceFailureTracker local_tracker;
  DeviceFailureTracker* tracker = options.tracker ? options.tracker : &local_tracker;
  RecordingCamera recording(camera, "camera '" + camera->info().id + "' (" + options.camera_name + ")", &writer, tracker);

  std::unique_ptr<ProgressReporter> progress;
  if (options.progress != nullptr) {
    progress = std::make_unique<ProgressReporter>(options.label, options.planned_frames, options.progress,
                                                  options.progress_is_terminal);
  }
  writer.set_observer([&]() {
    if (progress) {
      // Called once a claimed step is on disk (written now or skipped on resume).
      progress->Update(writer.steps_claimed(), std::min(writer.steps_claimed(), writer.steps_on_disk()));
    }
  });
  std::string stop_reason;
  writer.set_stop_check([&]() {
    if (options.stop_check) stop_reason = options.stop_check();
    return stop_reason;
  });

  // An exception (memory exhausted, a library's) ends the session as failed, recorded in the
  // manifest, like a device failure: never a session left "running" (issue #22).
  Status status;
  try {
    status = script(&recording, &writer);
  } catch (const std::bad_alloc&) {
    status = Status::Error("out of memory while acquiring (frames of this camera size do not fit in memory)");
  } catch (const std::exception& e) {
    status = Status::Error(std::string("internal error while acquiring: ") + e.what());
  }

  Session* s = writer.mutable_session();
  // Camera transport statistics (dropped buffers, resends, timeouts) at the end of the run.
  for (CameraInfo& cam : s->rig.cameras) {
    if (cam.id != camera->info().id) continue;
    for (const auto& [key, value] : camera->statistics()) cam.stream_statistics[key] = value;
  }
  result->camera_captures = recording.captures();
  int usable = 0;
  for (const FrameRecord& f : s->frames) usable += f.status != FrameStatus::kFailed;
  result->frames_captured = usable - result->frames_on_disk_before;
  if (status.ok()) {
    s->acquisition.state = "complete";
    AddEvent(s, "completed", "", std::to_string(usable) + " usable frames");
  } else if (!stop_reason.empty()) {
    s->acquisition.state = "interrupted";
    AddEvent(s, "interrupted", "", stop_reason);
  } else {
    s->acquisition.state = "failed";
    AddEvent(s, "failed", tracker->device, status.message());
  }
  result->state = s->acquisition.state;
  writer.set_observer(nullptr);
  // The manifest first: it holds every frame and the event; the journal line is its audit copy.
  Status saved = writer.Save();
  const Status journaled = writer.AppendJournalLine(EventLine(s->acquisition.events.back()));
  if (saved.ok()) saved = journaled;
  if (progress) progress->Finish(result->state);
  if (!status.ok()) {
    if (!saved.ok()) return Status::Error(status.message() + " (and the manifest could not be updated: " + saved.message() + ")");
    return status;
  }
  return saved;
}

Status FoldJournalIntoManifest(const std::string& session_dir, JournalFoldResult* result) {
  *result = JournalFoldResult();
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (!FileExists(manifest)) return Status::Error(session_dir + ": not a capture session (no " + kSessionManifestName + ")");
  Session before;
  THINSLAB_RETURN_IF_ERROR(ReadSession(session_dir, &before));
  if (!before.acquisition.present) {  // Refused before the lock file is created in a folder not ours.
    return Status::Error(manifest + ": no \"acquisition\" record: the session was not written by `thinslab acquire` "
                                    "and has no journal to fold");
  }
  SessionFolderLock lock;
  THINSLAB_RETURN_IF_ERROR(lock.Acquire(session_dir));
  THINSLAB_RETURN_IF_ERROR(ReadSession(session_dir, &before));  // Again, under the lock.
  // The same repair a resume makes before it captures: temporaries and frame files of a killed
  // write go, a journal line the kill cut short is dropped, the journaled records are taken.
  RemoveStaleTemporaries(session_dir);
  SessionWriter writer;
  SessionWriterOptions writer_options;
  writer_options.journal = true;
  THINSLAB_RETURN_IF_ERROR(writer.Open(session_dir, before, writer_options));
  result->frames = static_cast<int>(writer.session().frames.size());
  result->folded_frames = result->frames - static_cast<int>(before.frames.size());
  result->state = writer.session().acquisition.state;
  if (result->folded_frames > 0) THINSLAB_RETURN_IF_ERROR(writer.Save());
  return Status::Ok();
}

}  // namespace thinslab
