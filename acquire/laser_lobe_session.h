// SPDX-License-Identifier: Apache-2.0
// Laser-lobe capture (Gu et al. 2007, Sec. 5.2, Fig. 9b): a collimated laser beam crosses a
// uniform contaminant layer at normal incidence and the camera records the scattering lobe on
// the board behind it. The lobe spans ~6 decades, so every state is an exposure bracket:
//   flat  (board under a uniform flat field, no laser; for the camera's vignetting),
//   dark  (laser off), laser on with the contaminated sample, laser on with clean glass.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "acquire/session_writer.h"
#include "acquire/shadow_map_session.h"
#include "drivers/camera.h"
#include "drivers/display.h"
#include "drivers/laser.h"

namespace thinslab {

struct LaserLobeSessionOptions {
  // Requested exposures of the bracket; the applied (read-back) ones are recorded.
  std::vector<double> exposure_times_us = {20, 200, 2000, 20000, 200000, 2000000};
  int frames_per_exposure = 1;
  bool capture_clean = true;  // Clean-glass bracket for background subtraction and checks.
  bool capture_flat = true;   // Flat-field bracket of the board (projector "flat").
  int max_retries = 2;

  bool Check(std::string* error) const;
};

Status RunLaserLobeSession(const LaserLobeSessionOptions& options, Camera* camera, Laser* laser,
                           Projector* flat_source, const SampleChanger& change_sample, SessionWriter* writer);

}  // namespace thinslab
