// SPDX-License-Identifier: Apache-2.0
#include "app/calibration_options.h"

#include "app/option_parser.h"

namespace thinslab {

void AddCalibrationOptions(OptionParser* parser, SessionCalibrationOptions* options) {
  parser->AddString("calibration", &options->mode,
                    "'auto': apply CAPTURE/calib/rig.json and response.json where present; 'none': the manifest's "
                    "geometry and a linear camera");
  parser->AddString("rig", &options->rig_path, "rig.json to apply (default CAPTURE/calib/rig.json if present)");
  parser->AddString("response", &options->response_path,
                    "response.json that linearises the frames, or 'linear' (default CAPTURE/calib/response.json if "
                    "present)");
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
