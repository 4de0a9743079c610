// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/session.h"

namespace thinslab {

const char* FrameStatusName(FrameStatus status) {
  switch (status) {
    case FrameStatus::kOk: return "ok";
    case FrameStatus::kFailed: return "failed";
    case FrameStatus::kRetried: return "retried";
  }
  return "unknown";
}

const CameraInfo* Session::FindCamera(const std::string& id) const {
  for (const auto& camera : rig.cameras) {
    if (camera.id == id) return &camera;
  }
  return nullptr;
}

namespace {

// Usable frames (status ok or retried) of `kind` (and sample state, if non-empty) whose
// validation flag is `validation`.
std::vector<const FrameRecord*> UsableFramesOf(const std::vector<FrameRecord>& frames, const std::string& kind,
                                               const std::string& sample_state, bool validation) {
  std::vector<const FrameRecord*> out;
  for (const auto& frame : frames) {
    if (frame.kind != kind || frame.status == FrameStatus::kFailed || frame.validation != validation) continue;
    if (!sample_state.empty() && frame.sample_state != sample_state) continue;
    out.push_back(&frame);
  }
  return out;
}

}  // namespace

std::vector<const FrameRecord*> Session::UsableFrames(const std::string& frame_kind,
                                                      const std::string& sample_state) const {
  return UsableFramesOf(frames, frame_kind, sample_state, false);
}

std::vector<const FrameRecord*> Session::ValidationFrames(const std::string& frame_kind,
                                                          const std::string& sample_state) const {
  return UsableFramesOf(frames, frame_kind, sample_state, true);
}

}  // namespace thinslab
