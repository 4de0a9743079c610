// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/response_io.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "thinslab/core/file.h"

namespace thinslab {

namespace {

// Index j of the segment [knots[j], knots[j+1]] used for z (end segments extend outwards).
size_t Segment(const std::vector<double>& knots, double z) {
  const auto it = std::upper_bound(knots.begin(), knots.end(), z);
  size_t j = it == knots.begin() ? 0 : static_cast<size_t>(it - knots.begin()) - 1;
  return std::min(j, knots.size() - 2);
}

}  // namespace

double CameraResponse::Linearize(double z_dn) const {
  if (knots_dn.size() < 2) return z_dn;
  const size_t j = Segment(knots_dn, z_dn);
  const double a = (z_dn - knots_dn[j]) / (knots_dn[j + 1] - knots_dn[j]);
  return linear_dn[j] + a * (linear_dn[j + 1] - linear_dn[j]);
}

double CameraResponse::Slope(double z_dn) const {
  if (knots_dn.size() < 2) return 1.0;
  const size_t j = Segment(knots_dn, z_dn);
  return (linear_dn[j + 1] - linear_dn[j]) / (knots_dn[j + 1] - knots_dn[j]);
}

Status CameraResponse::Validate() const {
  std::ostringstream msg;
  if (method != "linear" && method != "debevec" && method != "robertson") {
    msg << "method: expected \"linear\", \"debevec\" or \"robertson\", got \"" << method << "\"";
  } else if (knots_dn.size() != linear_dn.size()) {
    msg << "linear_dn: has " << linear_dn.size() << " values, knots_dn has " << knots_dn.size();
  } else if (knots_dn.size() == 1) {
    msg << "knots_dn: needs 0 (identity) or at least 2 knots, got 1";
  } else if (!(black_level_dn >= 0) || !std::isfinite(black_level_dn)) {
    msg << "black_level_dn: must be >= 0, got " << black_level_dn;
  } else if (!(saturation_dn >= 0) || !std::isfinite(saturation_dn)) {
    msg << "saturation_dn: must be >= 0, got " << saturation_dn;
  } else if (bit_depth != 0 && bit_depth != 8 && bit_depth != 10 && bit_depth != 12 && bit_depth != 14 &&
             bit_depth != 16 && bit_depth != 32) {
    msg << "bit_depth: expected 0, 8, 10, 12, 14, 16 or 32, got " << bit_depth;
  } else {
    for (size_t j = 0; j < knots_dn.size(); ++j) {
      if (!std::isfinite(knots_dn[j]) || !std::isfinite(linear_dn[j])) {
        msg << "knots_dn/linear_dn[" << j << "]: not finite";
        break;
      }
      if (j > 0 && !(knots_dn[j] > knots_dn[j - 1])) {
        msg << "knots_dn[" << j << "]: must be > knots_dn[" << j - 1 << "] (" << knots_dn[j - 1] << "), got "
            << knots_dn[j];
        break;
      }
      if (j > 0 && linear_dn[j] < linear_dn[j - 1]) {
        msg << "linear_dn[" << j << "]: the response must be non-decreasing, got " << linear_dn[j] << " < "
            << linear_dn[j - 1];
        break;
      }
    }
    if (msg.str().empty()) {
      if (!knots_dn.empty() && !(linear_dn.back() > linear_dn.front())) {
        msg << "linear_dn: constant response (" << linear_dn.front() << "), cannot linearise";
      } else {
        return Status::Ok();
      }
    }
  }
  return Status::Error(msg.str());
}

std::string ResponseToJson(const CameraResponse& r) {
  nlohmann::ordered_json j;
  j["format"] = "thinslab-response";
  j["format_version"] = "1.0";
  j["method"] = r.method;
  j["camera"] = r.camera_id;
  j["bit_depth"] = r.bit_depth;
  j["black_level_dn"] = r.black_level_dn;
  j["saturation_dn"] = r.saturation_dn;
  j["reference_dn"] = r.reference_dn;
  j["knots_dn"] = r.knots_dn;
  j["linear_dn"] = r.linear_dn;
  j["num_samples"] = r.num_samples;
  j["exposures_us"] = r.exposures_us;
  j["smoothness_lambda"] = r.smoothness_lambda;
  j["rms_log_residual"] = r.rms_log_residual;
  j["iterations"] = r.iterations;
  return j.dump(1) + "\n";
}

Status ResponseFromJson(const std::string& text, const std::string& path, CameraResponse* out) {
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return Status::Error(path + ": not valid JSON");
  if (!j.is_object()) return Status::Error(path + ": top level is not an object");
  auto err = [&](const std::string& field, const std::string& what) { return Status::Error(path + ": " + field + ": " + what); };
  if (!j.contains("format") || j["format"] != "thinslab-response") {
    return err("format", "expected \"thinslab-response\"");
  }
  if (!j.contains("format_version") || !j["format_version"].is_string()) return err("format_version", "missing or not a string");
  const std::string version = j["format_version"];
  if (version.rfind("1.", 0) != 0) {
    return err("format_version", version + " is not supported by this reader (supports 1.x)");
  }
  CameraResponse r;
  auto number = [&](const char* field, double* value, bool required) -> Status {
    if (!j.contains(field) || j[field].is_null()) {
      return required ? err(field, "missing") : Status::Ok();
    }
    if (!j[field].is_number()) return err(field, "expected a number");
    *value = j[field].get<double>();
    if (!std::isfinite(*value)) return err(field, "not finite");
    return Status::Ok();
  };
  auto array = [&](const char* field, std::vector<double>* values) -> Status {
    if (!j.contains(field) || j[field].is_null()) return Status::Ok();
    if (!j[field].is_array()) return err(field, "expected an array of numbers");
    for (size_t i = 0; i < j[field].size(); ++i) {
      if (!j[field][i].is_number()) return err(std::string(field) + "[" + std::to_string(i) + "]", "expected a number");
      values->push_back(j[field][i].get<double>());
    }
    return Status::Ok();
  };
  if (!j.contains("method") || !j["method"].is_string()) return err("method", "missing or not a string");
  r.method = j["method"];
  if (j.contains("camera") && j["camera"].is_string()) r.camera_id = j["camera"];
  double bit_depth = 0, num_samples = 0, iterations = 0;
  THINSLAB_RETURN_IF_ERROR(number("bit_depth", &bit_depth, false));
  if (bit_depth != std::floor(bit_depth)) return err("bit_depth", "expected an integer");
  r.bit_depth = static_cast<int>(bit_depth);
  THINSLAB_RETURN_IF_ERROR(number("black_level_dn", &r.black_level_dn, true));
  THINSLAB_RETURN_IF_ERROR(number("saturation_dn", &r.saturation_dn, false));
  THINSLAB_RETURN_IF_ERROR(number("reference_dn", &r.reference_dn, false));
  THINSLAB_RETURN_IF_ERROR(array("knots_dn", &r.knots_dn));
  THINSLAB_RETURN_IF_ERROR(array("linear_dn", &r.linear_dn));
  THINSLAB_RETURN_IF_ERROR(number("num_samples", &num_samples, false));
  THINSLAB_RETURN_IF_ERROR(array("exposures_us", &r.exposures_us));
  THINSLAB_RETURN_IF_ERROR(number("smoothness_lambda", &r.smoothness_lambda, false));
  THINSLAB_RETURN_IF_ERROR(number("rms_log_residual", &r.rms_log_residual, false));
  THINSLAB_RETURN_IF_ERROR(number("iterations", &iterations, false));
  r.num_samples = static_cast<int>(num_samples);
  r.iterations = static_cast<int>(iterations);
  THINSLAB_RETURN_IF_ERROR(r.Validate().WithContext(path));
  *out = r;
  return Status::Ok();
}

Status WriteResponse(const std::string& path, const CameraResponse& response, const std::string& provenance_json) {
  THINSLAB_RETURN_IF_ERROR(response.Validate().WithContext(path));
  if (provenance_json.empty()) return WriteFileAtomically(path, ResponseToJson(response));
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(ResponseToJson(response));
  j["provenance"] = nlohmann::ordered_json::parse(provenance_json);
  return WriteFileAtomically(path, j.dump(1) + "\n");
}

Status ReadResponse(const std::string& path, CameraResponse* response) {
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &text));
  return ResponseFromJson(text, path, response);
}

}  // namespace thinslab
