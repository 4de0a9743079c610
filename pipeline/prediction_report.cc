// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/prediction_report.h"

#include <cmath>
#include <cstdio>

namespace thinslab {

std::vector<ShadowPredictionRegion> CompareShadowWithMaps(const TauFitOptions& layer, const Image& tau_map,
                                                          const RectifiedShadowMaps& data, const Image& e0,
                                                          const Image& prediction_variance, bool use_fitted_frames,
                                                          Image* predicted_shadow) {
  const Image tau = tau_map.Channel(tau_map.ChannelIndex("tau"));
  const Image tau_plain = tau_map.Channel(tau_map.ChannelIndex("tau_eq7"));
  const Image status = tau_map.Channel(tau_map.ChannelIndex("status"));
  const Image sigma_tau = tau_map.Channel(tau_map.ChannelIndex("sigma_tau"));
  const Image& measured = use_fitted_frames ? data.shadow : data.validation_shadow;
  const Image& measured_variance = use_fitted_frames ? data.shadow_variance : data.validation_shadow_variance;
  const Image& measured_saturated = use_fitted_frames ? data.saturated : data.validation_saturated;
  const size_t n = tau.data().size();
  Image source = e0;  // Pixels outside the view emit with the median (PredictShadowRatio).
  for (size_t i = 0; i < n; ++i) {
    if (data.outside.data()[i] > 0) source.data()[i] = 0;
  }
  const Image ratio = PredictShadowRatio(layer, tau, source, data.board_distance_m, data.pixel_pitch_m);
  Image predicted(tau.width(), tau.height()), plain(tau.width(), tau.height()), variance(tau.width(), tau.height());
  std::vector<uint8_t> valid(n, 0);
  for (size_t i = 0; i < n; ++i) {
    const double clean = source.data()[i];
    predicted.data()[i] = static_cast<float>(ratio.data()[i] * clean);
    plain.data()[i] = static_cast<float>(std::exp(-tau_plain.data()[i]) * clean);
    variance.data()[i] = measured_variance.data()[i] + prediction_variance.data()[i];
    valid[i] = status.data()[i] == static_cast<float>(TauPixelStatus::kOk) && clean > 0 &&
               data.outside.data()[i] == 0 && measured_saturated.data()[i] == 0;
  }
  if (predicted_shadow != nullptr) {
    *predicted_shadow = Image(tau.width(), tau.height(), {"predicted", "predicted_plain", "measured", "variance", "valid"});
    for (size_t i = 0; i < n; ++i) {
      const int x = static_cast<int>(i % tau.width()), y = static_cast<int>(i / tau.width());
      predicted_shadow->at(x, y, 0) = predicted.data()[i];
      predicted_shadow->at(x, y, 1) = plain.data()[i];
      predicted_shadow->at(x, y, 2) = measured.data()[i];
      predicted_shadow->at(x, y, 3) = variance.data()[i];
      predicted_shadow->at(x, y, 4) = valid[i];
    }
  }
  return CompareShadowPrediction(predicted, plain, measured, variance, tau, sigma_tau, valid);
}

nlohmann::json ShadowRegionsJson(const std::vector<ShadowPredictionRegion>& regions) {
  nlohmann::json out = nlohmann::json::array();
  auto number = [](double v) { return v >= 0 ? nlohmann::json(v) : nlohmann::json(nullptr); };
  for (const ShadowPredictionRegion& r : regions) {
    nlohmann::json range = r.name == "all" ? nlohmann::json(nullptr)
                                           : nlohmann::json({r.tau_min, r.tau_max < 1e29 ? nlohmann::json(r.tau_max)
                                                                                          : nlohmann::json(nullptr)});
    out.push_back({{"region", r.name},
                   {"tau_range", range},
                   {"pixels", r.pixels},
                   {"relative_rms", number(r.relative_rms)},
                   {"plain_relative_rms", number(r.alternative_relative_rms)},
                   {"noise_relative_rms", number(r.noise_relative_rms)},
                   {"sigma_tau_relative_rms", number(r.sigma_tau_relative_rms)}});
  }
  return out;
}

std::string ShadowRegionsText(const std::vector<ShadowPredictionRegion>& regions) {
  std::string out;
  for (const ShadowPredictionRegion& r : regions) {
    char line[256];
    if (r.pixels == 0) {
      std::snprintf(line, sizeof(line), "  %-5s: no pixel\n", r.name.c_str());
    } else {
      std::snprintf(line, sizeof(line),
                    "  %-5s: relative RMS %.4f (plain Eq. 7 %.4f; noise alone %.4f; sigma_tau claims %.4f) over %lld px\n",
                    r.name.c_str(), r.relative_rms, r.alternative_relative_rms, r.noise_relative_rms,
                    r.sigma_tau_relative_rms, static_cast<long long>(r.pixels));
    }
    out += line;
  }
  return out;
}

nlohmann::json LobeBandsJson(const LobePrediction& prediction) {
  nlohmann::json bands = nlohmann::json::array();
  for (const LobePredictionBand& b : prediction.bands) {
    bands.push_back({{"theta_range_deg", {b.theta_min_deg, b.theta_max_deg}},
                     {"rings", b.rings},
                     {"relative_rms", b.relative_rms},
                     {"shape_relative_rms", b.shape_relative_rms},
                     {"noise_relative_rms", b.noise_relative_rms}});
  }
  return {{"beam_centre_m", {prediction.beam_centre_m.x(), prediction.beam_centre_m.y()}},
          {"board_distance_m", prediction.board_distance_m},
          {"rings", prediction.rings.size()},
          {"scale_ratio", prediction.scale_ratio},
          {"bands", bands}};
}

std::string LobeBandsText(const LobePrediction& prediction) {
  char head[160];
  std::snprintf(head, sizeof(head), "  %zu rings; the measured lobe's scale / the fit's: %.3f\n",
                prediction.rings.size(), prediction.scale_ratio);
  std::string out = head;
  for (const LobePredictionBand& b : prediction.bands) {
    char line[256];
    std::snprintf(line, sizeof(line),
                  "  theta %2.0f-%2.0f deg: relative RMS %.4f (shape alone %.4f; noise alone %.4f) over %d rings\n",
                  b.theta_min_deg, b.theta_max_deg, b.relative_rms, b.shape_relative_rms, b.noise_relative_rms,
                  b.rings);
    out += line;
  }
  return out;
}

}  // namespace thinslab
