// SPDX-License-Identifier: Apache-2.0
#include "acquire/laser_lobe_session.h"

#include <sstream>

#include "acquire/capture_with_retries.h"

namespace thinslab {

bool LaserLobeSessionOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (exposure_times_us.empty()) {
    msg << "LaserLobeSessionOptions::exposure_times_us is empty. Violated constraint: at least one exposure";
  } else if (frames_per_exposure < 1) {
    msg << "LaserLobeSessionOptions::frames_per_exposure = " << frames_per_exposure << ". Violated constraint: >= 1";
  } else if (max_retries < 0) {
    msg << "LaserLobeSessionOptions::max_retries = " << max_retries << ". Violated constraint: >= 0";
  } else {
    for (double t : exposure_times_us) {
      if (!(t > 0)) {
        msg << "LaserLobeSessionOptions::exposure_times_us contains " << t << ". Violated constraint: > 0";
        *error = msg.str();
        return false;
      }
    }
    return true;
  }
  *error = msg.str();
  return false;
}

Status RunLaserLobeSession(const LaserLobeSessionOptions& options, Camera* camera, Laser* laser,
                           Projector* flat_source, const SampleChanger& change_sample, SessionWriter* writer) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  struct Step {
    const char* kind;
    const char* sample_state;
    bool laser_on;
    const char* pattern;
  };
  std::vector<Step> steps;
  if (options.capture_flat) steps.push_back({"flat", "none", false, "flat"});
  steps.push_back({"dark", "none", false, ""});
  steps.push_back({"laser", "contaminated", true, ""});
  if (options.capture_clean) steps.push_back({"laser", "clean", true, ""});
  for (const Step& step : steps) {
    THINSLAB_RETURN_IF_ERROR(change_sample(step.sample_state));
    THINSLAB_RETURN_IF_ERROR(flat_source->ShowPattern(step.pattern));
    THINSLAB_RETURN_IF_ERROR(laser->SetEmission(step.laser_on));
    for (double requested_us : options.exposure_times_us) {
      double applied_us = 0;
      THINSLAB_RETURN_IF_ERROR(camera->SetExposure(requested_us, &applied_us));
      for (int i = 0; i < options.frames_per_exposure; ++i) {
        FrameRecord templ;
        templ.camera_id = camera->info().id;
        templ.kind = step.kind;
        templ.sample_state = step.sample_state;
        templ.exposure_time_us = applied_us;
        templ.light.projector_pattern = step.pattern;
        templ.light.laser_on = step.laser_on;
        THINSLAB_RETURN_IF_ERROR(CaptureWithRetries(camera, templ, options.max_retries, writer));
      }
    }
  }
  THINSLAB_RETURN_IF_ERROR(laser->SetEmission(false));
  return flat_source->ShowPattern("");
}

}  // namespace thinslab
