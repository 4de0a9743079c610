// SPDX-License-Identifier: Apache-2.0
#include "core/session.h"

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

std::vector<const FrameRecord*> Session::UsableFrames(const std::string& frame_kind,
                                                      const std::string& sample_state) const {
  std::vector<const FrameRecord*> out;
  for (const auto& frame : frames) {
    if (frame.kind != frame_kind || frame.status == FrameStatus::kFailed || frame.validation) continue;
    if (!sample_state.empty() && frame.sample_state != sample_state) continue;
    out.push_back(&frame);
  }
  return out;
}

std::vector<const FrameRecord*> Session::ValidationFrames(const std::string& frame_kind,
                                                          const std::string& sample_state) const {
  std::vector<const FrameRecord*> out;
  for (const auto& frame : frames) {
    if (frame.kind != frame_kind || frame.status == FrameStatus::kFailed || !frame.validation) continue;
    if (!sample_state.empty() && frame.sample_state != sample_state) continue;
    out.push_back(&frame);
  }
  return out;
}

}  // namespace thinslab
