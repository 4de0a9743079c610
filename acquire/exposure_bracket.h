// SPDX-License-Identifier: Apache-2.0
// Exposure brackets: the list of exposures a session takes of one light state so that a
// signal spanning many decades (a laser lobe, a CRT dot through a rough slab) is merged into
// one HDR image (calib/hdr_merge.h). With a scanned display in the light path (CRT, LCD
// with PWM backlight) every exposure is a whole number of refresh periods, so every pixel of
// the screen is integrated the same number of times; a fraction of a period would make the
// recorded dot brightness depend on where the raster was when the shutter opened.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/status.h"
#include "thinslab/drivers/camera.h"

namespace thinslab {

struct ExposureBracketOptions {
  // Explicit exposures [us]; when empty, `steps` exposures spaced geometrically from
  // min_exposure_us to max_exposure_us.
  std::vector<double> exposures_us;
  double min_exposure_us = 1000;
  double max_exposure_us = 100000;
  int steps = 3;
  // Refresh period of the display in the light path [s]; 0 = no scanned display. Exposures
  // are then rounded to whole multiples (at least one period).
  double refresh_period_s = 0;
  // Largest accepted difference between the exposure the camera reports applying and the
  // whole multiple of the refresh period that was asked for, as a fraction of one period.
  double max_refresh_mismatch = 0.02;

  bool Check(std::string* error) const;
};

// `options` with refresh_period_s set to `display_refresh_period_s` unless it already gives
// one (> 0): the session scripts' rule "0 takes the display's".
ExposureBracketOptions WithDisplayRefresh(ExposureBracketOptions options, double display_refresh_period_s);

// Requested exposures [us], ascending, duplicates (after rounding to refresh multiples)
// removed.
std::vector<double> PlanExposureBracket(const ExposureBracketOptions& options);

// Rounds `requested_us` to the nearest whole number (>= 1) of refresh periods; returns the
// request unchanged when refresh_period_s <= 0.
double ExposureAsRefreshMultipleUs(double requested_us, double refresh_period_s);

// Sets the exposure and reads back the applied value. With a refresh period, an applied
// exposure further than max_refresh_mismatch periods from a whole multiple is an error naming
// the camera and both values (the camera's exposure granularity cannot follow the display).
Status ApplyBracketExposure(Camera* camera, double requested_us, const ExposureBracketOptions& options,
                            double* applied_us);

// Parses "20,200,2000" (microseconds, positive); errors name `option`.
Status ParseExposureList(const std::string& text, const std::string& option, std::vector<double>* exposures_us);

}  // namespace thinslab
