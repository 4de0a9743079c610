// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/calibration_summary.h"

#include <cstdio>

#include "thinslab/calib/dot_geometry.h"

namespace thinslab {

std::string AssumedDotRadiusWarning(const std::string& manifest) {
  char radius[32];
  std::snprintf(radius, sizeof(radius), "%g", kDefaultDotRadiusPx);
  return manifest + ": rig.monitor.dot_radius_px is not given; assuming " + radius +
         " monitor px (it sets the detection windows and L_q; --dot-radius-px or the manifest field sets it)";
}

nlohmann::json CalibrationSummaryJson(const SessionCalibration& calibration) {
  nlohmann::json j;
  j["rig"] = calibration.rig_file.empty() ? nlohmann::json() : nlohmann::json(calibration.rig_file);
  j["intrinsics"] = calibration.intrinsics;
  j["pose"] = calibration.pose;
  j["monitor"] = calibration.monitor.present;
  j["response"] = calibration.response_file.empty() ? nlohmann::json() : nlohmann::json(calibration.response_file);
  j["response_method"] = calibration.response_file.empty() ? std::string("linear") : calibration.response.method;
  j["flat_field"] =
      calibration.flat_field_file.empty() ? nlohmann::json() : nlohmann::json(calibration.flat_field_file);
  return j;
}

nlohmann::json ExposureCheckJson(const ExposureCheck& check, bool merged_with_measured_exposures) {
  return {{"reported_us", check.reported_us},
          {"measured_over_reported", check.measured_over_reported},
          {"pixels", check.pixels},
          {"max_deviation", check.measured ? check.max_deviation : -1},
          {"warning", check.Warning()},
          {"merged_with", merged_with_measured_exposures ? "measured" : "reported"}};
}

}  // namespace thinslab
