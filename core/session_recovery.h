// SPDX-License-Identifier: Apache-2.0
// Reading a capture the way `thinslab acquire` left it (running, killed, failed or finished):
// session.json plus the frame records journal.log holds beyond its last rewrite (docs/format.md
// 10.2), and what is known about its completeness: state, usable against planned frames, and
// whether the camera's own frame counter shows frames lost between captures. The fits and the
// calibration commands read captures through ReadCapture, so a capture that did not finish is
// never processed silently as if it had.
#pragma once

#include <cstdint>
#include <string>

#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

constexpr char kSessionJournalName[] = "journal.log";

// A frame line of journal.log (docs/format.md 10.2) without its leading time stamp:
// "frame <index> <status> captures=<n> discarded=<m> <json>", <json> the frames[k] object of
// section 2.4; the counters are the session's camera_captures and discarded_frames once the
// frame was recorded.
std::string JournalFrameText(const FrameRecord& record, const AcquisitionInfo& acquisition, const std::string& json);
// Parses a whole journal line; false if it is not a frame record (an event line, or a line of
// the audit-only journal that older versions wrote).
bool ParseJournalFrameLine(const std::string& line, int* captures, int* discarded, std::string* json);

// The session as the writer would resume it: session.json plus the frame records journal.log
// holds beyond it (and the capture counters of the last of them). Journal lines that are not
// frame records, records the manifest already has, and a last line cut short by a kill are
// skipped; a malformed record line or a gap in the indices is an error naming
// journal.log:<line>. The result is validated like ReadSession's. *journaled_frames, if given,
// receives how many frames came from the journal.
Status ReadSessionWithJournal(const std::string& session_dir, Session* session, int* journaled_frames = nullptr);

// The camera frame counters (FrameRecord::camera_frame_id) of one camera, in frame order. A
// counter that goes down is a restart (the camera was reopened, e.g. by a resume). Within a
// run of rising counters every id skipped is a frame the camera numbered that no record holds:
// a capture whose frame was discarded or failed, or a frame lost between captures. Only the
// excess over the captures that explain skips is unexplained.
struct CameraFrameIdAudit {
  std::string camera_id;
  int stamped_frames = 0;      // Records with a camera_frame_id.
  uint64_t first_id = 0, last_id = 0;
  int gaps = 0;                // Places where the counter jumped by more than 1.
  uint64_t skipped_ids = 0;    // Sum of the jumps' missing ids.
  int restarts = 0;            // Places where it went down (or repeated).
  // Capture calls that left no stamped record: acquisition.camera_captures minus the stamped
  // records (one camera); -1 when unknown (several cameras, or no acquisition record).
  int64_t unstamped_captures = -1;
  // skipped_ids beyond unstamped_captures (0 if explained, or if that count is unknown).
  uint64_t unexplained_skips = 0;
};

// What a reader knows about how complete a capture is.
struct CaptureCompleteness {
  bool acquired = false;     // Written by `thinslab acquire` (session.json has "acquisition").
  std::string state;         // acquisition.state; "" when not acquired.
  int frames = 0;            // Frame records, with those from the journal.
  int usable_frames = 0;     // Status ok or retried.
  int planned_frames = 0;    // acquisition.planned_frames.
  int journaled_frames = 0;  // Records only journal.log had (session.json lagged behind).
  std::string last_event;    // "<event> at <n> frames[: <device>][: <message>]", or "".
  std::vector<CameraFrameIdAudit> frame_ids;  // One per camera with stamped frames.

  // Not acquired (simulated, hand-written: complete by construction), or state "complete".
  bool complete() const { return !acquired || state == "complete"; }
  // One line for people: "state running, 812 of 3200 planned frames usable (40 only in
  // journal.log); last event: started at 0 frames".
  std::string Describe() const;
};

CaptureCompleteness AssessCapture(const Session& session, int journaled_frames);
// Lines for `thinslab info`: completeness and the frame-id audit, each line ended by '\n'.
std::string SummarizeCompleteness(const CaptureCompleteness& completeness);

enum class IncompleteCapture { kRefuse, kAccept };

// ReadSessionWithJournal, then, unless `policy` is kAccept, an error for a capture whose
// acquisition did not complete (state running, failed or interrupted), naming session.json,
// the state, usable and planned frames, the last event, and the ways on (resume the
// acquisition, or accept the frames it has). *completeness, if given, is filled either way.
Status ReadCapture(const std::string& session_dir, IncompleteCapture policy, Session* session,
                   CaptureCompleteness* completeness = nullptr);

}  // namespace thinslab
