// SPDX-License-Identifier: Apache-2.0
// Shadow-map capture (Gu et al. 2007, Sec. 5.1, Fig. 9a): the projector floods the pane with
// a flat field, the camera records the Lambertian board behind it. Three states are taken:
// dark (projector off), reference (clean glass) and shadow (contaminated glass), several
// frames each so the fit can average them. A failed capture is recorded and retried.
#pragma once

#include <functional>
#include <string>

#include "acquire/session_writer.h"
#include "drivers/camera.h"
#include "drivers/display.h"

namespace thinslab {

struct ShadowMapSessionOptions {
  // Frames per state; the fit averages them (noise falls as 1/sqrt(n)).
  int frames_per_state = 4;
  int dark_frames = 2;
  // Requested exposure; the applied (read-back) one is recorded.
  double exposure_time_us = 20000;
  // Further attempts after a failed capture before the session gives up.
  int max_retries = 2;

  bool Check(std::string* error) const;
};

// Moves the sample between "clean" and "contaminated" (an operator prompt at the rig, a
// state switch in the simulator).
using SampleChanger = std::function<Status(const std::string& sample_state)>;

Status RunShadowMapSession(const ShadowMapSessionOptions& options, Camera* camera,
                           Projector* projector, const SampleChanger& change_sample,
                           SessionWriter* writer);

}  // namespace thinslab
