// SPDX-License-Identifier: Apache-2.0
// CRT/monitor dot scan (Dai et al. 2009, Sec. 4.1): the monitor behind the sample lights one
// dot at a time on a grid (40 x 40 in the paper); the camera records, per dot, an exposure
// bracket of the light the sample transmits. Before the scan, one frame of all grid dots
// without the sample in place locates the dots in the camera (geometric calibration), and a
// dark bracket with the sample in place gives the background. Frame kinds:
//   "all_dots"  sample_state "none", pattern "dots:<x0>,<y0>,<dx>,<dy>,<nx>,<ny>", each exposure
//   "dark"      sample_state = options.sample_state, pattern "" (monitor black), each exposure
//   "dot"       sample_state = options.sample_state, pattern "dot:<x>,<y>", light.dot_px = (x, y),
//               each exposure; dots in row-major order (x fastest)
// Every frame goes through the display-camera synchronisation of acquire/display_sync.h.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "thinslab/acquire/display_sync.h"
#include "thinslab/acquire/exposure_bracket.h"
#include "thinslab/acquire/session_writer.h"
#include "thinslab/acquire/shadow_map_session.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"

namespace thinslab {

struct DotScanSessionOptions {
  int grid_nx = 40;
  int grid_ny = 40;
  // Monitor size [px]; the grid spans it with `margin_fraction` left free on each side, unless
  // step_x_px/step_y_px are given (> 0), in which case the grid starts at (first_x_px, first_y_px).
  int monitor_width_px = 0;
  int monitor_height_px = 0;
  double margin_fraction = 0.1;
  double first_x_px = 0, first_y_px = 0;
  double step_x_px = 0, step_y_px = 0;
  // Exposures of every dot; refresh_period_s 0 takes the monitor's (Projector::refresh_period_s).
  ExposureBracketOptions bracket;
  bool capture_all_dots = true;
  bool capture_dark = true;
  std::string sample_state = "contaminated";  // State of the sample during the dot frames.
  // Validation dots (monitor px, any position): captured after the grid like its dots, marked
  // FrameRecord::validation (not fitted; `fit dmf` reports how well it predicts them).
  std::vector<Eigen::Vector2d> validation_dots_px;
  // Frames of every dot (and of the dark bracket) at the longest exposure, averaged by the HDR
  // merge. On a display whose black glows, the glow's shot noise in the longest exposure hides
  // the lobes' tails, and a longer exposure would saturate the glow: only more frames lower it
  // (as 1/sqrt(frames)). The all-dots frames and the shorter exposures stay single; the dark
  // bracket takes 4x as many at the longest when this is above 1 (its noise is every dot's).
  int longest_exposure_frames = 1;
  DisplaySyncOptions sync;

  bool Check(std::string* error) const;
};

// Dot centres in monitor pixel coordinates (pixel centres at +0.5), row-major.
std::vector<Eigen::Vector2d> DotScanGrid(const DotScanSessionOptions& options);
// The "dots:..." id of the whole grid.
std::string DotScanGridPattern(const DotScanSessionOptions& options);
// `count` validation dots between the grid's dots: the centres of grid cells (between four
// dots, where no fitted dot lies) spread evenly over the grid in row-major order.
std::vector<Eigen::Vector2d> DotScanValidationDots(const DotScanSessionOptions& options, int count);
// The frames the scan takes, in order, for a display of the given refresh period.
std::vector<PlannedFrame> PlanDotScan(const DotScanSessionOptions& options, double refresh_period_s);

Status RunDotScanSession(const DotScanSessionOptions& options, Camera* camera, Projector* monitor,
                         const SampleChanger& change_sample, SessionWriter* writer);

// Exposure-bracket session (kind "exposure_bracket", for the camera's radiometric response):
// sample_state "none"; an optional dark bracket (pattern "", kind "dark") and a bracket of
// `pattern` (default "flat", kind "bracket"), frames_per_exposure frames each.
struct BracketSessionOptions {
  ExposureBracketOptions bracket;
  std::string pattern = "flat";
  bool capture_dark = true;
  int frames_per_exposure = 1;
  DisplaySyncOptions sync;

  bool Check(std::string* error) const;
};
std::vector<PlannedFrame> PlanBracketSession(const BracketSessionOptions& options, double refresh_period_s);
Status RunBracketSession(const BracketSessionOptions& options, Camera* camera, Projector* projector,
                         const SampleChanger& change_sample, SessionWriter* writer);

}  // namespace thinslab
