// SPDX-License-Identifier: Apache-2.0
// The radiometric response of a camera as data, and its file calib/response.json
// (docs/format.md, "Radiometric calibration files").
//
// thinslab stores the *inverse* response: for a black-subtracted raw value z (DN), the
// linearised signal L(z), in the units of a linear camera's DN. L is piecewise linear through
// (knots_dn[j], linear_dn[j]) and normalised so that L(reference_dn) = reference_dn; for a
// linear camera L(z) = z. Dividing L(z) by the exposure gives radiance in linear DN per
// microsecond, the unit every stage uses (docs/conventions.md). Debevec & Malik 1997 solve for
// g(z) = ln L(z) (their Eq. 2); Robertson et al. 2003 for L(z) itself.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

struct CameraResponse {
  std::string method = "linear";  // "linear" (identity), "debevec", "robertson".
  std::string camera_id;          // Camera the response belongs to ("" = any).
  int bit_depth = 0;              // Bit depth of the frames it was recovered from; 0 = any.
  double black_level_dn = 0;      // Camera black level (raw DN) the knots are relative to.
  double saturation_dn = 0;       // Raw saturation level (DN); 0 = unknown.
  // Knots in black-subtracted DN, strictly increasing; empty = identity (linear camera).
  std::vector<double> knots_dn;
  // L at the knots, linear DN, non-decreasing.
  std::vector<double> linear_dn;
  double reference_dn = 0;  // L(reference_dn) = reference_dn.
  // Diagnostics of the recovery (written to the file, not needed to apply the response).
  int num_samples = 0;
  std::vector<double> exposures_us;
  double smoothness_lambda = 0;
  double rms_log_residual = 0;  // RMS of the weighted fit residual in ln units.
  int iterations = 0;           // Robertson iterations.

  bool IsIdentity() const { return knots_dn.empty(); }
  // L(z): piecewise linear between knots; beyond the end knots, continued with the end
  // segments' slopes (values under black, values at saturation).
  double Linearize(double z_dn) const;
  // dL/dz at z (slope of the segment holding z).
  double Slope(double z_dn) const;
  // Consistency: sizes, ordering, finiteness. Errors name the field.
  Status Validate() const;
};

// response.json as text, and back. Readers refuse a wrong "format", an unsupported major
// version and any violated constraint, naming the file and field.
std::string ResponseToJson(const CameraResponse& response);
Status ResponseFromJson(const std::string& text, const std::string& path_for_errors, CameraResponse* response);
// Atomic. `provenance_json`: a JSON object written as the file's "provenance" (readers ignore
// it); "" for none.
Status WriteResponse(const std::string& path, const CameraResponse& response, const std::string& provenance_json = "");
Status ReadResponse(const std::string& path, CameraResponse* response);

}  // namespace thinslab
