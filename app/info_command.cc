// SPDX-License-Identifier: Apache-2.0
#include <algorithm>
#include <iomanip>
#include <iostream>
#include <map>
#include <set>
#include <tuple>

#include "thinslab/acquire/session_lock.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/session_recovery.h"

namespace thinslab {

namespace {

// Issue #23: an integer capture with one exposure per light state clips wherever a pixel
// saturates; a bracket (or linear frames) would have kept those pixels. Counts per frame kind.
class SingleExposureClipping {
 public:
  void Add(const Session& session, const FrameRecord& frame, const Image& image) {
    const CameraInfo* camera = session.FindCamera(frame.camera_id);
    if (camera == nullptr || camera->linear_frames() || frame.kind == "dark") return;
    const double saturation = camera->saturation_dn - camera->black_level_dn - 0.5;
    const int64_t saturated = std::count_if(image.data().begin(), image.data().end(),
                                            [&](float v) { return v >= saturation; });
    const Eigen::Vector2d dot = frame.light.dot_px.value_or(Eigen::Vector2d(-1, -1));
    const State state(frame.camera_id, frame.kind, frame.sample_state, frame.light.projector_pattern,
                      frame.light.laser_on, dot.x(), dot.y());
    exposures_[state].insert(frame.exposure_time_us);
    double& worst = worst_saturated_fraction_[state];
    worst = std::max(worst, static_cast<double>(saturated) / std::max<size_t>(1, image.num_pixels()));
  }

  void Warn(std::ostream& out) const {
    std::map<std::string, std::pair<int, double>> by_kind;  // kind -> (states, worst fraction).
    for (const auto& [state, exposures] : exposures_) {
      const double fraction = worst_saturated_fraction_.at(state);
      if (exposures.size() != 1 || fraction <= 0) continue;
      auto& entry = by_kind[std::get<0>(state) + " '" + std::get<1>(state) + "'"];
      ++entry.first;
      entry.second = std::max(entry.second, fraction);
    }
    for (const auto& [kind, entry] : by_kind) {
      out << "warning: " << kind << ": " << entry.first << " light state(s) have a single exposure and saturated "
          << "pixels (up to " << std::setprecision(3) << 100 * entry.second << std::setprecision(6) << " % of a frame); those pixels are lost: capture a bracket "
          << "(>= 2 exposures) or frames already linear (frame_values \"linear\")\n";
    }
  }

 private:
  using State = std::tuple<std::string, std::string, std::string, std::string, bool, double, double>;
  std::map<State, std::set<double>> exposures_;
  std::map<State, double> worst_saturated_fraction_;
};

}  // namespace

int RunInfo(int argc, char** argv) {
  std::string session_dir;
  OptionParser parser("info");
  parser.AddPositional("CAPTURE", &session_dir, "capture session folder (holding session.json)");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  // Through the journal: a running or killed capture shows every frame it recorded.
  Session session;
  int journaled = 0;
  if (status.ok()) status = ReadSessionWithJournal(session_dir, &session, &journaled);
  if (!status.ok()) return CommandFailed(status);
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
  SingleExposureClipping clipping;
  for (const FrameRecord& frame : session.frames) {
    if (frame.status == FrameStatus::kFailed) continue;
    Image image;
    const Status frame_status = LoadFrame(session_dir, session, frame, &image);
    if (!frame_status.ok()) {
      std::cout << "valid: no\n";
      std::cerr << "error: " << frame_status.message() << "\n";
      return 1;
    }
    clipping.Add(session, frame, image);
    ++decoded;
  }
  clipping.Warn(std::cout);
  std::cout << "frames decoded: " << decoded << "\n";
  const auto validation = std::count_if(session.frames.begin(), session.frames.end(), [](const FrameRecord& f) {
    return f.validation && f.status != FrameStatus::kFailed;
  });
  if (validation > 0) std::cout << "validation frames (not fitted): " << validation << "\n";
  std::cout << "valid: yes\n";
  return 0;
}

}  // namespace thinslab
