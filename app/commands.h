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
#include "thinslab/pipeline/phase_pipeline.h"
#include "thinslab/pipeline/tau_pipeline.h"
#include "thinslab/sim/synthesize_shadow_session.h"

namespace thinslab {

int RunInfo(int argc, char** argv);
int RunCheck(int argc, char** argv);  // app/check_command.cc
int RunExport(int argc, char** argv);  // app/export_command.cc
int RunPreviewFit(int argc, char** argv);  // app/preview_command.cc
int RunRoundTrip(int argc, char** argv);  // app/roundtrip_command.cc
int RunBatch(int argc, char** argv);  // app/batch_command.cc
// `thinslab check`'s exit status for the verdict "retake" (and `thinslab acquire`'s check option).
inline constexpr int kCheckRetakeExitCode = 3;
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

// Adds the sim rig and session options to a parser (used by `sim shadow-maps` and `demo`).
class OptionParser;
void AddSimShadowOptions(OptionParser* parser, SyntheticShadowSessionOptions* options, double* board_distance_mm,
                         std::string* tau_path);
// --linear-float-frames and --value-scale of every `sim` command (SimSensorOptions).
void AddSimFrameValueOptions(OptionParser* parser, SimSensorOptions* sensor);
// Loads --tau EXR or generates the bundled demo pattern on the rig's grid when tau_path is "".
Status LoadOrGenerateTau(const std::string& tau_path, uint64_t seed, Image* tau);

}  // namespace thinslab
