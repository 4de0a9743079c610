// SPDX-License-Identifier: Apache-2.0
#include "acquire/shadow_map_session.h"

#include <sstream>

#include "acquire/capture_with_retries.h"

namespace thinslab {

bool ShadowMapSessionOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (frames_per_state < 1) {
    msg << "ShadowMapSessionOptions::frames_per_state = " << frames_per_state << ". Violated constraint: >= 1";
  } else if (dark_frames < 0) {
    msg << "ShadowMapSessionOptions::dark_frames = " << dark_frames << ". Violated constraint: >= 0";
  } else if (!(exposure_time_us > 0)) {
    msg << "ShadowMapSessionOptions::exposure_time_us = " << exposure_time_us << ". Violated constraint: > 0";
  } else if (max_retries < 0) {
    msg << "ShadowMapSessionOptions::max_retries = " << max_retries << ". Violated constraint: >= 0";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

Status RunShadowMapSession(const ShadowMapSessionOptions& options, Camera* camera,
                           Projector* projector, const SampleChanger& change_sample,
                           SessionWriter* writer) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  double applied_us = 0;
  THINSLAB_RETURN_IF_ERROR(camera->SetExposure(options.exposure_time_us, &applied_us));

  struct Step {
    const char* kind;
    const char* sample_state;
    const char* pattern;
    int count;
  };
  const Step steps[] = {
      {"dark", "clean", "", options.dark_frames},
      {"reference", "clean", "flat", options.frames_per_state},
      {"shadow", "contaminated", "flat", options.frames_per_state},
  };
  for (const Step& step : steps) {
    THINSLAB_RETURN_IF_ERROR(change_sample(step.sample_state));
    THINSLAB_RETURN_IF_ERROR(projector->ShowPattern(step.pattern));
    for (int i = 0; i < step.count; ++i) {
      FrameRecord templ;
      templ.camera_id = camera->info().id;
      templ.kind = step.kind;
      templ.sample_state = step.sample_state;
      templ.exposure_time_us = applied_us;
      templ.light.projector_pattern = step.pattern;
      THINSLAB_RETURN_IF_ERROR(CaptureWithRetries(camera, templ, options.max_retries, writer));
    }
  }
  return projector->ShowPattern("");
}

}  // namespace thinslab
