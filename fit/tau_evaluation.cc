// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/tau_evaluation.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

namespace thinslab {
namespace {

TauAccuracy Accuracy(const Image& maps, int channel, int sigma_channel, const Image& truth, double min_tau,
                     double max_tau) {
  const int status = maps.ChannelIndex("status");
  double sum_sq_err = 0, sum_sq_true = 0, sum_err = 0, sum_true = 0;
  int64_t in_view = 0, within_1 = 0, within_2 = 0;
  TauAccuracy acc;
  for (int y = 0; y < maps.height(); ++y) {
    for (int x = 0; x < maps.width(); ++x) {
      const double t = truth.at(x, y);
      if (t < min_tau || t > max_tau || maps.at(x, y, status) == 3) continue;
      ++in_view;
      if (maps.at(x, y, status) != 0) continue;
      const double e = maps.at(x, y, channel) - t;
      if (sigma_channel >= 0) {
        const double sigma = maps.at(x, y, sigma_channel);
        within_1 += std::abs(e) <= sigma;
        within_2 += std::abs(e) <= 2 * sigma;
      }
      sum_sq_err += e * e;
      sum_sq_true += t * t;
      sum_err += e;
      sum_true += t;
      acc.max_abs_error = std::max(acc.max_abs_error, std::abs(e));
      ++acc.pixels;
    }
  }
  if (acc.pixels > 0) {
    acc.rms_relative = std::sqrt(sum_sq_err / sum_sq_true);
    acc.mean_relative_bias = sum_err / sum_true;
    if (sigma_channel >= 0) {
      acc.within_1_sigma = static_cast<double>(within_1) / acc.pixels;
      acc.within_2_sigma = static_cast<double>(within_2) / acc.pixels;
    }
  }
  acc.ok_fraction = in_view > 0 ? static_cast<double>(acc.pixels) / in_view : 0;
  return acc;
}

nlohmann::json ToJsonObject(const TauAccuracy& a) {
  nlohmann::json j = {{"pixels", a.pixels}, {"rms_relative", a.rms_relative},
                      {"mean_relative_bias", a.mean_relative_bias}, {"max_abs_error", a.max_abs_error},
                      {"ok_fraction", a.ok_fraction}};
  if (a.within_1_sigma >= 0) {
    j["within_1_sigma"] = a.within_1_sigma;
    j["within_2_sigma"] = a.within_2_sigma;
  }
  return j;
}

}  // namespace

std::string TauComparison::ToJson() const {
  nlohmann::json j;
  j["tau_range"] = {min_tau, max_tau};
  j["refined"] = ToJsonObject(refined);
  j["plain_eq7"] = ToJsonObject(plain);
  return j.dump(2) + "\n";
}

std::string SplitHalfConsistency::ToJson() const {
  nlohmann::json j = {{"pixels", pixels},       {"rms_z", rms_z}, {"within_1_sigma", within_1},
                      {"within_2_sigma", within_2}, {"rms_difference", rms_difference},
                      {"shared_reference", shared_reference}};
  return j.dump();
}

SplitHalfConsistency CompareSplitHalves(const Image& tau_a, const Image& noise_a, const Image& tau_b,
                                        const Image& noise_b) {
  SplitHalfConsistency c;
  const int status_a = tau_a.ChannelIndex("status"), status_b = tau_b.ChannelIndex("status");
  double sum_z2 = 0, sum_d2 = 0;
  int64_t within_1 = 0, within_2 = 0;
  for (int y = 0; y < tau_a.height(); ++y) {
    for (int x = 0; x < tau_a.width(); ++x) {
      if (tau_a.at(x, y, status_a) != 0 || tau_b.at(x, y, status_b) != 0) continue;
      const double sigma = std::hypot(noise_a.at(x, y), noise_b.at(x, y));
      if (!(sigma > 0)) continue;
      const double d = tau_a.at(x, y, 0) - tau_b.at(x, y, 0);
      const double z = d / sigma;
      sum_z2 += z * z;
      sum_d2 += d * d;
      within_1 += std::abs(z) <= 1;
      within_2 += std::abs(z) <= 2;
      ++c.pixels;
    }
  }
  if (c.pixels > 0) {
    c.rms_z = std::sqrt(sum_z2 / c.pixels);
    c.rms_difference = std::sqrt(sum_d2 / c.pixels);
    c.within_1 = static_cast<double>(within_1) / c.pixels;
    c.within_2 = static_cast<double>(within_2) / c.pixels;
  }
  return c;
}

Status CompareTauWithTruth(const Image& maps, const Image& truth, double min_tau, double max_tau,
                           TauComparison* comparison) {
  const int tau = maps.ChannelIndex("tau"), plain = maps.ChannelIndex("tau_eq7");
  if (tau < 0 || plain < 0 || maps.ChannelIndex("status") < 0) {
    return Status::Error("tau map lacks one of the channels tau, tau_eq7, status");
  }
  const int truth_channel = truth.ChannelIndex("tau");
  if (truth_channel < 0) return Status::Error("ground truth lacks channel 'tau'");
  if (truth.width() != maps.width() || truth.height() != maps.height()) {
    return Status::Error("ground truth is " + std::to_string(truth.width()) + "x" + std::to_string(truth.height()) +
                         " but the tau map is " + std::to_string(maps.width()) + "x" + std::to_string(maps.height()));
  }
  const Image t = truth.Channel(truth_channel);
  comparison->min_tau = min_tau;
  comparison->max_tau = max_tau;
  comparison->refined = Accuracy(maps, tau, maps.ChannelIndex("sigma_tau"), t, min_tau, max_tau);
  comparison->plain = Accuracy(maps, plain, -1, t, min_tau, max_tau);
  return Status::Ok();
}

}  // namespace thinslab
