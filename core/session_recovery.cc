// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/session_recovery.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <sstream>

#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

std::string JournalFrameText(const FrameRecord& record, const AcquisitionInfo& acquisition, const std::string& json) {
  return "frame " + std::to_string(record.index) + " " + FrameStatusName(record.status) +
         " captures=" + std::to_string(acquisition.camera_captures) +
         " discarded=" + std::to_string(acquisition.discarded_frames) + " " + json;
}

bool ParseJournalFrameLine(const std::string& line, int* captures, int* discarded, std::string* json) {
  int index = 0, consumed = -1;
  char status[16];
  if (std::sscanf(line.c_str(), "%*s frame %d %15s captures=%d discarded=%d %n", &index, status, captures,
                  discarded, &consumed) != 4 ||
      consumed < 0) {
    return false;
  }
  *json = line.substr(static_cast<size_t>(consumed));
  return true;
}

Status ReadSessionWithJournal(const std::string& session_dir, Session* session, int* journaled_frames) {
  if (journaled_frames != nullptr) *journaled_frames = 0;
  Session s;
  THINSLAB_RETURN_IF_ERROR(ReadSession(session_dir, &s));
  const std::string path = JoinPath(session_dir, kSessionJournalName);
  int added = 0;
  if (FileExists(path)) {
    std::string bytes;
    THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &bytes));
    size_t begin = 0;
    for (int line_number = 1;; ++line_number) {
      const size_t end = bytes.find('\n', begin);
      if (end == std::string::npos) break;  // No line, or the last one cut short by a kill.
      const std::string line = bytes.substr(begin, end - begin);
      begin = end + 1;
      int captures = 0, discarded = 0;
      std::string json;
      if (!ParseJournalFrameLine(line, &captures, &discarded, &json)) continue;
      const std::string where = path + ":" + std::to_string(line_number);
      FrameRecord record;
      THINSLAB_RETURN_IF_ERROR(ParseFrameRecordJson(json, where, &record));
      const int next = static_cast<int>(s.frames.size());
      if (record.index < next) continue;  // The manifest has it already.
      if (record.index > next) {
        return Status::Error(where + ": frame record " + std::to_string(record.index) + " follows frame " +
                             std::to_string(next - 1) + ": records are missing");
      }
      s.frames.push_back(std::move(record));
      s.acquisition.camera_captures = std::max(s.acquisition.camera_captures, captures);
      s.acquisition.discarded_frames = std::max(s.acquisition.discarded_frames, discarded);
      ++added;
    }
  }
  if (added > 0) {
    THINSLAB_RETURN_IF_ERROR(ValidateSession(s, session_dir)
                                 .WithContext("with the " + std::to_string(added) + " frames journaled in " + path));
  }
  if (journaled_frames != nullptr) *journaled_frames = added;
  *session = std::move(s);
  return Status::Ok();
}

namespace {

std::string EventText(const AcquisitionEvent& e) {
  std::string text = e.event + " at " + std::to_string(e.frames) + " frames";
  if (!e.device.empty()) text += ": " + e.device;
  if (!e.message.empty()) text += ": " + e.message;
  return text;
}

std::vector<CameraFrameIdAudit> AuditFrameIds(const Session& session) {
  std::map<std::string, CameraFrameIdAudit> by_camera;
  std::map<std::string, uint64_t> previous;
  for (const FrameRecord& f : session.frames) {
    if (!f.camera_frame_id) continue;
    const uint64_t id = *f.camera_frame_id;
    CameraFrameIdAudit& audit = by_camera[f.camera_id];
    audit.camera_id = f.camera_id;
    if (audit.stamped_frames == 0) {
      audit.first_id = id;
    } else if (id <= previous[f.camera_id]) {
      ++audit.restarts;
    } else if (id > previous[f.camera_id] + 1) {
      ++audit.gaps;
      audit.skipped_ids += id - previous[f.camera_id] - 1;
    }
    previous[f.camera_id] = id;
    audit.last_id = id;
    ++audit.stamped_frames;
  }
  std::vector<CameraFrameIdAudit> audits;
  for (auto& [id, audit] : by_camera) audits.push_back(audit);
  // camera_captures counts the capture calls of the whole session; it explains one camera's
  // skips only when the session has one camera.
  if (session.acquisition.present && session.rig.cameras.size() == 1 && audits.size() == 1) {
    CameraFrameIdAudit& audit = audits[0];
    audit.unstamped_captures =
        std::max<int64_t>(0, static_cast<int64_t>(session.acquisition.camera_captures) - audit.stamped_frames);
    const uint64_t explained = static_cast<uint64_t>(audit.unstamped_captures);
    audit.unexplained_skips = audit.skipped_ids > explained ? audit.skipped_ids - explained : 0;
  }
  return audits;
}

}  // namespace

