// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/sensor_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace thinslab {

bool SimSensorOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(full_well_e > 0)) {
    msg << "SimSensorOptions::full_well_e = " << full_well_e << ". Violated constraint: > 0";
  } else if (!(read_noise_e >= 0)) {
    msg << "SimSensorOptions::read_noise_e = " << read_noise_e << ". Violated constraint: >= 0";
  } else if (bit_depth < 8 || bit_depth > 16) {
    msg << "SimSensorOptions::bit_depth = " << bit_depth << ". Violated constraint: 8..16";
  } else if (!(response_gamma > 0 && response_gamma < 10)) {
    msg << "SimSensorOptions::response_gamma = " << response_gamma << ". Violated constraint: (0, 10)";
  } else if (!(black_level_dn >= 0 && black_level_dn < (1 << bit_depth) / 2)) {
    msg << "SimSensorOptions::black_level_dn = " << black_level_dn << ". Violated constraint: [0, 2^bit_depth / 2)";
  } else if (!(exposure_step_us > 0 && std::isfinite(exposure_step_us))) {
    msg << "SimSensorOptions::exposure_step_us = " << exposure_step_us << ". Violated constraint: > 0";
  } else if (!(value_scale > 0 && value_scale < 1e30)) {
    msg << "SimSensorOptions::value_scale = " << value_scale << ". Violated constraint: (0, 1e30)";
  } else if (!std::isfinite(exposure_offset_us) || !(exposure_offset_us > -exposure_step_us)) {
    msg << "SimSensorOptions::exposure_offset_us = " << exposure_offset_us
        << ". Violated constraint: finite and > -exposure_step_us";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

double SimSensorOptions::AppliedExposureUs(double requested_us) const {
  return exposure_step_us * std::max(1.0, std::round(requested_us / exposure_step_us));
}

namespace {

double GammaCurve(double s, double gamma) {
  constexpr double kOffset = 0.01;  // Keeps the slope at 0 finite (like Rec. 709's linear toe).
  const double p = 1.0 / gamma;
  const double lo = std::pow(kOffset, p), hi = std::pow(1.0 + kOffset, p);
  return (std::pow(s + kOffset, p) - lo) / (hi - lo);
}

double CurveOnUnitInterval(SimResponseCurve curve, double gamma, double s) {
  switch (curve) {
    case SimResponseCurve::kLinear:
      return s;
    case SimResponseCurve::kGamma:
      return GammaCurve(s, gamma);
    case SimResponseCurve::kSCurve: {
      const double g = GammaCurve(s, gamma);
      return 0.5 * (g + g * g * (3.0 - 2.0 * g));
    }
  }
  return s;
}

}  // namespace

double SimSensorOptions::ResponseCurve(double s) const {
  if (response == SimResponseCurve::kLinear) return s;
  if (s >= 0) return CurveOnUnitInterval(response, response_gamma, std::min(s, 1.0)) + std::max(s - 1.0, 0.0);
  const double h = 1e-6;
  const double slope0 = CurveOnUnitInterval(response, response_gamma, h) / h;
  return slope0 * s;
}

double SimSensorOptions::InverseResponseCurve(double v) const {
  if (response == SimResponseCurve::kLinear) return v;
  if (v <= 0) {
    const double h = 1e-6;
    return v / (CurveOnUnitInterval(response, response_gamma, h) / h);
  }
  if (v >= 1) return 1.0 + (v - 1.0);
  double lo = 0, hi = 1;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (CurveOnUnitInterval(response, response_gamma, mid) < v ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

void SimSensorOptions::DescribeCamera(CameraInfo* camera, bool declare_gain) const {
  if (linear_float_frames) {
    camera->bit_depth = 32;
    camera->frame_values = "linear";
    camera->black_level_dn = 0;
    camera->saturation_dn = std::numeric_limits<double>::infinity();
    camera->gain_e_per_dn = 1 / value_scale;
    return;
  }
  camera->bit_depth = bit_depth;
  camera->black_level_dn = black_level_dn;
  camera->saturation_dn = saturation_dn();
  camera->gain_e_per_dn = declare_gain ? gain_e_per_dn() : 0.0;
}

Image ApplySensor(const Image& electrons, const SimSensorOptions& options, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double gain = options.gain_e_per_dn();
  const double max_dn = options.saturation_dn();
  Image raw(electrons.width(), electrons.height());
  for (size_t i = 0; i < raw.data().size(); ++i) {
    double e = std::max(0.0, static_cast<double>(electrons.data()[i]));
    if (options.enable_noise) {
      if (e < 30) {
        e = std::poisson_distribution<int>(e)(rng);
      } else {
        e += std::sqrt(e) * normal(rng);
      }
      e += options.read_noise_e * normal(rng);
    }
    if (options.linear_float_frames) {
      raw.data()[i] = static_cast<float>(e * options.value_scale);
      continue;
    }
    // The response acts on the collected signal (after shot and read noise), as a camera's
    // analogue/digital tone curve does; quantisation follows it.
    const double range_dn = max_dn - options.black_level_dn;
    const double signal_dn = options.response == SimResponseCurve::kLinear
                                 ? e / gain
                                 : range_dn * options.ResponseCurve(e / options.full_well_e);
    const double dn = std::round(signal_dn + options.black_level_dn);
    raw.data()[i] = static_cast<float>(std::clamp(dn, 0.0, max_dn));
  }
  return raw;
}

}  // namespace thinslab
