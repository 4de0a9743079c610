// SPDX-License-Identifier: Apache-2.0
// Simulated exposure brackets for radiometric calibration: a static radiance scene spanning
// several decades, rendered through the sensor model (shot and read noise, optional nonlinear
// response curve, quantisation, saturation) at a list of exposures, optionally with ambient
// light that the dark frames also see. Used by the calib tests and by `thinslab sim bracket`.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/sim/sensor_model.h"

namespace thinslab {

struct BracketSimOptions {
  int width_px = 256;
  int height_px = 128;
  // Scene irradiance in photo-electrons per microsecond: a log ramp along x from
  // min to max (each row shifted by a fraction of a decade, so rows differ), times a mild
  // multiplicative texture. The bracket should cover min..max.
  double min_e_per_us = 0.05;
  double max_e_per_us = 500;
  double texture_amplitude = 0.2;  // Relative amplitude of the texture, [0, 1).
  // Extra irradiance present in every frame, dark frames included (ambient light); e-/us.
  double ambient_e_per_us = 0;
  std::vector<double> exposures_us = {30, 120, 480, 1920, 7680};  // Requested; the sensor rounds them.
  int frames_per_exposure = 1;
  int dark_frames_per_exposure = 0;  // Dark frames (scene light off, ambient on) per exposure.
  SimSensorOptions sensor;
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};

// The noise-free scene irradiance (e-/us), without ambient light.
Image MakeBracketScene(const BracketSimOptions& options);

struct SimulatedBracket {
  Image scene_e_per_us;             // MakeBracketScene().
  std::vector<Image> frames;        // Raw DN (black level included), frames_per_exposure per exposure, in order.
  std::vector<double> frame_exposures_us;  // Applied: sensor.AppliedExposureUs(requested).
  std::vector<Image> darks;         // Raw DN, dark_frames_per_exposure per exposure.
  std::vector<double> dark_exposures_us;
};

Status SimulateBracket(const BracketSimOptions& options, SimulatedBracket* bracket);

// Writes the bracket as a capture session of kind "exposure_bracket": frames of kind
// "bracket" (light.projector_pattern "flat") and "dark" (projector off), camera "cam0" with the
// sensor's bit depth, black level, saturation and gain; plus ground_truth/scene.exr (channel
// "Y", e-/us) and ground_truth/response.json-like truth in ground_truth/truth.json.
Status SynthesizeBracketSession(const BracketSimOptions& options, const std::string& session_dir);

}  // namespace thinslab
