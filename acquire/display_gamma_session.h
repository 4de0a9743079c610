// SPDX-License-Identifier: Apache-2.0
// Display gamma session (kind "display_gamma", docs/format.md; issue #7): the camera looks at
// the display (or at a diffuse screen it lights) while the display shows uniform levels
// "flat:0", "flat:1/steps", ..., "flat:1" (GammaMeasurementPatterns) driven through the
// identity table, each recorded as an exposure bracket; `thinslab calib gamma` merges each
// bracket (calib/hdr_merge.h) and fits the display's gamma table (calib/display_gamma_fit.h).
// Frame kinds:
//   "dark"   pattern "" (display black), dark_frames per exposure, first
//   "level"  pattern "flat:<level>", each exposure of the bracket; the levels of each repeat in
//            a seeded random order (a new permutation per repeat), so slow drift of display or
//            camera (warm-up, room light) does not alias onto the drive level as a trend.
// Why a bracket: a gamma 2.2 display at level 1/16 emits ~0.2 % of its full light; an exposure
// that keeps level 1 below saturation leaves that level a few DN above black, where the 8-12
// bit quantisation step is a large part of the signal. Exposures a factor 4 apart measure every
// level at a useful fraction of full scale (docs/drivers.md, "Gamma").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/acquire/display_sync.h"
#include "thinslab/acquire/exposure_bracket.h"
#include "thinslab/acquire/sample_changer.h"
#include "thinslab/acquire/session_writer.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"

namespace thinslab {

struct DisplayGammaSessionOptions {
  int steps = 16;        // Drive levels 0, 1/steps, ..., 1 (steps + 1 levels); in [2, 255].
  int repeats = 2;       // Measurements of every level, each repeat in its own random order; >= 1.
  uint64_t order_seed = 1;  // Seed of the level order (recorded in the plan).
  int dark_frames = 2;   // Dark (display black) frames per exposure; >= 0.
  // Exposures of every level; refresh_period_s 0 takes the display's.
  ExposureBracketOptions bracket;
  DisplaySyncOptions sync;

  bool Check(std::string* error) const;
};

// The drive levels in measurement order: `repeats` seeded permutations of the steps + 1 levels.
std::vector<double> DisplayGammaLevelOrder(const DisplayGammaSessionOptions& options);
std::vector<PlannedFrame> PlanDisplayGammaSession(const DisplayGammaSessionOptions& options, double refresh_period_s);
// Runs the plan through RunSynchronizedPlan (sample state "none": nothing between camera and display).
Status RunDisplayGammaSession(const DisplayGammaSessionOptions& options, Camera* camera, Projector* display,
                              const SampleChanger& change_sample, SessionWriter* writer);

}  // namespace thinslab
