// SPDX-License-Identifier: Apache-2.0
// `thinslab calib gamma SESSION [--response FILE|linear] [--out FILE]` (docs/cli.md): the display
// gamma table of a "display_gamma" session (`thinslab acquire gamma`), fitted by
// calib/display_gamma_fit.h and written atomically to SESSION/calib/display_gamma.txt (or
// --out / -o), with its summary beside it (<table without .txt>_summary.json) and on stdout
// (pipeline/gamma_calibration.h runs it; this file parses its options).
#include <iostream>
#include <string>
#include <vector>

#include "thinslab/app/capture_options.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/pipeline/gamma_calibration.h"

namespace thinslab {
namespace {

}  // namespace

int RunCalibGamma(int argc, char** argv) {
  CalibGammaRun run;
  std::string &session_dir = run.session_dir, &response_path = run.response_path, &out = run.out;
  DisplayGammaFitOptions& options = run.options;
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
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  parser.SetShortName("out", 'o');
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  run.options_ini = parser.ToIni();
  const Status status = CalibrateDisplayGamma(run, std::cout);
  return status.ok() ? 0 : CommandFailed(status);
}

}  // namespace thinslab
