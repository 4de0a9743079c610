// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/exposure_bracket.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace thinslab {

bool ExposureBracketOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (exposures_us.empty()) {
    if (!(min_exposure_us > 0)) {
      msg << "ExposureBracketOptions::min_exposure_us = " << min_exposure_us << ". Violated constraint: > 0";
    } else if (!(max_exposure_us >= min_exposure_us)) {
      msg << "ExposureBracketOptions::max_exposure_us = " << max_exposure_us
          << ". Violated constraint: >= min_exposure_us (" << min_exposure_us << ")";
    } else if (steps < 1 || steps > 64) {
      msg << "ExposureBracketOptions::steps = " << steps << ". Violated constraint: in [1, 64]";
    }
  } else {
    for (double t : exposures_us) {
      if (!(t > 0) || !std::isfinite(t)) {
        msg << "ExposureBracketOptions::exposures_us contains " << t << ". Violated constraint: > 0";
        break;
      }
    }
  }
  if (msg.str().empty()) {
    if (!(refresh_period_s >= 0) || !std::isfinite(refresh_period_s)) {
      msg << "ExposureBracketOptions::refresh_period_s = " << refresh_period_s << ". Violated constraint: >= 0";
    } else if (!(max_refresh_mismatch > 0 && max_refresh_mismatch < 0.5)) {
      msg << "ExposureBracketOptions::max_refresh_mismatch = " << max_refresh_mismatch
          << ". Violated constraint: in (0, 0.5)";
    }
  }
  if (msg.str().empty()) return true;
  *error = msg.str();
  return false;
}

double ExposureAsRefreshMultipleUs(double requested_us, double refresh_period_s) {
  if (!(refresh_period_s > 0)) return requested_us;
  const double period_us = refresh_period_s * 1e6;
  return std::max(1.0, std::round(requested_us / period_us)) * period_us;
}

ExposureBracketOptions WithDisplayRefresh(ExposureBracketOptions options, double display_refresh_period_s) {
  if (!(options.refresh_period_s > 0)) options.refresh_period_s = display_refresh_period_s;
  return options;
}

std::vector<double> PlanExposureBracket(const ExposureBracketOptions& options) {
  std::vector<double> planned = options.exposures_us;
  if (planned.empty()) {
    for (int i = 0; i < options.steps; ++i) {
      const double f = options.steps == 1 ? 0.0 : static_cast<double>(i) / (options.steps - 1);
      planned.push_back(options.min_exposure_us * std::pow(options.max_exposure_us / options.min_exposure_us, f));
    }
  }
  for (double& t : planned) t = ExposureAsRefreshMultipleUs(t, options.refresh_period_s);
  std::sort(planned.begin(), planned.end());
  // Rounding to refresh multiples can merge neighbours; equal exposures add nothing to a bracket.
  planned.erase(std::unique(planned.begin(), planned.end(),
                            [](double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(a, b); }),
                planned.end());
  return planned;
}

Status ApplyBracketExposure(Camera* camera, double requested_us, const ExposureBracketOptions& options,
                            double* applied_us) {
  const double target_us = ExposureAsRefreshMultipleUs(requested_us, options.refresh_period_s);
  THINSLAB_RETURN_IF_ERROR(camera->SetExposure(target_us, applied_us));
  if (!(*applied_us > 0) || !std::isfinite(*applied_us)) {
    return Status::Error("camera '" + camera->info().id + "': reports an applied exposure of " +
                         std::to_string(*applied_us) + " us after a request of " + std::to_string(target_us) + " us");
  }
  if (options.refresh_period_s > 0) {
    const double period_us = options.refresh_period_s * 1e6;
    const double periods = *applied_us / period_us;
    const double mismatch = std::abs(periods - std::round(periods));
    if (std::round(periods) < 1 || mismatch > options.max_refresh_mismatch) {
      std::ostringstream msg;
      msg << "camera '" << camera->info().id << "': applied exposure " << *applied_us << " us is "
          << periods << " display refresh periods (" << period_us << " us each); requested " << target_us
          << " us, a whole multiple. Mismatch " << mismatch << " periods > ExposureBracketOptions::max_refresh_mismatch "
          << options.max_refresh_mismatch;
      return Status::Error(msg.str());
    }
  }
  return Status::Ok();
}

Status ParseExposureList(const std::string& text, const std::string& option, std::vector<double>* exposures_us) {
  exposures_us->clear();
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ',')) {
    char* end = nullptr;
    const double t = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !(t > 0) || !std::isfinite(t)) {
      return Status::Error("option --" + option + ": '" + item + "' is not a positive number of microseconds");
    }
    exposures_us->push_back(t);
  }
  if (exposures_us->empty()) return Status::Error("option --" + option + ": empty list");
  return Status::Ok();
}

}  // namespace thinslab
