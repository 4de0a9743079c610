// SPDX-License-Identifier: Apache-2.0
// The whole shadow-map fit (Gu et al. 2007, Eqs. 5-7) from a capture folder to an output folder,
// without device code: what `thinslab fit tau`, `demo`, the stability benches and a user's own
// program run.
#pragma once

#include <string>

#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/tau_evaluation.h"
#include "thinslab/fit/tau_fit.h"

namespace thinslab {

// Shared by `fit tau` and `demo`: reads the session, rectifies, fits and writes
// <out_dir>/{tau.exr, tau_falsecolor.png, tau_plain_falsecolor.png, summary.json, summary.txt,
// options.ini} atomically (the folder appears complete or not at all). If the session holds
// ground_truth/tau.exr, also writes comparison.json and fills `comparison`.
struct FitTauRun {
  TauFitOptions fit;
  int supersample = 4;
  double board_distance_m = 0;  // 0: from the manifest.
  SessionCalibrationOptions calibration;  // CAPTURE/calib/ files applied (calib/session_calibration.h).
  // A `fit phase` output folder whose choice sets fit.layer_g and fit.refine_scattering
  // (pipeline/layer_from_phase.h); "" = the options as given.
  std::string phase_dir;
  bool allow_incomplete_capture = false;  // accept a capture whose acquisition did not complete (--allow-incomplete).
  // Fit the even and the odd shadow frames separately too and compare them (summary.json
  // `consistency`; needs >= 2 shadow frames): the noise part of sigma_tau put to a test.
  bool split_half_check = true;
  // Budget of the fit's peak memory [bytes] (issue #29): a capture whose estimated need
  // (fit/tau_memory.h) exceeds it is refused before any frame is read; 0 = none (the machine's
  // memory still bounds it).
  double max_memory_bytes = 2.0 * 1024 * 1024 * 1024;
  std::string options_ini;      // Effective options, written as options.ini.
};
Status FitTauPipeline(const std::string& session_dir, const std::string& out_dir, const FitTauRun& run,
                      TauFitSummary* summary, TauComparison* comparison, bool* has_truth);

}  // namespace thinslab
