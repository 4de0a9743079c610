// SPDX-License-Identifier: Apache-2.0
// The options every fit command shares for the calibration it applies (calib/session_calibration.h)
// and the record of it in the fits' summary.json.
#pragma once

#include <nlohmann/json.hpp>

#include "thinslab/calib/dot_geometry.h"
#include "thinslab/calib/exposure_check.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/pipeline/calibration_summary.h"

namespace thinslab {

class OptionParser;

// --calibration auto|none, --rig PATH, --response PATH|linear.
void AddCalibrationOptions(OptionParser* parser, SessionCalibrationOptions* options);

// The all-dots frame's detection (calib/dot_geometry.h), shared by `calib dots` and `fit dmf`:
// --dot-radius-px (0 = rig.monitor.dot_radius_px, else 2 px with a warning), --threshold-sigma,
// --threshold-fraction, --min-peak-fraction, --min-blob-area-px, --peak-separation-fraction,
// --window-margin-px, --background-window-px, --match-gate-fraction.
void AddDotDetectionOptions(OptionParser* parser, DotGeometryOptions* options, double* dot_radius_px);
// After parsing: an explicitly given --dot-radius-px must be > 0 (0 is only the default's meaning).
Status CheckDotRadiusOption(const OptionParser& parser, double dot_radius_px);
}  // namespace thinslab
