// SPDX-License-Identifier: Apache-2.0
// Projector flat field for shadow maps (Gu et al. 2007, Sec. 5.1: the shadow is the projector's
// flat illumination attenuated by e^-tau, so the illumination's own non-uniformity must be
// divided out). From the flat frames of a shadow-map session (kind "flat" if present, else the
// clean-glass "reference" frames): dark-subtracted, HDR-merged when bracketed (through the
// camera response), normalised to a median of 1 over the valid pixels and smoothed with a
// Gaussian by normalised convolution (valid pixels only), so board texture and noise do not
// enter the flat. Written as calib/flat_field.exr (docs/format.md).
#pragma once

#include <string>

#include "thinslab/calib/response_io.h"
#include "thinslab/calib/frame_noise.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct FlatFieldOptions {
  double smoothing_sigma_px = 4;  // Gaussian sigma in camera pixels; 0 = no smoothing. [0, 200].
  double min_relative = 0.05;     // Pixels below this fraction of the median are invalid. [0, 1).
  std::string kind;               // Frame kind to use; "" = "flat" if present, else "reference".

  bool Check(std::string* error) const;
};

struct FlatFieldSummary {
  std::string kind;               // Frame kind used.
  int num_frames = 0;
  int num_exposures = 0;
  int num_darks = 0;
  double median_dn_per_us = 0;    // Normalisation: the flat is radiance / this.
  int64_t pixels_valid = 0;
  int64_t pixels_invalid = 0;     // Saturated everywhere, too dark or non-finite.
  double read_noise_dn = 0;
  FrameNoiseModel noise;          // The merge's noise model (calib/frame_noise.h).
  std::string BriefReport() const;
};

// Normalises and smooths an HDR radiance image into a flat field image with channels
// "flat" (unitless, median 1 over valid pixels), "variance" (of flat) and "valid" (1/0).
Status ComputeFlatField(const Image& radiance, const Image& variance, const Image& all_saturated,
                        const FlatFieldOptions& options, Image* flat, FlatFieldSummary* summary);

// Loads, dark-subtracts and merges the flat frames of the first camera of a session and
// computes its flat field. `response` may be nullptr (linear camera).
Status ComputeSessionFlatField(const std::string& session_dir, const Session& session, const CameraResponse* response,
                               const FlatFieldOptions& options, Image* flat, FlatFieldSummary* summary);

}  // namespace thinslab
