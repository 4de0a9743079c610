// SPDX-License-Identifier: Apache-2.0
// summary.json sections and text lines for predictions compared with measurements (issue #23
// section 4): the validation reports of `fit tau` and `fit phase` and `thinslab predict`.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "thinslab/calib/session_calibration.h"
#include "thinslab/calib/shadow_map_preparation.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session.h"
#include "thinslab/fit/phase_fit.h"
#include "thinslab/fit/tau_fit.h"
#include "thinslab/fit/tau_prediction.h"

namespace thinslab {

// The shadow `data.validation_shadow` (or, with `use_fitted_frames`, `data.shadow`) compared with
// what `maps` predict at `data.board_distance_m` for the layer of `layer`, lit by `e0` (the
// capture's clean board signal); the prediction's noise variance is `prediction_variance`.
std::vector<ShadowPredictionRegion> CompareShadowWithMaps(const TauFitOptions& layer, const Image& tau_map,
                                                          const RectifiedShadowMaps& data, const Image& e0,
                                                          const Image& prediction_variance, bool use_fitted_frames,
                                                          Image* predicted_shadow);

nlohmann::json ShadowRegionsJson(const std::vector<ShadowPredictionRegion>& regions);
// One line per region: "  thin (tau 0.05-0.5): relative RMS 0.012 (plain Eq. 7 0.020, noise 0.010) over 400 px".
std::string ShadowRegionsText(const std::vector<ShadowPredictionRegion>& regions);

nlohmann::json LobeBandsJson(const LobePrediction& prediction);
std::string LobeBandsText(const LobePrediction& prediction);

// `thinslab predict` (app/predict_command.cc) for the fits of shadow-map and laser-lobe captures
// (pipeline/predict_layer.cc): writes into `out` and commits it.
struct PredictRun {
  std::string session_dir, fit_dir, out_dir;
  SessionCalibrationOptions calibration;
  std::string options_ini;  // PredictCaptureRun::options_ini.
};
Status PredictShadowFromTau(const PredictRun& run, const Session& session, StagedDirectory* out);

// The shadow a `fit tau` output (FIT/tau.exr and summary.json) predicts for the shadow-map
// capture SESSION: what PredictShadowFromTau writes, for callers that compare it with more (the
// render round trip, export/round_trip.h).
struct ShadowPrediction {
  RectifiedShadowMaps data;  // The capture's frames as `fit tau` rectifies them, with the camera's.
  TauFitOptions layer;       // The layer the map was fitted with (summary.json).
  Image tau_map;             // FIT/tau.exr.
  bool validation = false;   // `measured` holds the capture's validation frames (else its fitted ones).
  Image board;               // shadow.exr's channels, on the board grid.
  // shadow_camera.exr's channels in the camera's pixels: predicted, predicted_plain, measured,
  // variance, valid, clean (the pixel's own reference signal), tau, sigma_tau (footprint means).
  Image camera;
  std::vector<ShadowPredictionRegion> regions, camera_regions;
};
Status PredictShadow(const std::string& session_dir, const Session& session, const std::string& fit_dir,
                     const SessionCalibrationOptions& calibration, ShadowPrediction* prediction);
Status PredictLobeFromPhase(const PredictRun& run, const Session& session, StagedDirectory* out);

}  // namespace thinslab
