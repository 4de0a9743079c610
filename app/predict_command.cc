// SPDX-License-Identifier: Apache-2.0
// `thinslab predict CAPTURE` (pipeline/predict.h runs it; this file parses its options): what a fit predicts for light states it was not fitted to (issue
// #23 section 4). Shadow maps and laser lobes: pipeline/predict_layer.cc. Dot scans: the images a
// dot-scan fit predicts for dots (fit/dmf_prediction.h), in the capture's camera, against the
// capture's frames of those dots where it has them. Writes OUT (default CAPTURE/fit/predict) atomically:
//   dot_<k>.exr    channels predicted, valid (and measured, variance: the HDR merge of the
//                  capture's frames of that dot), DN/us with the black level and darks removed
//   summary.json   per dot: dot_px, measured, pixels, relative_rms, noise_relative_rms
//   summary.txt
//   options.ini    the effective options (their digest is the outputs' options_digest)
#include <iostream>

#include "thinslab/app/calibration_options.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/pipeline/predict.h"

namespace thinslab {

int RunPredict(int argc, char** argv) {
  PredictCaptureRun run;
  std::string &session_dir = run.session_dir, &fit_dir = run.fit_dir, &out_dir = run.out_dir, &dots = run.dots;
  OptionParser parser("predict");
  parser.AddPositional("CAPTURE", &session_dir, "capture whose frames the fit predicts (may be another capture of the fitted sample)");
  parser.AddString("fit", &fit_dir,
                   "output folder of `thinslab fit tau`, `fit phase` or `fit dmf` (default CAPTURE/fit/tau, phase or dmf by "
                   "the capture's kind)");
  parser.AddString("dots", &dots, "dots to predict, 'x,y;x,y' [monitor px] (default: the capture's validation dots)");
  parser.AddString("out", &out_dir, "output folder (default CAPTURE/fit/predict)");
  AddCalibrationOptions(&parser, &run.calibration);
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  run.options_ini = parser.ToIni();
  if (status.ok()) status = PredictCapture(run, std::cout);
  if (!status.ok()) return CommandFailed(status);
  return 0;
}

}  // namespace thinslab
