// SPDX-License-Identifier: Apache-2.0
// Camera sensor: photo-electrons -> shot noise (Poisson), read noise (Gaussian), conversion
// gain, black level, an optional nonlinear camera response curve, quantisation to bit_depth
// and clipping at full scale (saturation).
#pragma once

#include <cstdint>
#include <random>
#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"

namespace thinslab {

// Shape of the camera response: the map from the (noisy) collected signal, as a fraction s of
// full well, to the fraction v of the DN range above black. kLinear is the default (raw
// sensors); the others stand in for cameras that apply a tone curve, so that radiometric
// calibration (calib/response_recovery) has a known nonlinear curve to recover.
enum class SimResponseCurve {
  kLinear,  // v = s.
  kGamma,   // v = ((s + a)^(1/gamma) - a^(1/gamma)) / ((1 + a)^(1/gamma) - a^(1/gamma)), a = 0.01.
  kSCurve,  // v = (g + S(g)) / 2, g the kGamma curve, S(x) = 3x^2 - 2x^3 (smoothstep).
};

// Largest simulated camera side: larger than any sensor a lab has (issue #22: a 100000 px
// camera allocated 40 GB per frame before failing).
inline constexpr int kMaxSimCameraSidePx = 16384;
// Memory a simulated camera of w x h holds while it renders (radiance, noise and frame
// buffers, about 16 float planes): the figure CheckMemoryNeed compares with the machine.
inline double SimCameraMemoryBytes(int width_px, int height_px) {
  return 16.0 * sizeof(float) * static_cast<double>(width_px) * height_px;
}

struct SimSensorOptions {
  double full_well_e = 30000;  // Electrons at full scale.
  double read_noise_e = 6;     // RMS electrons.
  int bit_depth = 12;
  double black_level_dn = 64;
  bool enable_noise = true;
  SimResponseCurve response = SimResponseCurve::kLinear;
  double response_gamma = 2.2;  // Exponent of kGamma / kSCurve; > 0.
  // Granularity of the exposure control: real sensors expose whole line periods (typically
  // 10-40 us), so the applied exposure is the request rounded to a multiple of this, at least
  // one step. 1 us by default (whole microseconds).
  double exposure_step_us = 1;
  // Not reported: the sensor integrates light this much longer than the exposure it applies and
  // reports (a reset or frame-transfer time; negative: shorter). 0 by default. For testing the
  // exposure check (calib/exposure_check.h).
  double exposure_offset_us = 0;
  // What an HDR tool or a renderer writes instead of a raw sensor's frames (issue #23): each
  // value is the collected electrons (shot and read noise) times value_scale, as a float with
  // no quantisation, clipping or black level, stored as float EXR with frame_values "linear".
  // The simulated camera knows its gain (1 / value_scale e- per value) for display
  // synchronisation; the capture's manifest declares none (OpenSimulatedSession), as such
  // programs do not.
  bool linear_float_frames = false;
  double value_scale = 1;  // Values per electron; > 0.

  // v = f(s) for the configured curve: f(0) = 0, f(1) = 1, strictly increasing on [0, 1],
  // continued linearly below 0 (noise under black) with the slope at 0.
  double ResponseCurve(double s) const;
  // s = f^-1(v), by bisection on [0, 1] (linear continuation outside).
  double InverseResponseCurve(double v) const;

  // The exposure the sensor applies for a request: round(requested / step) steps, at least 1.
  double AppliedExposureUs(double requested_us) const;
  // What the light is integrated over: AppliedExposureUs + exposure_offset_us (> 0 required).
  double IntegratedExposureUs(double requested_us) const { return AppliedExposureUs(requested_us) + exposure_offset_us; }

  double gain_e_per_dn() const { return full_well_e / ((1 << bit_depth) - 1 - black_level_dn); }
  // The camera fields this sensor determines: bit depth, black level, saturation, gain and
  // frame values (raw DN, or linear floats). `declare_gain` = false leaves the gain unknown (0)
  // for raw frames, as for a nonlinear response.
  void DescribeCamera(CameraInfo* camera, bool declare_gain = true) const;
  // The sensor's read noise and a change of `dn` raw DN, in the units of its frames.
  double FrameValuesPerDn() const { return linear_float_frames ? value_scale * gain_e_per_dn() : 1.0; }
  double saturation_dn() const { return (1 << bit_depth) - 1; }
  bool Check(std::string* error) const;
};

// Converts an image of expected electrons to raw DN (integers stored as float).
Image ApplySensor(const Image& electrons, const SimSensorOptions& options, uint64_t seed);

}  // namespace thinslab
