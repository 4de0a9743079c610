// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/tau_prediction.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "thinslab/core/math.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/henyey_greenstein.h"

namespace thinslab {

BoardGeometry LayerScatterGeometry(const TauFitOptions& layer, double board_distance_m, double pixel_pitch_m, int width,
                                   int height) {
  BoardGeometry geometry;
  geometry.distance_m = board_distance_m;
  geometry.pixel_pitch_m = pixel_pitch_m;
  geometry.max_angle_deg = layer.kernel_max_angle_deg;
  geometry.max_radius_px = static_cast<int>(std::ceil(std::hypot(width, height)));
  return geometry;
}

std::vector<double> LayerScatterNodes(const TauFitOptions& layer) {
  std::vector<double> nodes;
  for (double t : ScatterKernelBank::DefaultNodes()) {
    nodes.push_back(t);
    if (t >= layer.tau_max) break;
  }
  return nodes;
}

ScatterKernelBank LayerScatterKernelBank(const TauFitOptions& layer, double board_distance_m, double pixel_pitch_m,
                                         int width, int height) {
  const BoardGeometry geometry = LayerScatterGeometry(layer, board_distance_m, pixel_pitch_m, width, height);
  const std::vector<double> nodes = LayerScatterNodes(layer);
  const double albedo = layer.layer_albedo, g = layer.layer_g;
  // Gu et al. 2007, Eq. 6 with mu'_i = 1, divided by tau (its limit at tau = 0).
  return ScatterKernelBank(nodes, [albedo, g](double t, double mu) {
    if (t < 1e-9) return albedo * HenyeyGreenstein(mu, g) / mu;
    return LayerSingleScatterRadiance(t, mu, albedo, g) / t;
  }, geometry);
}

Image PredictShadowRatio(const TauFitOptions& layer, const Image& tau, const Image& e0, double board_distance_m,
                         double pixel_pitch_m) {
  const int w = tau.width(), h = tau.height();
  Image ratio(w, h), clamped(w, h);
  for (size_t i = 0; i < tau.data().size(); ++i) {
    clamped.data()[i] = static_cast<float>(std::clamp(static_cast<double>(tau.data()[i]), 0.0, layer.tau_max));
    ratio.data()[i] = static_cast<float>(std::exp(-clamped.data()[i]));  // Gu Eq. 5.
  }
  if (!layer.refine_scattering || !(layer.layer_albedo > 0)) return ratio;
  // Pixels without a clean signal (outside the view, masked) emit with the median, as in FitTau.
  std::vector<float> positive;
  for (float v : e0.data()) {
    if (v > 0) positive.push_back(v);
  }
  if (positive.empty()) return ratio;
  std::nth_element(positive.begin(), positive.begin() + positive.size() / 2, positive.end());
  const float median = positive[positive.size() / 2];
  Image source = e0;
  for (float& v : source.data()) {
    if (!(v > 0)) v = median;
  }
  const ScatterKernelBank bank = LayerScatterKernelBank(layer, board_distance_m, pixel_pitch_m, w, h);
  const Image scattered = bank.Scattered(source, clamped);  // Gu Eq. 6.
  for (size_t i = 0; i < ratio.data().size(); ++i) ratio.data()[i] += scattered.data()[i] / source.data()[i];
  return ratio;
}

std::vector<ShadowPredictionRegion> CompareShadowPrediction(const Image& predicted, const Image& alternative,
                                                            const Image& measured, const Image& variance,
                                                            const Image& tau, const Image& sigma_tau,
                                                            const std::vector<uint8_t>& valid) {
  std::vector<ShadowPredictionRegion> regions = {
      {"clean", 0, 0.05}, {"thin", 0.05, 0.5}, {"thick", 0.5, 1e30}, {"all", -1e30, 1e30}};
  for (ShadowPredictionRegion& r : regions) {
    double sum_meas2 = 0, sum_err2 = 0, sum_alt2 = 0, sum_var = 0, sum_sigma2 = 0;
    for (size_t i = 0; i < predicted.data().size(); ++i) {
      const double t = tau.data()[i];
      if (valid[i] == 0 || t < r.tau_min || t >= r.tau_max) continue;
      const double meas = measured.data()[i], pred = predicted.data()[i];
      ++r.pixels;
      sum_meas2 += Sqr(meas);
      sum_err2 += Sqr(pred - meas);
      if (!alternative.empty()) sum_alt2 += Sqr(alternative.data()[i] - meas);
      sum_var += std::max(0.0f, variance.data()[i]);
      // d pred / d tau = -pred for the unscattered part, which dominates it.
      sum_sigma2 += Sqr(pred * sigma_tau.data()[i]);
    }
    if (r.pixels == 0 || !(sum_meas2 > 0)) continue;
    r.relative_rms = std::sqrt(sum_err2 / sum_meas2);
    if (!alternative.empty()) r.alternative_relative_rms = std::sqrt(sum_alt2 / sum_meas2);
    r.noise_relative_rms = std::sqrt(sum_var / sum_meas2);
    r.sigma_tau_relative_rms = std::sqrt(sum_sigma2 / sum_meas2);
  }
  return regions;
}

}  // namespace thinslab
