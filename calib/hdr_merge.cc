// SPDX-License-Identifier: Apache-2.0
#include "calib/hdr_merge.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace thinslab {

bool HdrMergeOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(saturation_dn > 0)) {
    msg << "HdrMergeOptions::saturation_dn = " << saturation_dn << ". Violated constraint: > 0";
  } else if (!(gain_e_per_dn >= 0)) {
    msg << "HdrMergeOptions::gain_e_per_dn = " << gain_e_per_dn << ". Violated constraint: >= 0";
  } else if (!(read_noise_dn > 0)) {
    msg << "HdrMergeOptions::read_noise_dn = " << read_noise_dn << ". Violated constraint: > 0";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

Status MergeExposureBracket(const std::vector<HdrFrame>& frames, const HdrMergeOptions& options, HdrImage* hdr) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (frames.empty()) return Status::Error("MergeExposureBracket: no frames");
  const int w = frames[0].dn->width(), h = frames[0].dn->height();
  for (size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].dn->width() != w || frames[k].dn->height() != h) {
      return Status::Error("MergeExposureBracket: frame " + std::to_string(k) + " is " +
                           std::to_string(frames[k].dn->width()) + "x" + std::to_string(frames[k].dn->height()) +
                           ", frame 0 is " + std::to_string(w) + "x" + std::to_string(h));
    }
    if (!(frames[k].exposure_time_us > 0)) {
      return Status::Error("MergeExposureBracket: frame " + std::to_string(k) + " has exposure_time_us <= 0");
    }
  }
  const double gain = options.gain_e_per_dn > 0 ? options.gain_e_per_dn : 1.0;
  const double read_var = options.read_noise_dn * options.read_noise_dn;
  size_t shortest = 0;
  for (size_t k = 1; k < frames.size(); ++k) {
    if (frames[k].exposure_time_us < frames[shortest].exposure_time_us) shortest = k;
  }
  hdr->radiance = Image(w, h);
  hdr->variance = Image(w, h);
  hdr->all_saturated = Image(w, h);
  for (size_t i = 0; i < static_cast<size_t>(w) * h; ++i) {
    double sum_w = 0, sum_wx = 0;
    for (const HdrFrame& frame : frames) {
      const double dn = frame.dn->data()[i];
      if (dn >= options.saturation_dn - 0.5) continue;
      const double t = frame.exposure_time_us;
      // Variance of dn / t; the expected dn is approximated by the measured one (floored at 0).
      const double var = (std::max(dn, 0.0) / gain + read_var) / (t * t);
      sum_w += 1.0 / var;
      sum_wx += (dn / t) / var;
    }
    if (sum_w > 0) {
      hdr->radiance.data()[i] = static_cast<float>(sum_wx / sum_w);
      hdr->variance.data()[i] = static_cast<float>(1.0 / sum_w);
    } else {
      const double t = frames[shortest].exposure_time_us;
      hdr->radiance.data()[i] = static_cast<float>(options.saturation_dn / t);
      hdr->variance.data()[i] = static_cast<float>(std::pow(options.saturation_dn / t, 2));
      hdr->all_saturated.data()[i] = 1;
    }
  }
  return Status::Ok();
}

}  // namespace thinslab
