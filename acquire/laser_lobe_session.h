// SPDX-License-Identifier: Apache-2.0
// Laser-lobe capture (Gu et al. 2007, Sec. 5.2, Fig. 9b): a collimated laser beam crosses a
// uniform contaminant layer at normal incidence and the camera records the scattering lobe on
// the board behind it. The lobe spans ~6 decades, so every state is an exposure bracket:
//   flat  (board under a uniform flat field, no laser; for the camera's vignetting),
//   dark  (laser off), laser on with the contaminated sample, laser on with clean glass.
// Every frame goes through the display-camera synchronisation of acquire/display_sync.h (a frame
// counts once the change of flat field, laser or sample is seen). The flat bracket, lit by the
// display, is rounded to whole refresh periods when the flat-field source has one (duplicates
// dropped); the laser-lit and dark brackets are not.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "thinslab/acquire/display_sync.h"
#include "thinslab/acquire/sample_changer.h"
#include "thinslab/acquire/session_writer.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"
#include "thinslab/drivers/laser.h"

namespace thinslab {

struct LaserLobeSessionOptions {
  // Requested exposures of the bracket; the applied (read-back) ones are recorded.
  std::vector<double> exposure_times_us = {20, 200, 2000, 20000, 200000, 2000000};
  // The flat-field bracket's, when its light is planned apart (`--exposures-us auto`); empty:
  // the laser bracket's.
  std::vector<double> flat_exposure_times_us;
  int frames_per_exposure = 1;
  bool capture_clean = true;  // Clean-glass bracket for background subtraction and checks.
  bool capture_flat = true;   // Flat-field bracket of the board (projector "flat").
  // A second contaminated bracket marked FrameRecord::validation: never fitted; `fit phase`
  // reports how well the fitted lobe predicts it (issue #23 section 4).
  bool capture_validation = false;
  // Synchronisation rule and retries (sync.max_retries further attempts after a failed capture).
  DisplaySyncOptions sync;
  // Largest accepted mismatch of an applied flat exposure to whole refresh periods (fraction of one).
  double max_refresh_mismatch = 0.02;

  bool Check(std::string* error) const;
};

// The frames in order: flat, dark, laser (contaminated), validation laser (contaminated), laser (clean); `refresh_period_s` of
// the flat-field source (0: none) rounds the flat bracket.
std::vector<PlannedFrame> PlanLaserLobeSession(const LaserLobeSessionOptions& options, double refresh_period_s);

Status RunLaserLobeSession(const LaserLobeSessionOptions& options, Camera* camera, Laser* laser,
                           Projector* flat_source, const SampleChanger& change_sample, SessionWriter* writer);

}  // namespace thinslab
