// SPDX-License-Identifier: Apache-2.0
// summary.json sections and text lines for predictions compared with measurements (issue #23
// section 4): the validation reports of `fit tau` and `fit phase` and `thinslab predict`.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "thinslab/calib/laser_lobe_preparation.h"
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

// The lobe a `fit phase` output (FIT/summary.json: Eq. 8's beta, g and tau) predicts for the
// laser-lobe capture SESSION, against the rings measured in its frames (its validation lobe when
// it has one) out to the fit's outermost angle: what PredictLobeFromPhase writes, for callers
// that compare it with more (the render round trip, export/lobe_round_trip.h).
struct LobeFitPrediction {
  LaserLobeImages images;  // With the camera's HDR (keep_camera_hdr); `lobe` is the one compared.
  bool validation = false;
  double beta = 0, g = 0, sigma_g = 0, tau = 0, fit_board_distance_m = 0, max_theta_deg = 0;
  double layer_albedo = -1;  // The albedo the fit was given (summary.json), -1 when not recorded.
  LobePrediction prediction;
};
Status PredictLobe(const std::string& session_dir, const Session& session, const std::string& fit_dir,
                   const SessionCalibrationOptions& calibration, LobeFitPrediction* out);

// A radial lobe profile (a ring's value, flat-fielded at the beam centre and clean glass
// subtracted, against the distance r from the beam centre on the board) imaged in the capture's
// camera: per camera pixel, the board point its ray meets, taken back from the rings' units to
// the pixel's own:
//   predicted = profile(r) * flat(u) / flat(centre) + clean(u),
// over the pixels between the spike core and the outermost angle of `ring`, against the HDR
// merge. camera_image: channels predicted, measured, variance, valid.
struct LobeCameraError {
  int64_t pixels = 0;
  double relative_rms = -1, noise_relative_rms = -1;
};
LobeCameraError ImageLobeInCamera(const LaserLobeImages& images, const LaserRingGeometry& ring,
                                  const std::function<double(double r_m)>& profile, Image* camera_image);

}  // namespace thinslab