std::string CaptureCompleteness::Describe() const {
  std::ostringstream out;
  if (!acquired) {
    out << "not written by thinslab acquire (complete by construction), " << usable_frames << " usable frames";
    return out.str();
  }
  out << "state " << state << (state == "running" ? " (still capturing, or killed)" : "") << ", " << usable_frames << " of " << planned_frames << " planned frames usable";
  if (journaled_frames > 0) out << " (" << journaled_frames << " recorded only in " << kSessionJournalName << ")";
  if (!last_event.empty()) out << "; last event: " << last_event;
  return out.str();
}

CaptureCompleteness AssessCapture(const Session& session, int journaled_frames) {
  CaptureCompleteness c;
  c.acquired = session.acquisition.present;
  c.state = session.acquisition.state;
  c.frames = static_cast<int>(session.frames.size());
  for (const FrameRecord& f : session.frames) {
    if (f.status != FrameStatus::kFailed) ++c.usable_frames;
  }
  c.planned_frames = session.acquisition.planned_frames;
  c.journaled_frames = journaled_frames;
  if (!session.acquisition.events.empty()) c.last_event = EventText(session.acquisition.events.back());
  c.frame_ids = AuditFrameIds(session);
  return c;
}

std::string SummarizeCompleteness(const CaptureCompleteness& c) {
  std::ostringstream out;
  out << "Capture: " << (c.complete() ? "complete" : "INCOMPLETE") << " (" << c.Describe() << ")\n";
  for (const CameraFrameIdAudit& a : c.frame_ids) {
    out << "Camera frame ids (" << a.camera_id << "): " << a.stamped_frames << " stamped, " << a.first_id << " .. "
        << a.last_id << ", " << a.gaps << " gap(s) skipping " << a.skipped_ids << " id(s), " << a.restarts
        << " restart(s)";
    if (a.unstamped_captures >= 0) {
      out << "; " << a.unstamped_captures << " capture(s) left no stamped frame (discarded or failed)";
    }
    out << "\n";
    if (a.unexplained_skips > 0) {
      out << "  WARNING: " << a.unexplained_skips
          << " frame(s) the camera numbered were delivered to no capture (dropped between captures: "
             "check the stream statistics in rig.cameras[].stream_statistics)\n";
    }
  }
  return out.str();
}

Status ReadCapture(const std::string& session_dir, IncompleteCapture policy, Session* session,
                   CaptureCompleteness* completeness) {
  Session s;
  int journaled = 0;
  THINSLAB_RETURN_IF_ERROR(ReadSessionWithJournal(session_dir, &s, &journaled));
  const CaptureCompleteness c = AssessCapture(s, journaled);
  if (completeness != nullptr) *completeness = c;
  if (!c.complete() && policy == IncompleteCapture::kRefuse) {
    return Status::Error(JoinPath(session_dir, "session.json") + ": acquisition: the capture did not complete (" +
                         c.Describe() +
                         "). Finish it with `thinslab acquire ... --resume`, or pass --allow-incomplete to "
                         "process the frames it has");
  }
  *session = std::move(s);
  return Status::Ok();
}

}  // namespace thinslab
