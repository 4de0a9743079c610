// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/laser_lobe_session.h"

#include <sstream>


namespace thinslab {

bool LaserLobeSessionOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (exposure_times_us.empty()) {
    msg << "LaserLobeSessionOptions::exposure_times_us is empty. Violated constraint: at least one exposure";
  } else if (frames_per_exposure < 1) {
    msg << "LaserLobeSessionOptions::frames_per_exposure = " << frames_per_exposure << ". Violated constraint: >= 1";
  } else if (!(max_refresh_mismatch >= 0)) {
    msg << "LaserLobeSessionOptions::max_refresh_mismatch = " << max_refresh_mismatch << ". Violated constraint: >= 0";
  } else if (!sync.Check(error)) {
    msg << "LaserLobeSessionOptions::sync: " << *error;
  } else {
    for (double t : flat_exposure_times_us) {
      if (!(t > 0)) {
        msg << "LaserLobeSessionOptions::flat_exposure_times_us contains " << t << ". Violated constraint: > 0";
        *error = msg.str();
        return false;
      }
    }
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

std::vector<PlannedFrame> PlanLaserLobeSession(const LaserLobeSessionOptions& options, double refresh_period_s) {
  struct Step {
    const char* kind;
    const char* sample_state;
    bool laser_on;
    const char* pattern;
    bool validation;
  };
  std::vector<Step> steps;
  if (options.capture_flat) steps.push_back({"flat", "none", false, "flat", false});
  steps.push_back({"dark", "none", false, "", false});
  steps.push_back({"laser", "contaminated", true, "", false});
  // Before the clean bracket: no extra sample change.
  if (options.capture_validation) steps.push_back({"laser", "contaminated", true, "", true});
  if (options.capture_clean) steps.push_back({"laser", "clean", true, "", false});
  ExposureBracketOptions flat_bracket;
  flat_bracket.exposures_us =
      options.flat_exposure_times_us.empty() ? options.exposure_times_us : options.flat_exposure_times_us;
  flat_bracket.refresh_period_s = refresh_period_s;
  const std::vector<double> flat_exposures = PlanExposureBracket(flat_bracket);
  std::vector<PlannedFrame> plan;
  for (const Step& step : steps) {
    const bool lit_by_display = *step.pattern != '\0';
    for (double requested_us : lit_by_display ? flat_exposures : options.exposure_times_us) {
      for (int i = 0; i < options.frames_per_exposure; ++i) {
        PlannedFrame p;
        p.kind = step.kind;
        p.sample_state = step.sample_state;
        p.pattern = step.pattern;
        p.requested_exposure_us = requested_us;
        p.laser_on = step.laser_on;
        p.validation = step.validation;
        p.refresh_locked = lit_by_display;
        plan.push_back(p);
      }
    }
  }
  return plan;
}

Status RunLaserLobeSession(const LaserLobeSessionOptions& options, Camera* camera, Laser* laser,
                           Projector* flat_source, const SampleChanger& change_sample, SessionWriter* writer) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  ExposureBracketOptions exposure;
  exposure.exposures_us = options.exposure_times_us;
  exposure.refresh_period_s = flat_source->refresh_period_s();
  exposure.max_refresh_mismatch = options.max_refresh_mismatch;
  return RunSynchronizedPlan(PlanLaserLobeSession(options, flat_source->refresh_period_s()), exposure, options.sync,
                             camera, flat_source, change_sample, writer, laser);
}

}  // namespace thinslab
