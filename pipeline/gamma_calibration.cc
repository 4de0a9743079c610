// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/gamma_calibration.h"

#include <nlohmann/json.hpp>

#include <string>

#include "thinslab/core/provenance.h"
#include "thinslab/core/file.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/pipeline/capture_reading.h"

namespace thinslab {
namespace {

// The summary file beside a table: "x/display_gamma.txt" -> "x/display_gamma_summary.json".
std::string SummaryPath(const std::string& table_path) {
  const std::string ext = ".txt";
  const bool txt = table_path.size() > ext.size() && table_path.compare(table_path.size() - ext.size(), ext.size(), ext) == 0;
  return (txt ? table_path.substr(0, table_path.size() - ext.size()) : table_path) + "_summary.json";
}

}  // namespace

Status CalibrateDisplayGamma(const CalibGammaRun& run, std::ostream& log) {
  const std::string &session_dir = run.session_dir, &response_path = run.response_path;
  std::string out = run.out;
  const DisplayGammaFitOptions& options = run.options;
  Status status = Status::Ok();
  const std::string response_input = DefaultResponsePath(session_dir, response_path);
  if (status.ok()) status = ResolveCalibOutputFile(session_dir, "display_gamma.txt", {response_input}, &out);
  if (status.ok()) status = CheckOutputFile(SummaryPath(out), {{session_dir, {"calib"}}, {response_input, {}}});
  if (!status.ok()) return status;
  Session session;
  CameraResponse response;
  std::string response_file;
  status = ReadCaptureAndResponse(session_dir, run.allow_incomplete_capture, response_path, &session, &response, &response_file);
  if (!status.ok()) return status;
  DisplayGammaFitSummary summary;
  status = FitDisplayGammaSession(session_dir, session, response_file.empty() ? nullptr : &response, options, &summary);
  if (!status.ok()) return status;
  const std::string comment = "measured by thinslab " + std::string(THINSLAB_VERSION_STRING) + " (" +
                              THINSLAB_GIT_HASH + ") calib gamma from " + session_dir + "; " +
                              std::to_string(summary.num_levels) + " levels, fit residual rms " +
                              std::to_string(summary.rms_residual) + " of full light";
  status = CreateParentFolder(out);
  if (status.ok()) status = WriteGammaTable(out, summary.table, comment);
  nlohmann::ordered_json j;
  j["format"] = "thinslab-display-gamma-summary";
  j["format_version"] = "1.0";
  j["provenance"] = ProvenanceJson({"calib gamma", session_dir, "", run.options_ini});
  j["thinslab_version"] = THINSLAB_VERSION_STRING;
  j["git_hash"] = THINSLAB_GIT_HASH;
  j["session"] = session_dir;
  j["table"] = out;
  j["response"] = response_file.empty() ? "linear" : response_file;
  j["options_digest"] = OptionsDigest(run.options_ini);
  j["levels"] = summary.num_levels;
  j["darks"] = summary.num_darks;
  j["lit_pixels"] = summary.lit_pixels;
  j["pixels_saturated"] = summary.pixels_saturated;
  j["frames_near_saturation"] = summary.frames_near_saturation;
  j["outliers_rejected"] = summary.outliers_rejected;
  j["rms_residual"] = summary.rms_residual;
  j["max_abs_residual"] = summary.max_abs_residual;
  j["repeat_rms"] = summary.repeat_rms;
  j["power_exponent"] = summary.power_exponent;
  nlohmann::ordered_json measurements = nlohmann::ordered_json::array();
  for (const DisplayGammaMeasurement& m : summary.measurements) {
    measurements.push_back({{"level", m.level},
                            {"repeat", m.repeat},
                            {"frames", m.num_frames},
                            {"signal_dn_per_us", m.signal},
                            {"light", m.light},
                            {"residual", m.residual},
                            {"first_file", m.first_file}});
  }
  j["measurements"] = measurements;
  if (status.ok()) status = WriteFileAtomically(SummaryPath(out), j.dump(2) + "\n");
  if (!status.ok()) return status;
  log << summary.FullReport() << "wrote " << out << " and " << SummaryPath(out) << "\n";
  return Status::Ok();
}

}  // namespace thinslab
