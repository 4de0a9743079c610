// SPDX-License-Identifier: Apache-2.0
// The thinslab subcommands. Each takes the arguments after its name and returns an exit code;
// errors are printed as one line naming the file/field/option.
#pragma once

#include <iostream>
#include <string>

#include "thinslab/calib/laser_lobe_preparation.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/laser_lobe_ladder.h"
#include "thinslab/fit/phase_fit.h"
#include "thinslab/fit/tau_evaluation.h"
#include "thinslab/fit/tau_fit.h"
#include "thinslab/sim/sensor_model.h"
#include "thinslab/sim/synthesize_shadow_session.h"

namespace thinslab {

// A dispatcher's answer to a missing, help or unknown subcommand `what`: the usage on stderr,
// and for an unknown one an `error:` line naming it; exit 0 for help, 2 otherwise.
inline int SubcommandUsage(const std::string& command, const std::string& what, const std::string& usage) {
  std::cerr << usage;
  if (what.empty() || what == "--help" || what == "-h" || what == "help") return 0;
  std::cerr << "error: thinslab " << command << ": unknown subcommand '" << what << "'\n";
  return 2;
}

int RunInfo(int argc, char** argv);
int RunSim(int argc, char** argv);
int RunFit(int argc, char** argv);
int RunDemo(int argc, char** argv);
int RunFitPhase(int argc, char** argv);
int RunFitDmf(int argc, char** argv);  // app/dmf_commands.cc
int RunPredict(int argc, char** argv);  // app/predict_command.cc
int RunSimLaser(int argc, char** argv);
int RunCharts(int argc, char** argv);
int RunBench(int argc, char** argv);    // app/bench_command.cc
int RunAcquire(int argc, char** argv);  // app/acquire_commands.cc
int RunSynth(int argc, char** argv);    // app/synth_commands.cc
int RunCalib(int argc, char** argv);    // app/calib_commands.cc: dispatches to the seven below.
int RunCalibCamera(int argc, char** argv);    // app/calib_geometry_commands.cc
int RunCalibPose(int argc, char** argv);      // app/calib_geometry_commands.cc
int RunCalibDots(int argc, char** argv);      // app/calib_geometry_commands.cc
int RunCalibResponse(int argc, char** argv);  // app/calib_radiometry_commands.cc
int RunCalibHdr(int argc, char** argv);       // app/calib_radiometry_commands.cc
int RunCalibFlat(int argc, char** argv);      // app/calib_radiometry_commands.cc
int RunCalibGamma(int argc, char** argv);     // app/calib_gamma_command.cc

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
  // (app/layer_from_phase.h); "" = the options as given.
  std::string phase_dir;
  bool allow_incomplete_capture = false;  // --allow-incomplete (app/capture_options.h).
  // Fit the even and the odd shadow frames separately too and compare them (summary.json
  // `consistency`; needs >= 2 shadow frames): the noise part of sigma_tau put to a test.
  bool split_half_check = true;
  std::string options_ini;      // Effective options, written as options.ini.
};
Status FitTauPipeline(const std::string& session_dir, const std::string& out_dir, const FitTauRun& run,
                      TauFitSummary* summary, TauComparison* comparison, bool* has_truth);

// `fit phase`: reads a laser-lobe session, fits Gu Eq. 8 and writes <out_dir>/{summary.json,
// summary.txt, rings.csv, lobe_plot.png, options.ini} atomically.
// allow_incomplete_capture: --allow-incomplete (app/capture_options.h).
Status FitPhasePipeline(const std::string& session_dir, const std::string& out_dir, const PhaseFitOptions& options,
                        const LaserLobePreparationOptions& preparation, bool allow_incomplete_capture,
                        const std::string& options_ini, PhaseFitSummary* summary,
                        std::vector<LaserRing>* rings, LaserLadderResult* ladder = nullptr);

// Adds the sim rig and session options to a parser (used by `sim shadow-maps` and `demo`).
class OptionParser;
void AddSimShadowOptions(OptionParser* parser, SyntheticShadowSessionOptions* options, double* board_distance_mm,
                         std::string* tau_path);
// --linear-float-frames and --value-scale of every `sim` command (SimSensorOptions).
void AddSimFrameValueOptions(OptionParser* parser, SimSensorOptions* sensor);
// Loads --tau EXR or generates the bundled demo pattern on the rig's grid when tau_path is "".
Status LoadOrGenerateTau(const std::string& tau_path, uint64_t seed, Image* tau);

}  // namespace thinslab
