// SPDX-License-Identifier: Apache-2.0
// What an optical-thickness map predicts for a shadow-map light state (issue #23 section 4):
// the ratio m = I / I_clean on the board at a given board distance, from the model the fit
// inverts (Gu et al. 2007, Eq. 5 and Eq. 6; fit/tau_fit.h):
//   m = e^{-tau} + S[tau] / E0,
// S the light the layer scatters onto the board (optics/shadow_map_model.h) and E0 the clean
// board signal. The scattered part depends on the board distance and the unscattered one does
// not, so a map fitted at one distance predicts a shadow at another: a test of the model, not
// only of the frames' repeatability.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/fit/tau_fit.h"
#include "thinslab/optics/shadow_map_model.h"

namespace thinslab {

// The geometry (kernel angle, radius capped at the grid's diagonal) and the tau nodes (up to
// tau_max) of LayerScatterKernelBank.
BoardGeometry LayerScatterGeometry(const TauFitOptions& layer, double board_distance_m, double pixel_pitch_m, int width,
                                   int height);
std::vector<double> LayerScatterNodes(const TauFitOptions& layer);

// The Eq. 6 kernels of the layer (albedo, g, kernel angle and tau nodes up to tau_max of
// `layer`) at `board_distance_m` on a width x height grid of `pixel_pitch_m`.
ScatterKernelBank LayerScatterKernelBank(const TauFitOptions& layer, double board_distance_m, double pixel_pitch_m,
                                         int width, int height);

// m at every map pixel of `tau` (single channel), lit by `e0` (the clean board signal, any
// unit, same grid; pixels not > 0 emit with the median of the others): e^{-tau} + S[tau] / e0,
// or e^{-tau} alone when
// layer.refine_scattering is off or the albedo is 0.
Image PredictShadowRatio(const TauFitOptions& layer, const Image& tau, const Image& e0, double board_distance_m,
                         double pixel_pitch_m);

// Prediction against a measurement over one range of fitted tau.
struct ShadowPredictionRegion {
  std::string name;               // "clean", "thin", "thick" or "all".
  double tau_min = 0, tau_max = 0;  // Fitted tau in [tau_min, tau_max).
  int64_t pixels = 0;
  // sqrt(sum (pred - meas)^2 / sum meas^2); -1 without pixels.
  double relative_rms = -1;
  // The same for a second prediction (e.g. plain Eq. 7, e^{-tau_plain} I_clean); -1 if none.
  double alternative_relative_rms = -1;
  // sqrt(sum var / sum meas^2): the error noise alone would give (measurement and prediction).
  double noise_relative_rms = -1;
  // sqrt(sum (pred sigma_tau)^2 / sum meas^2): the error the map's sigma_tau claims.
  double sigma_tau_relative_rms = -1;
};

// Over map pixels with valid[i] != 0, per fitted-tau region (clean < 0.05 <= thin < 0.5 <=
// thick) and over all. `variance` holds the measurement's plus the prediction's noise variance;
// `alternative` may be empty.
std::vector<ShadowPredictionRegion> CompareShadowPrediction(const Image& predicted, const Image& alternative,
                                                            const Image& measured, const Image& variance,
                                                            const Image& tau, const Image& sigma_tau,
                                                            const std::vector<uint8_t>& valid);

}  // namespace thinslab
