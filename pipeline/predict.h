// SPDX-License-Identifier: Apache-2.0
// `thinslab predict CAPTURE`: what a fit predicts for light states it was not fitted to (issue
// #23 section 4). Shadow maps and laser lobes: pipeline/predict_layer.cc. Dot scans: the images a
// dot-scan fit predicts for dots (fit/dmf_prediction.h), in the capture's camera, against the
// capture's frames of those dots where it has them. Writes OUT (default CAPTURE/fit/predict) atomically:
//   dot_<k>.exr    channels predicted, valid (and measured, variance: the HDR merge of the
//                  capture's frames of that dot), DN/us with the black level and darks removed
//   summary.json   per dot: dot_px, measured, pixels, relative_rms, noise_relative_rms
//   summary.txt
#pragma once

#include <Eigen/Core>
#include <ostream>
#include <string>
#include <vector>

#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct PredictCaptureRun {
  std::string session_dir;  // The capture whose frames the fit predicts (may be another capture of the sample).
  std::string fit_dir;      // `fit tau`, `fit phase` or `fit dmf` output; "" = CAPTURE/fit/<by the capture's kind>.
  std::string out_dir;      // "" = CAPTURE/fit/predict.
  std::string dots;         // "x,y;x,y" [monitor px] for dot scans; "" = the capture's validation dots.
  SessionCalibrationOptions calibration;
  bool allow_incomplete_capture = false;
  // The command's effective options (OptionParser::ToIni), written as OUT/options.ini; their
  // digest is the outputs' options_digest. "" (library callers): the resolved dots stand in.
  std::string options_ini;
};
Status PredictCapture(const PredictCaptureRun& run, std::ostream& log);

// "x,y;x,y" [monitor px]; errors name --dots.
Status ParseDotList(const std::string& text, std::vector<Eigen::Vector2d>* dots);
// The distinct dot positions of the capture's validation dot frames of `camera`; an error naming
// the manifest (and --dots) when it has none.
Status ValidationDots(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                      std::vector<Eigen::Vector2d>* dots);
// The HDR merge (DN/us, black level and darks removed) of the capture's frames of the dot at
// `dot_px`, fitted or validation; *found is false (and hdr untouched) when it has none.
Status MergeDotFrames(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                      const SessionCalibration& calibration, const FrameNoiseModel& noise,
                      const Eigen::Vector2d& dot_px, HdrImage* hdr, bool* found);

}  // namespace thinslab
