// SPDX-License-Identifier: Apache-2.0
// `thinslab calib response|hdr|flat SESSION`: the options of the radiometric calibration
// (issue #6; pipeline/radiometric_calibration.h runs it). Each reads the session (never
// modifying its frames) and writes into SESSION/calib/ atomically:
//   response   -> calib/response.json           (calib/response_recovery, calib/response_io)
//   hdr        -> calib/hdr/<group>.exr + summary.json + options.ini (calib/hdr_merge)
//   flat       -> calib/flat_field.exr          (calib/flat_field)
// docs/format.md ("Radiometric calibration files") describes every file.
#include <iostream>

#include "thinslab/app/command_progress.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/pipeline/radiometric_calibration.h"

namespace thinslab {
namespace {

}  // namespace

int RunCalibResponse(int argc, char** argv) {
  CalibResponseRun run;
  std::string &session_dir = run.session_dir, &out = run.out, &method = run.method, &kind = run.kind,
              &camera_id = run.camera_id;
  ResponseRecoveryOptions& options = run.options;
  OptionParser parser("calib response");
  parser.AddPositional("SESSION", &session_dir, "capture session with an exposure bracket of a static scene");
  parser.AddString("method", &method, "debevec (Debevec & Malik 1997) or robertson (Robertson et al. 2003)");
  parser.AddString("kind", &kind,
                   "frame kind or group name (e.g. laser_contaminated) of the bracket; default: the non-dark group "
                   "with most exposures");
  parser.AddString("camera", &camera_id, "camera id (default: the first camera)");
  parser.AddInt("samples", &options.num_samples, "pixels sampled (stratified over irradiance)");
  parser.AddInt("strata", &options.num_strata, "irradiance strata the samples are spread over");
  parser.AddInt("knots", &options.max_knots, "largest number of response knots (16..4096)");
  parser.AddDouble("lambda", &options.smoothness_lambda, "Debevec smoothness weight");
  parser.AddDouble("robertson-lambda", &options.robertson_smoothness_lambda, "Robertson smoothness weight");
  parser.AddInt("min-exposures", &options.min_exposures, "fewest distinct exposures accepted (>= 2)");
  parser.AddUint64("seed", &options.seed, "seed of the pixel sample");
  parser.AddString("out", &out, "output file (default SESSION/calib/response.json)");
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  run.options_ini = parser.ToIni();
  if (status.ok()) status = CalibrateResponse(run, std::cout);
  return status.ok() ? 0 : CommandFailed(status);
}

int RunCalibHdr(int argc, char** argv) {
  CalibHdrRun run;
  std::string &session_dir = run.session_dir, &response_path = run.response_path, &weighting = run.weighting,
              &kind = run.kind, &camera_id = run.camera_id, &out = run.out;
  HdrMergeOptions& options = run.options;
  double& read_noise_dn = run.read_noise_dn;
  OptionParser parser("calib hdr");
  parser.AddPositional("SESSION", &session_dir, "capture session");
  parser.AddString("response", &response_path,
                   "response.json (default SESSION/calib/response.json if present; 'linear' = linear camera)");
  parser.AddString("weighting", &weighting, "inverse-variance, hat (linear mean) or debevec (hat, log-domain mean)");
  parser.AddString("kind", &kind, "merge only frames of this kind (default: every non-dark kind)");
  parser.AddString("camera", &camera_id, "camera id (default: the first camera)");
  parser.AddDouble("read-noise-dn", &read_noise_dn, "read noise when the session has no dark frames [DN]");
  parser.AddInt("threads", &options.num_threads, "threads");
  parser.AddString("out", &out, "output folder (default SESSION/calib/hdr)");
  parser.AddString("exposures", &run.exposures,
                   "reported (what the camera says it applied) or measured (reported x the factor the frames show)");
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  run.options_ini = parser.ToIni();
  run.progress = CommandProgress();
  if (status.ok()) status = CalibrateHdr(run, std::cout);
  return status.ok() ? 0 : CommandFailed(status);
}

int RunCalibFlat(int argc, char** argv) {
  CalibFlatRun run;
  std::string &session_dir = run.session_dir, &response_path = run.response_path, &out = run.out;
  FlatFieldOptions& options = run.options;
  OptionParser parser("calib flat");
  parser.AddPositional("SESSION", &session_dir, "shadow-map capture session");
  parser.AddString("response", &response_path,
                   "response.json (default SESSION/calib/response.json if present; 'linear' = linear camera)");
  parser.AddString("kind", &options.kind, "frame kind of the flat frames (default: flat if present, else reference)");
  parser.AddDouble("sigma-px", &options.smoothing_sigma_px, "Gaussian smoothing sigma [camera px]; 0 = none");
  parser.AddDouble("min-relative", &options.min_relative, "pixels below this fraction of the median are invalid");
  parser.AddString("out", &out, "output file (default SESSION/calib/flat_field.exr)");
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  run.options_ini = parser.ToIni();
  if (status.ok()) status = CalibrateFlatField(run, std::cout);
  return status.ok() ? 0 : CommandFailed(status);
}

}  // namespace thinslab
