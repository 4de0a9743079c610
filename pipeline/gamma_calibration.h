// SPDX-License-Identifier: Apache-2.0
// The display gamma table of a "display_gamma" session (`thinslab acquire gamma`), fitted by
// calib/display_gamma_fit.h: what `thinslab calib gamma` runs, without CLI or device code. Writes
// SESSION/calib/display_gamma.txt (or `out`) and its summary beside it
// (<table without .txt>_summary.json) atomically and logs the report to `log`.
#pragma once

#include <ostream>
#include <string>

#include "thinslab/calib/display_gamma_fit.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct CalibGammaRun {
  std::string session_dir;
  std::string response_path;  // "" = SESSION/calib/response.json if present; "linear".
  std::string out;            // "" = SESSION/calib/display_gamma.txt.
  DisplayGammaFitOptions options;
  bool allow_incomplete_capture = false;
  std::string options_ini;    // Its digest goes into the summary.
};
Status CalibrateDisplayGamma(const CalibGammaRun& run, std::ostream& log);

}  // namespace thinslab
