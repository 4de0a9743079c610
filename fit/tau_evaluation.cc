// SPDX-License-Identifier: Apache-2.0
#include "fit/tau_evaluation.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace thinslab {
namespace {

TauAccuracy Accuracy(const Image& maps, int channel, const Image& truth, double min_tau, double max_tau) {
  const int status = maps.ChannelIndex("status");
  double sum_sq_err = 0, sum_sq_true = 0, sum_err = 0, sum_true = 0;
  TauAccuracy acc;
  for (int y = 0; y < maps.height(); ++y) {
    for (int x = 0; x < maps.width(); ++x) {
      const double t = truth.at(x, y);
      if (t < min_tau || t > max_tau || maps.at(x, y, status) != 0) continue;
      const double e = maps.at(x, y, channel) - t;
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
  }
  return acc;
}

nlohmann::json ToJsonObject(const TauAccuracy& a) {
  return {{"pixels", a.pixels}, {"rms_relative", a.rms_relative}, {"mean_relative_bias", a.mean_relative_bias},
          {"max_abs_error", a.max_abs_error}};
}

}  // namespace

std::string TauComparison::ToJson() const {
  nlohmann::json j;
  j["tau_range"] = {min_tau, max_tau};
  j["refined"] = ToJsonObject(refined);
  j["plain_eq7"] = ToJsonObject(plain);
  return j.dump(2) + "\n";
}

Status CompareTauWithTruth(const Image& maps, const Image& truth, double min_tau, double max_tau,
                           TauComparison* comparison) {
  const int tau = maps.ChannelIndex("tau"), plain = maps.ChannelIndex("tau_plain");
  if (tau < 0 || plain < 0 || maps.ChannelIndex("status") < 0) {
    return Status::Error("tau map lacks one of the channels tau, tau_plain, status");
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
  comparison->refined = Accuracy(maps, tau, t, min_tau, max_tau);
  comparison->plain = Accuracy(maps, plain, t, min_tau, max_tau);
  return Status::Ok();
}

}  // namespace thinslab
