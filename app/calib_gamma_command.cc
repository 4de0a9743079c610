// SPDX-License-Identifier: Apache-2.0
// `thinslab calib gamma SESSION [--response FILE|linear] [--out FILE]` (docs/cli.md): the display
// gamma table of a "display_gamma" session (`thinslab acquire gamma`), fitted by
// calib/display_gamma_fit.h and written atomically to SESSION/calib/display_gamma.txt (or
// --out / -o), with its summary beside it (<table without .txt>_summary.json) and on stdout.
#include <nlohmann/json.hpp>

#include <iostream>
#include <string>
#include <vector>

#include "thinslab/app/capture_options.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/calib/display_gamma_fit.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"

namespace thinslab {
namespace {

int Fail(const Status& status) {
  std::cerr << "error: " << status.message() << "\n";
  return 1;
}

// The summary file beside a table: "x/display_gamma.txt" -> "x/display_gamma_summary.json".
std::string SummaryPath(const std::string& table_path) {
  const std::string ext = ".txt";
  const bool txt = table_path.size() > ext.size() && table_path.compare(table_path.size() - ext.size(), ext.size(), ext) == 0;
  return (txt ? table_path.substr(0, table_path.size() - ext.size()) : table_path) + "_summary.json";
}

}  // namespace

int RunCalibGamma(int argc, char** argv) {
  // "-o FILE" is accepted as "--out FILE".
  std::vector<std::string> args(argv, argv + argc);
  for (std::string& a : args) {
    if (a == "-o") a = "--out";
  }
  std::vector<char*> arg_ptrs;
  for (std::string& a : args) arg_ptrs.push_back(a.data());
  std::string session_dir, response_path, out;
  DisplayGammaFitOptions options;
  OptionParser parser("calib gamma");
  parser.AddPositional("SESSION", &session_dir, "display_gamma session (thinslab acquire gamma)");
  parser.AddString("response", &response_path,
                   "camera response.json (default SESSION/calib/response.json if present; 'linear' = linear camera)");
  parser.AddString("out", &out, "gamma table to write (default SESSION/calib/display_gamma.txt); also -o");
  parser.AddDouble("lit-fraction", &options.lit_fraction,
                   "lit region: level-1 signal above this fraction of its --lit-percentile percentile");
  parser.AddDouble("lit-percentile", &options.lit_percentile, "percentile the lit region refers to, in (0, 1]");
  parser.AddDouble("near-saturation", &options.near_saturation,
                   "frames with more than --max-near-saturated-fraction of their pixels above this fraction of "
                   "saturation are left out");
  parser.AddDouble("max-near-saturated-fraction", &options.max_near_saturated_fraction,
                   "fraction of a frame's pixels allowed above --near-saturation");
  parser.AddDouble("max-saturated-fraction", &options.max_saturated_fraction,
                   "more of the lit pixels saturated at every exposure of a level is an error");
  parser.AddDouble("outlier-mads", &options.outlier_mads, "pixels further than this many scaled MADs are left out");
  parser.AddDouble("read-noise-dn", &options.fallback_read_noise_dn, "read noise when the session has no dark frames [DN]");
  bool allow_incomplete = false;
  AddIncompleteCaptureOption(&parser, &allow_incomplete);
  Status status = parser.Parse(static_cast<int>(arg_ptrs.size()), arg_ptrs.data());
  if (parser.help_requested()) {
    std::cout << parser.Usage();
    return 0;
  }
  const std::string response_input = DefaultResponsePath(session_dir, response_path);
  if (status.ok()) status = ResolveCalibOutputFile(session_dir, "display_gamma.txt", {response_input}, &out);
  if (status.ok()) status = CheckOutputFile(SummaryPath(out), {{session_dir, {"calib"}}, {response_input, {}}});
  if (!status.ok()) return Fail(status);
  Session session;
  CameraResponse response;
  std::string response_file;
  status = ReadCaptureAndResponse(session_dir, allow_incomplete, response_path, &session, &response, &response_file);
  if (!status.ok()) return Fail(status);
  DisplayGammaFitSummary summary;
  status = FitDisplayGammaSession(session_dir, session, response_file.empty() ? nullptr : &response, options, &summary);
  if (!status.ok()) return Fail(status);
  const std::string comment = "measured by thinslab " + std::string(THINSLAB_VERSION_STRING) + " (" +
                              THINSLAB_GIT_HASH + ") calib gamma from " + session_dir + "; " +
                              std::to_string(summary.num_levels) + " levels, fit residual rms " +
                              std::to_string(summary.rms_residual) + " of full light";
  status = CreateParentFolder(out);
  if (status.ok()) status = WriteGammaTable(out, summary.table, comment);
  nlohmann::ordered_json j;
  j["format"] = "thinslab-display-gamma-summary";
  j["format_version"] = "1.0";
  j["thinslab_version"] = THINSLAB_VERSION_STRING;
  j["git_hash"] = THINSLAB_GIT_HASH;
  j["session"] = session_dir;
  j["table"] = out;
  j["response"] = response_file.empty() ? "linear" : response_file;
  j["options_digest"] = "fnv1a64:" + Digest(parser.ToIni());
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
  if (!status.ok()) return Fail(status);
  std::cout << summary.FullReport() << "wrote " << out << " and " << SummaryPath(out) << "\n";
  return 0;
}

}  // namespace thinslab
