// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/exposure_check.h"

#include "thinslab/calib/hdr_merge.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

namespace thinslab {

std::string ExposureCheck::Warning() const {
  std::string text;
  for (size_t k = 0; k < reported_us.size(); ++k) {
    const double r = measured_over_reported[k];
    if (r < 0 || std::abs(r - 1) <= kExposureCheckTolerance) continue;
    char item[160];
    std::snprintf(item, sizeof(item), "%s%g us reported, %.4g us measured (x%.4f)", text.empty() ? "" : "; ",
                  reported_us[k], r * reported_us[k], r);
    text += item;
  }
  if (text.empty()) return "";
  return "the bracket's frames disagree with the exposures the camera reported, relative to the longest (" +
         std::to_string(reported_us.empty() ? 0.0 : reported_us.back()) + " us): " + text +
         ". The camera applies other exposures than it reports (an offset or unreported rounding): the merged "
         "radiance is off by these factors where those frames dominate";
}

bool CombineExposureChecks(const ExposureCheck& other, ExposureCheck* combined) {
  if (combined->reported_us.empty()) {
    *combined = other;
    return true;
  }
  if (combined->reported_us != other.reported_us) return false;
  combined->max_deviation = 0;
  combined->measured = false;
  for (size_t k = 0; k < other.reported_us.size(); ++k) {
    const bool take = other.measured_over_reported[k] > 0 &&
                      (combined->measured_over_reported[k] < 0 || other.pixels[k] > combined->pixels[k]);
    if (take) {
      combined->measured_over_reported[k] = other.measured_over_reported[k];
      combined->pixels[k] = other.pixels[k];
    }
    // The longest exposure is the reference (factor 1, no pixels compared): not a measurement.
    if (k + 1 < other.reported_us.size() && combined->measured_over_reported[k] > 0) {
      combined->measured = true;
      combined->max_deviation = std::max(combined->max_deviation, std::abs(combined->measured_over_reported[k] - 1));
    }
  }
  return true;
}

Status CheckBracketExposures(const std::vector<HdrFrame>& frames, const HdrMergeOptions& options, ExposureCheck* check) {
  *check = ExposureCheck();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (frames.empty()) return Status::Error("CheckBracketExposures: no frames");
  for (const HdrFrame& f : frames) {
    if (f.dn == nullptr || f.dn->empty() || f.dn->num_channels() != 1 || f.dn->width() != frames[0].dn->width() ||
        f.dn->height() != frames[0].dn->height() || !(f.exposure_time_us > 0)) {
      return Status::Error("CheckBracketExposures: frames must be single-channel images of one size with exposures > 0");
    }
  }
  // Per distinct exposure: the mean linear, dark-subtracted signal, and whether any of its
  // frames is at or above 90 % of saturation there.
  const size_t n = frames[0].dn->data().size();
  const double saturation = options.saturation_dn > 0 ? options.saturation_dn : 1e300;
  std::map<double, std::vector<const HdrFrame*>> by_exposure;
  for (const HdrFrame& f : frames) by_exposure[f.exposure_time_us].push_back(&f);
  struct Level {
    std::vector<float> signal;
    std::vector<uint8_t> near_saturation;
  };
  std::vector<Level> levels;
  for (const auto& [t, group] : by_exposure) {
    check->reported_us.push_back(t);
    Level level;
    level.signal.assign(n, 0.0f);
    level.near_saturation.assign(n, 0);
    for (const HdrFrame* f : group) {
      const std::vector<float>& z = f->dn->data();
      for (size_t i = 0; i < n; ++i) {
        const double linear = options.response != nullptr ? options.response->Linearize(z[i]) : z[i];
        const double dark = f->dark_linear_dn != nullptr ? f->dark_linear_dn->data()[i] : 0.0;
        level.signal[i] += static_cast<float>((linear - dark) / group.size());
        level.near_saturation[i] |= z[i] >= 0.9 * saturation;
      }
    }
    levels.push_back(std::move(level));
  }
  const size_t m = levels.size();
  check->measured_over_reported.assign(m, -1.0);
  check->pixels.assign(m, 0);
  check->measured_over_reported[m - 1] = 1.0;
  const double min_linear = options.response != nullptr ? options.response->Linearize(0.02 * saturation)
                                                        : 0.02 * saturation;
  const double min_signal = std::max(kExposureCheckMinSignalSigmas * options.read_noise_dn,
                                     options.saturation_dn > 0 ? min_linear : 0.0);
  // Effective exposure of level b relative to its reported one, chained from the longest.
  double scale_b = 1.0;  // measured / reported of the longer exposure of the pair.
  for (size_t a = m - 1; a-- > 0;) {
    const size_t b = a + 1;
    // Pixels are chosen by the longer frame's signal (expected above min_signal in the shorter
    // one), not by the shorter frame's own: choosing by the noisy x_a keeps the pixels whose
    // noise lifted them over the threshold and biases the median of x_b / x_a low (1-1.5 % on the
    // steep laser lobe, where many pixels sit near the threshold); x_b's noise is smaller by
    // sqrt(t_b / t_a) and independent of x_a.
    const double ratio_reported = check->reported_us[b] / check->reported_us[a];
    std::vector<double> ratios;
    for (size_t i = 0; i < n; ++i) {
      const double xa = levels[a].signal[i], xb = levels[b].signal[i];
      if (levels[a].near_saturation[i] || levels[b].near_saturation[i] || !(xb > min_signal * ratio_reported)) continue;
      if (!(xa > 0)) continue;
      ratios.push_back(xb / xa);
    }
    check->pixels[a] = static_cast<int>(ratios.size());
    if (static_cast<int>(ratios.size()) < kExposureCheckMinPixels || scale_b < 0) {
      scale_b = -1;  // The chain is broken below this exposure.
      continue;
    }
    std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
    const double median = ratios[ratios.size() / 2];  // t_b^eff / t_a^eff.
    const double t_a_eff = scale_b * check->reported_us[b] / median;
    check->measured_over_reported[a] = t_a_eff / check->reported_us[a];
    scale_b = check->measured_over_reported[a];
    check->measured = true;
    check->max_deviation = std::max(check->max_deviation, std::abs(scale_b - 1));
  }
  return Status::Ok();
}

}  // namespace thinslab
