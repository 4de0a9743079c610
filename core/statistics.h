// SPDX-License-Identifier: Apache-2.0
// Order statistics of samples (medians, quantiles, robust scatter) for the checks and reports.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace thinslab {

// The q-quantile (0 <= q <= 1) of `values` by the element at floor(q (n - 1)); 0 for none.
// Takes the vector by value: it is reordered.
template <typename T>
double Quantile(std::vector<T> values, double q) {
  if (values.empty()) return 0;
  const size_t k = static_cast<size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return static_cast<double>(values[k]);
}

template <typename T>
double Median(std::vector<T> values) {
  return Quantile(std::move(values), 0.5);
}

// 1.4826 x the median absolute deviation from `center`: the standard deviation of normal samples.
template <typename T>
double RobustSigma(const std::vector<T>& values, double center) {
  std::vector<double> deviations;
  deviations.reserve(values.size());
  for (const T& v : values) deviations.push_back(std::abs(static_cast<double>(v) - center));
  return 1.4826 * Median(std::move(deviations));
}

}  // namespace thinslab
