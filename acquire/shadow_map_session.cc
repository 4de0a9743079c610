// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/shadow_map_session.h"

#include <sstream>


namespace thinslab {

bool ShadowMapSessionOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (frames_per_state < 1) {
    msg << "ShadowMapSessionOptions::frames_per_state = " << frames_per_state << ". Violated constraint: >= 1";
  } else if (dark_frames < 0) {
    msg << "ShadowMapSessionOptions::dark_frames = " << dark_frames << ". Violated constraint: >= 0";
  } else if (validation_frames < 0 || validation_frames > 10000) {
    msg << "ShadowMapSessionOptions::validation_frames = " << validation_frames
        << ". Violated constraint: in [0, 10000]";
  } else if (!(exposure_time_us > 0)) {
    msg << "ShadowMapSessionOptions::exposure_time_us = " << exposure_time_us << ". Violated constraint: > 0";
  } else if (!(max_refresh_mismatch >= 0)) {
    msg << "ShadowMapSessionOptions::max_refresh_mismatch = " << max_refresh_mismatch << ". Violated constraint: >= 0";
  } else if (!sync.Check(error)) {
    msg << "ShadowMapSessionOptions::sync: " << *error;
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

std::vector<PlannedFrame> PlanShadowMapSession(const ShadowMapSessionOptions& options) {
  struct Step {
    const char* kind;
    const char* sample_state;
    const char* pattern;
    int count;
    bool validation;
  };
  const Step steps[] = {
      {"dark", "clean", "", options.dark_frames, false},
      {"reference", "clean", "flat", options.frames_per_state, false},
      {"shadow", "contaminated", "flat", options.frames_per_state, false},
      {"shadow", "contaminated", "flat", options.validation_frames, true},
  };
  std::vector<PlannedFrame> plan;
  for (const Step& step : steps) {
    for (int i = 0; i < step.count; ++i) {
      PlannedFrame p;
      p.kind = step.kind;
      p.sample_state = step.sample_state;
      p.pattern = step.pattern;
      p.validation = step.validation;
      p.requested_exposure_us = options.exposure_time_us;  // Dark too: it is subtracted from the others.
      plan.push_back(p);
    }
  }
  return plan;
}

Status RunShadowMapSession(const ShadowMapSessionOptions& options, Camera* camera,
                           Projector* projector, const SampleChanger& change_sample,
                           SessionWriter* writer) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  ExposureBracketOptions exposure;
  exposure.exposures_us = {options.exposure_time_us};
  exposure.refresh_period_s = projector->refresh_period_s();
  exposure.max_refresh_mismatch = options.max_refresh_mismatch;
  return RunSynchronizedPlan(PlanShadowMapSession(options), exposure, options.sync, camera, projector, change_sample,
                             writer);
}

}  // namespace thinslab
