// SPDX-License-Identifier: Apache-2.0
// Does the camera apply the exposures it reports? Not in Debevec & Malik, whose merge (and
// response recovery) trusts the exposure times. Some cameras integrate longer than they report
// (a fixed reset or frame-transfer time), or round a request without reporting the rounding;
// the merge then scales each exposure's estimates by a different wrong factor, which shows as
// steps in the merged radiance at the pixels where the weight moves from one frame to the next.
//
// Measured from the bracket itself: for each pair of neighbouring exposures t_a < t_b, the
// median over pixels well exposed in both (linearised and dark-subtracted signal of frame b
// above t_b / t_a times kExposureCheckMinSignalSigmas read-noise sigmas and 2 % of full scale,
// so that frame a is expected above those; below 90 % of saturation in both) of x_b / x_a
// estimates t_b^eff / t_a^eff. The pixels are chosen on frame b, not on frame a's own noisier
// signal, which would keep the pixels its noise lifted over the threshold and bias the ratio. Chained down from the longest
// exposure (taken as right: a fixed offset matters least there), it gives each exposure's
// measured / reported ratio.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

struct HdrFrame;         // calib/hdr_merge.h, which includes this header for SessionMergeInfo.
struct HdrMergeOptions;

inline constexpr double kExposureCheckMinSignalSigmas = 50;
inline constexpr int kExposureCheckMinPixels = 100;
// A measured/reported ratio further than this from 1 is reported as a warning. 1 %: the median
// of >= 100 ratios of signals above 50 sigma is good to ~0.2 % (noise bias and scatter).
inline constexpr double kExposureCheckTolerance = 0.01;

struct ExposureCheck {
  std::vector<double> reported_us;             // Distinct reported exposures, ascending.
  std::vector<double> measured_over_reported;  // Per exposure; 1 for the longest; -1 = not measured.
  std::vector<int> pixels;                     // Pixels compared with the next longer exposure (0 for the longest).
  double max_deviation = 0;                    // Largest |ratio - 1| over measured exposures.
  bool measured = false;                       // At least one pair had enough pixels.

  // "" when every measured ratio is within kExposureCheckTolerance; else a message naming the
  // exposures and their measured/reported ratios.
  std::string Warning() const;
};

// Brackets of the same reported exposures (the dots of a scan): per exposure, the measured factor
// of whichever check compared more pixels for it. `combined` empty takes `other`; a check of other
// exposures is refused (false, `combined` unchanged).
bool CombineExposureChecks(const ExposureCheck& other, ExposureCheck* combined);

// `frames` and `options` as for MergeExposureBracket (response, saturation, read noise, darks).
// Frames of equal exposure are averaged. Errors as MergeExposureBracket's frame checks.
Status CheckBracketExposures(const std::vector<HdrFrame>& frames, const HdrMergeOptions& options, ExposureCheck* check);

}  // namespace thinslab
