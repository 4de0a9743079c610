// SPDX-License-Identifier: Apache-2.0
// The record of the calibration a fit applied and of its HDR merge's exposure check, in the
// fits' summary.json (docs/format.md section 9).
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "thinslab/calib/exposure_check.h"
#include "thinslab/calib/session_calibration.h"

namespace thinslab {

// The warning when the dot radius was assumed (ResolveDotRadiusPx's "default"), naming `manifest`.
std::string AssumedDotRadiusWarning(const std::string& manifest);

// {"rig": file or null, "intrinsics": bool, "pose": bool, "monitor": bool, "response": file or
// null, "response_method": "linear" | "debevec" | "robertson"} (docs/format.md section 9).
nlohmann::json CalibrationSummaryJson(const SessionCalibration& calibration);

// The exposure check of an HDR merge (calib/exposure_check.h): {"reported_us", "measured_over_reported",
// "pixels", "max_deviation" (-1 = not measured), "warning", "merged_with": "measured" | "reported"}.
nlohmann::json ExposureCheckJson(const ExposureCheck& check, bool merged_with_measured_exposures);

}  // namespace thinslab
