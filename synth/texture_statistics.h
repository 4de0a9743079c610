// SPDX-License-Identifier: Apache-2.0
// Statistics that say whether a synthesized texture reproduces its source (used by the
// quilting tests and their measurements, docs/models/contamination_synthesis.md, Sec. 4):
// the value histogram (two-sample Kolmogorov-Smirnov distance, mean, share of exact zeros),
// the normalised autocovariance, and a boundary-error measure of seam visibility.
#pragma once

#include <cstdint>

#include "thinslab/core/image.h"

namespace thinslab {

// Two-sample Kolmogorov-Smirnov statistic sup_v |F_a(v) - F_b(v)| of the channel-0 values.
double KsDistance(const Image& a, const Image& b);

// Mean of channel 0.
double MeanValue(const Image& image);

// Share of channel-0 values that are exactly 0 (clean glass for a tau map).
double ZeroFraction(const Image& image);

// Normalised autocovariance of channel 0 at lag (dx, dy) >= 0: the covariance over pixels
// whose both ends are inside, divided by the variance over the whole image (1 at lag 0).
double Autocorrelation(const Image& image, int dx, int dy);

// Largest |autocorrelation(a) - autocorrelation(b)| over lags 1..max_lag along x and y.
double MaxAutocorrelationDeviation(const Image& a, const Image& b, int max_lag);

// Boundary error (seam visibility): the mean |difference| of 4-neighbours that come from
// different patches (across a seam), divided by the same over 4-neighbours from the same
// patch. `patch_index` is a same-size image of patch ids (QuiltTexture's). A visible seam is
// a jump, so it raises the ratio above 1; an invisible one keeps it near or below 1.
// Returns 0 when either set of neighbours is empty.
struct SeamStatistics {
  double ratio = 0;
  int64_t neighbours_across = 0, neighbours_within = 0;
};
SeamStatistics SeamRatio(const Image& image, const Image& patch_index);

}  // namespace thinslab
