// SPDX-License-Identifier: Apache-2.0
// Shadow-map capture (Gu et al. 2007, Sec. 5.1, Fig. 9a): the projector floods the pane with
// a flat field, the camera records the Lambertian board behind it. Three states are taken:
// dark (projector off), reference (clean glass) and shadow (contaminated glass), several
// frames each so the fit can average them. Every frame goes through the display-camera
// synchronisation of acquire/display_sync.h (a frame counts once the change of projector or
// sample is seen); with a scanned projector (refresh_period_s() > 0) the exposure is a whole
// number of refresh periods. A failed capture is recorded and retried.
#pragma once

#include <string>
#include <vector>

#include "thinslab/acquire/display_sync.h"
#include "thinslab/acquire/sample_changer.h"
#include "thinslab/acquire/session_writer.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"

namespace thinslab {

struct ShadowMapSessionOptions {
  // Frames per state; the fit averages them (noise falls as 1/sqrt(n)).
  int frames_per_state = 4;
  int dark_frames = 2;
  // Further shadow frames, marked FrameRecord::validation: never fitted; `fit tau` reports how
  // well the map predicts them (issue #23 section 4).
  int validation_frames = 0;
  // Requested exposure; the applied (read-back) one is recorded.
  double exposure_time_us = 20000;
  // Synchronisation rule and retries (sync.max_retries further attempts after a failed capture).
  DisplaySyncOptions sync;
  // Largest accepted mismatch of the applied exposure to whole refresh periods (fraction of one).
  double max_refresh_mismatch = 0.02;

  bool Check(std::string* error) const;
};

// The frames in order: dark, reference, shadow, validation shadow.
std::vector<PlannedFrame> PlanShadowMapSession(const ShadowMapSessionOptions& options);

Status RunShadowMapSession(const ShadowMapSessionOptions& options, Camera* camera,
                           Projector* projector, const SampleChanger& change_sample,
                           SessionWriter* writer);

}  // namespace thinslab
