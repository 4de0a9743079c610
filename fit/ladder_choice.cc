// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/ladder_choice.h"

#include <algorithm>
#include <cmath>

namespace thinslab {

int SimplestRungWithinNoise(const std::vector<std::vector<double>>& squared_errors, double significance_sigmas,
                            const std::vector<double>& noise_variances) {
  const int rungs = static_cast<int>(squared_errors.size());
  int best = -1;
  double best_sum = 1e300;
  for (int k = 0; k < rungs; ++k) {
    if (squared_errors[k].empty()) continue;
    double sum = 0;
    for (double e : squared_errors[k]) sum += e;
    if (sum < best_sum) {
      best_sum = sum;
      best = k;
    }
  }
  if (best < 0) return -1;
  const std::vector<double>& reference = squared_errors[best];
  const int m = static_cast<int>(reference.size());
  double noise = 0;
  if (static_cast<int>(noise_variances.size()) == m) {
    for (double v : noise_variances) noise += v;
    noise /= std::max(1, m);
  }
  for (int k = 0; k < rungs; ++k) {
    if (squared_errors[k].empty()) continue;
    if (k == best) return k;
    if (static_cast<int>(squared_errors[k].size()) != m) continue;  // Not paired: cannot compare.
    double mean = 0;
    for (int j = 0; j < m; ++j) mean += squared_errors[k][j] - reference[j];
    mean /= m;
    double var = 0;
    for (int j = 0; j < m; ++j) {
      const double d = squared_errors[k][j] - reference[j] - mean;
      var += d * d;
    }
    const double standard_error = m > 1 ? std::sqrt(var / (m - 1) / m) : 0;
    if (mean <= noise + significance_sigmas * standard_error) return k;
  }
  return best;
}

}  // namespace thinslab
