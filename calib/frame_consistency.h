// SPDX-License-Identifier: Apache-2.0
// Do two frames of one light state show the same scene? Frames of one state (repeats at one
// exposure, neighbours in an exposure bracket) differ only by noise and by the exposure factor
// t_b / t_a. A sample, board or camera that moved between them changes the image's structure; a
// light source that flickered (or a shutter that did not apply the exposure) changes its
// brightness as a whole. Both are what the operator must know before the sample leaves the rig
// (issue #28), and neither can be seen in one frame.
//
// On the pixels where both frames are well exposed (b / expected_ratio, a's expected value,
// min_signal_sigmas above a's noise; chosen on b, so that a's own noise does not choose them)
// and neither frame is near saturation, the ratio k = b / a is measured per signal level
// (equal-count bins of a; a camera response left unlinearised bends k with the level, a flicker
// does not), and each pixel's residual b - k(level) a is divided by its noise sqrt(var_b +
// k^2 var_a). The variances are per pixel (the caller's: the frame noise model of
// calib/frame_noise.h at the raw level, which includes a display's glow, plus the subtracted
// dark's). A moved scene puts
// many pixels beyond outlier_sigmas; a flicker moves the median k away from the one the
// bracket's other states show.
#pragma once

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct FramePairOptions {
  double min_signal_sigmas = 20;         // Pixels compared: b / expected_ratio above this many sigmas at zero.
  double max_saturation_fraction = 0.9;  // and both below this fraction of saturation.
  double outlier_sigmas = 6;             // A pixel differs when its residual exceeds this many sigmas.
  int level_bins = 8;                    // Equal-count signal bins the ratio is measured in.
  int min_pixels = 100;                  // Fewer compared pixels: nothing is measured.
  bool Check(std::string* error) const;
};

struct FramePairComparison {
  int pixels = 0;               // Pixels compared (0: too few; nothing below is measured).
  double ratio = 0;             // Median of b / a over them (t_b / t_a when nothing changed).
  double ratio_sigma = 0;       // Its standard error (robust scatter / sqrt(pixels)).
  double outlier_fraction = 0;  // Pixels whose residual exceeds outlier_sigmas.
  bool measured() const { return pixels > 0; }
};

// `a`, `b`: linear, dark-subtracted values of the same size (b the longer exposure, or a repeat;
// expected_ratio = t_b / t_a >= 1), `var_a`, `var_b` their per-pixel variances (not finite:
// clipped, left out); `saturation`:
// the level at which a value clips (+inf: never). Errors: sizes differ, options invalid.
Status CompareFramePair(const Image& a, const Image& b, const Image& var_a, const Image& var_b, double expected_ratio,
                        double saturation, const FramePairOptions& options, FramePairComparison* comparison);

}  // namespace thinslab
