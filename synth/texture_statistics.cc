// SPDX-License-Identifier: Apache-2.0
#include "thinslab/synth/texture_statistics.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "thinslab/core/math.h"

namespace thinslab {
namespace {

std::vector<float> Channel0(const Image& image) {
  std::vector<float> v(image.num_pixels());
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) v[static_cast<size_t>(y) * image.width() + x] = image.at(x, y, 0);
  }
  return v;
}

}  // namespace

double KsDistance(const Image& a, const Image& b) {
  std::vector<float> x = Channel0(a), y = Channel0(b);
  std::sort(x.begin(), x.end());
  std::sort(y.begin(), y.end());
  size_t i = 0, j = 0;
  double d = 0;
  while (i < x.size() && j < y.size()) {
    const float v = std::min(x[i], y[j]);
    while (i < x.size() && x[i] <= v) ++i;
    while (j < y.size() && y[j] <= v) ++j;
    d = std::max(d, std::abs(static_cast<double>(i) / x.size() - static_cast<double>(j) / y.size()));
  }
  return d;
}

double MeanValue(const Image& image) {
  double sum = 0;
  for (float v : Channel0(image)) sum += v;
  return image.num_pixels() > 0 ? sum / image.num_pixels() : 0.0;
}

double ZeroFraction(const Image& image) {
  int64_t zeros = 0;
  for (float v : Channel0(image)) zeros += v == 0.0f;
  return image.num_pixels() > 0 ? static_cast<double>(zeros) / image.num_pixels() : 0.0;
}

double Autocorrelation(const Image& image, int dx, int dy) {
  const double mean = MeanValue(image);
  double var = 0;
  for (float v : Channel0(image)) var += Sqr(v - mean);
  var /= image.num_pixels();
  double cov = 0;
  int64_t n = 0;
  for (int y = 0; y + dy < image.height(); ++y) {
    for (int x = 0; x + dx < image.width(); ++x) {
      cov += (image.at(x, y, 0) - mean) * (image.at(x + dx, y + dy, 0) - mean);
      ++n;
    }
  }
  return n > 0 && var > 0 ? cov / n / var : 0.0;
}

double MaxAutocorrelationDeviation(const Image& a, const Image& b, int max_lag) {
  double worst = 0;
  for (int lag = 1; lag <= max_lag; ++lag) {
    worst = std::max(worst, std::abs(Autocorrelation(a, lag, 0) - Autocorrelation(b, lag, 0)));
    worst = std::max(worst, std::abs(Autocorrelation(a, 0, lag) - Autocorrelation(b, 0, lag)));
  }
  return worst;
}

SeamStatistics SeamRatio(const Image& image, const Image& patch_index) {
  double across = 0, within = 0;
  SeamStatistics s;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      for (int k = 0; k < 2; ++k) {
        const int x2 = x + (k == 0), y2 = y + (k == 1);
        if (x2 >= image.width() || y2 >= image.height()) continue;
        const double d = std::abs(image.at(x, y, 0) - image.at(x2, y2, 0));
        if (patch_index.at(x, y, 0) != patch_index.at(x2, y2, 0)) {
          across += d;
          ++s.neighbours_across;
        } else {
          within += d;
          ++s.neighbours_within;
        }
      }
    }
  }
  if (s.neighbours_across > 0 && s.neighbours_within > 0 && within > 0) {
    s.ratio = (across / s.neighbours_across) / (within / s.neighbours_within);
  }
  return s;
}

}  // namespace thinslab
