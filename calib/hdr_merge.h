// SPDX-License-Identifier: Apache-2.0
// HDR merge of an exposure bracket from a linear camera. Each frame k gives the estimate
// DN_k / t_k of the radiance (DN per microsecond) with variance (DN_k / gain + read^2) / t_k^2
// (shot + read noise). The merge is the inverse-variance weighted mean of the unsaturated
// estimates (optimal for a linear sensor, Granados et al. 2010); saturated samples get zero
// weight. Pixels saturated in every frame keep the estimate of the shortest exposure at its
// saturation level (a lower bound) and are flagged.
#pragma once

#include <string>
#include <vector>

#include "core/image.h"
#include "core/status.h"

namespace thinslab {

struct HdrFrame {
  const Image* dn = nullptr;  // Black level already subtracted.
  double exposure_time_us = 0;
};

struct HdrMergeOptions {
  double saturation_dn = 0;   // Raw saturation minus black level: samples at or above are dropped.
  double gain_e_per_dn = 0;   // 0: unknown, shot noise then taken as DN (gain 1).
  double read_noise_dn = 1;   // RMS read noise in DN.

  bool Check(std::string* error) const;
};

struct HdrImage {
  Image radiance;        // DN per microsecond.
  Image variance;        // (DN per microsecond)^2.
  Image all_saturated;   // 1 where every frame saturated.
};

Status MergeExposureBracket(const std::vector<HdrFrame>& frames, const HdrMergeOptions& options, HdrImage* hdr);

}  // namespace thinslab
