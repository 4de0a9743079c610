// SPDX-License-Identifier: Apache-2.0
#include <iostream>

#include "acquire/session_lock.h"
#include "app/commands.h"
#include "app/option_parser.h"
#include "core/session_io.h"
#include "core/session_recovery.h"

namespace thinslab {

int RunInfo(int argc, char** argv) {
  std::string session_dir;
  OptionParser parser("info");
  parser.AddPositional("CAPTURE", &session_dir, "capture session folder (holding session.json)");
  Status status = parser.Parse(argc, argv);
  if (parser.help_requested()) {
    std::cout << parser.Usage();
    return 0;
  }
  // Through the journal: a running or killed capture shows every frame it recorded.
  Session session;
  int journaled = 0;
  if (status.ok()) status = ReadSessionWithJournal(session_dir, &session, &journaled);
  if (!status.ok()) {
    std::cerr << "error: " << status.message() << "\n";
    return 1;
  }
  std::cout << SummarizeSession(session) << SummarizeCompleteness(AssessCapture(session, journaled));
  if (session.acquisition.present && session.acquisition.state == "running") {
    // "running" is either a capture in progress or one that was killed: the folder lock tells.
    std::string pid;
    if (ProbeSessionLock(session_dir, &pid) == SessionLockState::kHeld) {
      std::cout << "Writer: thinslab acquire" << (pid.empty() ? "" : " (process " + pid + ")")
                << " is capturing into this folder now\n";
    } else {
      std::cout << "Writer: none (no process holds " << kSessionLockName
                << "): the capture was killed or crashed; `thinslab acquire <same options> --resume` continues it, "
                   "`thinslab acquire fold-journal` writes its journaled frames into session.json\n";
    }
  }
  // The manifest can be valid while its frames are not (truncated, empty, of another size than
  // the camera's): every usable frame is decoded, so that "valid: yes" means the fits can read
  // the capture.
  int decoded = 0;
  for (const FrameRecord& frame : session.frames) {
    if (frame.status == FrameStatus::kFailed) continue;
    Image image;
    const Status frame_status = LoadFrame(session_dir, session, frame, &image);
    if (!frame_status.ok()) {
      std::cout << "valid: no\n";
      std::cerr << "error: " << frame_status.message() << "\n";
      return 1;
    }
    ++decoded;
  }
  std::cout << "frames decoded: " << decoded << "\n";
  std::cout << "valid: yes\n";
  return 0;
}

}  // namespace thinslab
