// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/frame_consistency.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>

#include "thinslab/core/statistics.h"

namespace thinslab {

bool FramePairOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(min_signal_sigmas > 0) || !std::isfinite(min_signal_sigmas)) {
    msg << "FramePairOptions::min_signal_sigmas = " << min_signal_sigmas << ": expected > 0";
  } else if (!(max_saturation_fraction > 0 && max_saturation_fraction <= 1)) {
    msg << "FramePairOptions::max_saturation_fraction = " << max_saturation_fraction << ": expected in (0, 1]";
  } else if (!(outlier_sigmas > 0) || !std::isfinite(outlier_sigmas)) {
    msg << "FramePairOptions::outlier_sigmas = " << outlier_sigmas << ": expected > 0";
  } else if (level_bins < 1 || level_bins > 256) {
    msg << "FramePairOptions::level_bins = " << level_bins << ": expected 1..256";
  } else if (min_pixels < 1) {
    msg << "FramePairOptions::min_pixels = " << min_pixels << ": expected >= 1";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

Status CompareFramePair(const Image& a, const Image& b, const Image& var_a, const Image& var_b, double expected_ratio,
                        double saturation, const FramePairOptions& options, FramePairComparison* comparison) {
  *comparison = FramePairComparison();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (a.width() != b.width() || a.height() != b.height() || a.num_channels() != 1 || b.num_channels() != 1 ||
      var_a.data().size() != a.data().size() || var_b.data().size() != b.data().size()) {
    return Status::Error("CompareFramePair: frames of different sizes or channel counts");
  }
  if (!(expected_ratio >= 1) || !std::isfinite(expected_ratio)) {
    return Status::Error("CompareFramePair: expected_ratio must be >= 1 (b the longer exposure)");
  }
  const double clip = options.max_saturation_fraction * saturation;
  std::vector<int> pixels;
  for (size_t i = 0; i < a.data().size(); ++i) {
    const double va = a.data()[i], vb = b.data()[i];
    if (!std::isfinite(va) || !std::isfinite(vb)) continue;
    if (!std::isfinite(var_a.data()[i]) || !std::isfinite(var_b.data()[i])) continue;  // Clipped.
    const double a_sigma = std::sqrt(std::max(static_cast<double>(var_a.data()[i]), 0.0));
    if (vb > options.min_signal_sigmas * a_sigma * expected_ratio && a_sigma > 0 && va > 0 && va < clip && vb < clip) {
      pixels.push_back(static_cast<int>(i));
    }
  }
  if (static_cast<int>(pixels.size()) < options.min_pixels) return Status::Ok();
  // Equal-count bins of a's level, each with its own median ratio.
  std::sort(pixels.begin(), pixels.end(), [&](int i, int j) { return a.data()[i] < a.data()[j]; });
  const int bins = std::min<int>(options.level_bins, static_cast<int>(pixels.size()) / options.min_pixels + 1);
  std::vector<float> all_ratios;
  all_ratios.reserve(pixels.size());
  int64_t outliers = 0;
  for (int bin = 0; bin < bins; ++bin) {
    const size_t begin = pixels.size() * bin / bins, end = pixels.size() * (bin + 1) / bins;
    std::vector<float> ratios;
    for (size_t p = begin; p < end; ++p) ratios.push_back(b.data()[pixels[p]] / a.data()[pixels[p]]);
    all_ratios.insert(all_ratios.end(), ratios.begin(), ratios.end());
    const double k = Median(std::move(ratios));
    for (size_t p = begin; p < end; ++p) {
      const double vb = b.data()[pixels[p]], va = a.data()[pixels[p]];
      const double variance = var_b.data()[pixels[p]] + k * k * var_a.data()[pixels[p]];
      if (std::abs(vb - k * va) > options.outlier_sigmas * std::sqrt(std::max(variance, 1e-30))) ++outliers;
    }
  }
  comparison->pixels = static_cast<int>(pixels.size());
  comparison->ratio = Median(all_ratios);
  // The median's standard error: sqrt(pi / 2) times the mean's for normal scatter.
  comparison->ratio_sigma =
      1.2533 * RobustSigma(all_ratios, comparison->ratio) / std::sqrt(static_cast<double>(pixels.size()));
  comparison->outlier_fraction = static_cast<double>(outliers) / static_cast<double>(pixels.size());
  return Status::Ok();
}

}  // namespace thinslab
