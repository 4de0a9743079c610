// SPDX-License-Identifier: Apache-2.0
// Reading, writing and validating capture sessions. docs/format.md is the normative
// description of session.json and of the frame files; keep the two in step.
#include "thinslab/core/session_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>
#include <utility>
#include <vector>

#include "thinslab/core/opencv_error.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/png_io.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
// Writing keeps the field order of docs/format.md, which makes manifests easy to read.
using OrderedJson = nlohmann::ordered_json;

constexpr char kFormatName[] = "thinslab-session";

std::string ManifestPath(const std::string& session_dir) {
  return JoinPath(session_dir, kSessionManifestName);
}

std::string Num(double value) {
  std::ostringstream ss;
  ss << std::setprecision(10) << value;
  return ss.str();
}

std::string Quote(const std::string& s) { return "\"" + s + "\""; }

std::string Child(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

std::string Element(const std::string& path, size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

// "a", "a or b", "a, b or c".
std::string OneOf(const std::vector<std::string>& values) {
  std::string out;
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) out += (i + 1 == values.size()) ? " or " : ", ";
    out += Quote(values[i]);
  }
  return out;
}

bool Contains(const std::vector<std::string>& values, const std::string& v) {
  return std::find(values.begin(), values.end(), v) != values.end();
}

const std::vector<std::string>& FrameStatusNames() {
  static const std::vector<std::string> names = {"ok", "failed", "retried"};
  return names;
}
const std::vector<std::string>& SampleStates() {
  static const std::vector<std::string> names = {"contaminated", "clean", "none"};
  return names;
}
const std::vector<std::string>& AcquisitionStates() {
  static const std::vector<std::string> names = {"running", "complete", "failed", "interrupted"};
  return names;
}
const std::vector<std::string>& ContaminantSides() {
  static const std::vector<std::string> names = {"board", "projector"};
  return names;
}
const std::vector<std::string>& FrameValueKinds() {
  static const std::vector<std::string> names = {"raw", "linear"};
  return names;
}
// A frame's exposure_time_us while parsing, before ReadSession knows its camera.
constexpr double kExposureAbsent = std::numeric_limits<double>::quiet_NaN();
const std::vector<std::string>& ProjectorKinds() {
  static const std::vector<std::string> names = {"collimated", "pinhole"};
  return names;
}
const std::vector<int>& BitDepths() {
  static const std::vector<int> depths = {8, 10, 12, 14, 16, 32};
  return depths;
}
bool IsIntegerDepth(int bit_depth) { return bit_depth >= 1 && bit_depth <= 16; }

// "<major>.<minor>" with decimal digits only.
bool ParseVersion(const std::string& s, int* major, int* minor) {
  const size_t dot = s.find('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == s.size()) return false;
  if (dot > 6 || s.size() - dot - 1 > 6) return false;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i != dot && !std::isdigit(static_cast<unsigned char>(s[i]))) return false;
  }
  *major = std::stoi(s.substr(0, dot));
  *minor = std::stoi(s.substr(dot + 1));
  return true;
}

// Empty if `file` is a relative path that stays inside the session folder, otherwise the
// reason it is not.
std::string CheckRelativeFile(const std::string& file) {
  if (file.empty()) return "must name the frame file, got an empty string";
  const fs::path p(file);
  if (p.is_absolute() || p.has_root_name() || p.has_root_directory()) {
    return "must be relative to the session folder, got the absolute path " + Quote(file);
  }
  for (const auto& part : p) {
    if (part == "..") {
      return "must stay inside the session folder (no \"..\" components), got " + Quote(file);
    }
  }
  return "";
}

// Where a frame's file is, resolved through symlinks; "" and *resolved set when it is a
// readable regular file inside the session folder, else why not. Frames are read by this
// resolved path, so that a symlink pointing out of the capture is refused (issue #22).
std::string ResolveFrameFile(const std::string& session_dir, const std::string& file, std::string* resolved) {
  const std::string relative = CheckRelativeFile(file);
  if (!relative.empty()) return relative;
  const std::string path = JoinPath(session_dir, file);
  const std::string unreadable = UnreadableFileReason(path);
  if (!unreadable.empty()) return "frame file " + Quote(file) + " " + unreadable;
  std::error_code ec;
  const fs::path real = fs::canonical(path, ec);
  const fs::path root = fs::canonical(session_dir, ec);
  if (ec) return "frame file " + Quote(file) + ": cannot resolve its path: " + ec.message();
  auto r = real.begin();
  for (auto s = root.begin(); s != root.end(); ++s, ++r) {
    if (r == real.end() || *r != *s) {
      return "frame file " + Quote(file) + " is a symbolic link to " + Quote(real.string()) +
             ", outside the session folder";
    }
  }
  *resolved = real.string();
  return "";
}

// The projector's light within acos(0.1) = 84.3 degrees of the sample normal.
constexpr double kMinProjectorCosine = 0.1;

std::string Array3Text(const Eigen::Vector3d& v) {
  std::ostringstream out;
  out << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return out.str();
}

// Normalises a quaternion unless it already is unit length to rounding, so that writing
// and reading a session reproduces it bit for bit.
void NormalizeIfNeeded(Eigen::Quaterniond* q) {
  const double norm = q->norm();
  if (norm > 0 && std::abs(norm - 1.0) > 4 * std::numeric_limits<double>::epsilon()) {
    q->normalize();
  }
}
void NormalizeIfNeeded(Eigen::Vector3d* v) {
  const double norm = v->norm();
  if (norm > 0 && std::isfinite(norm) &&
      std::abs(norm - 1.0) > 4 * std::numeric_limits<double>::epsilon()) {
    v->normalize();
  }
}

// ---------------------------------------------------------------------------------------
// Reading.

enum class Need { kRequired, kOptional };

// Typed field access with errors of the form "<file>: <json.path>: <problem>". Optional
// fields that are absent or null leave the output untouched (it holds the default).
class ManifestParser {
 public:
  explicit ManifestParser(std::string file) : file_(std::move(file)) {}

  Status Error(const std::string& path, const std::string& message) const {
    return Status::Error(file_ + ": " + (path.empty() ? "(top level)" : path) + ": " + message);
  }

  Status ExpectedType(const std::string& path, const char* expected, const Json& got) const {
    return Error(path, std::string("expected ") + expected + ", got " + got.type_name());
  }

  // *value is nullptr when an optional field is absent or null.
  Status Find(const Json& object, const std::string& path, const char* key, Need need,
              const Json** value) const {
    *value = nullptr;
    const auto it = object.find(key);
    if (it == object.end() || (it->is_null() && need == Need::kOptional)) {
      if (need == Need::kRequired) return Error(Child(path, key), "required field is missing");
      return Status::Ok();
    }
    *value = &*it;
    return Status::Ok();
  }

  Status Object(const Json& object, const std::string& path, const char* key, Need need,
                const Json** value) const {
    THINSLAB_RETURN_IF_ERROR(Find(object, path, key, need, value));
    if (*value != nullptr && !(*value)->is_object()) {
      return ExpectedType(Child(path, key), "an object", **value);
    }
    return Status::Ok();
  }

  Status Array(const Json& object, const std::string& path, const char* key, Need need,
               const Json** value) const {
    THINSLAB_RETURN_IF_ERROR(Find(object, path, key, need, value));
    if (*value != nullptr && !(*value)->is_array()) {
      return ExpectedType(Child(path, key), "an array", **value);
    }
    return Status::Ok();
  }

  Status String(const Json& object, const std::string& path, const char* key, Need need,
                std::string* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Find(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    if (!v->is_string()) return ExpectedType(Child(path, key), "a string", *v);
    *out = v->get<std::string>();
    return Status::Ok();
  }

  Status Bool(const Json& object, const std::string& path, const char* key, Need need,
              bool* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Find(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    if (!v->is_boolean()) return ExpectedType(Child(path, key), "a boolean", *v);
    *out = v->get<bool>();
    return Status::Ok();
  }

  Status NumberValue(const Json& v, const std::string& path, double* out) const {
    if (!v.is_number()) return ExpectedType(path, "a number", v);
    const double d = v.get<double>();
    if (!std::isfinite(d)) return Error(path, "expected a finite number");
    *out = d;
    return Status::Ok();
  }

  Status Number(const Json& object, const std::string& path, const char* key, Need need,
                double* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Find(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    return NumberValue(*v, Child(path, key), out);
  }

  // Integers; a float with an integral value (640.0) is accepted, 640.5 is not.
  Status Int(const Json& object, const std::string& path, const char* key, Need need,
             int* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Find(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    const std::string field = Child(path, key);
    if (!v->is_number()) return ExpectedType(field, "an integer", *v);
    double d = 0;
    if (v->is_number_unsigned()) {
      d = static_cast<double>(v->get<std::uint64_t>());
    } else if (v->is_number_integer()) {
      d = static_cast<double>(v->get<std::int64_t>());
    } else {
      d = v->get<double>();
      if (!std::isfinite(d) || std::floor(d) != d) {
        return Error(field, "expected an integer, got " + Num(d));
      }
    }
    if (d < std::numeric_limits<int>::min() || d > std::numeric_limits<int>::max()) {
      return Error(field, "integer " + Num(d) + " is out of range");
    }
    *out = static_cast<int>(d);
    return Status::Ok();
  }

  // Non-negative integers below 2^63 (device counters); a float with an integral value is
  // accepted up to 2^53, where doubles stop being exact.
  Status Counter(const Json& object, const std::string& path, const char* key, Need need,
                 std::optional<uint64_t>* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Find(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    const std::string field = Child(path, key);
    constexpr uint64_t kMax = uint64_t(1) << 63;
    if (v->is_number_unsigned()) {
      const uint64_t u = v->get<uint64_t>();
      if (u >= kMax) return Error(field, "integer " + std::to_string(u) + " is out of range (< 2^63)");
      *out = u;
      return Status::Ok();
    }
    if (v->is_number_integer()) {
      return Error(field, "must be >= 0, got " + std::to_string(v->get<std::int64_t>()));
    }
    if (!v->is_number()) return ExpectedType(field, "an integer", *v);
    const double d = v->get<double>();
    if (!std::isfinite(d) || std::floor(d) != d || d < 0 || d > 9007199254740992.0) {
      return Error(field, "expected an integer in [0, 2^53] when written as a float, got " + Num(d));
    }
    *out = static_cast<uint64_t>(d);
    return Status::Ok();
  }

  // A fixed-size array of numbers.
  Status Vector(const Json& object, const std::string& path, const char* key, Need need, int n,
                double* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Array(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    const std::string field = Child(path, key);
    if (static_cast<int>(v->size()) != n) {
      return Error(field, "expected an array of " + std::to_string(n) + " numbers, got " +
                              std::to_string(v->size()) + " elements");
    }
    for (int i = 0; i < n; ++i) {
      THINSLAB_RETURN_IF_ERROR(NumberValue((*v)[i], Element(field, i), &out[i]));
    }
    return Status::Ok();
  }

  Status Vector2(const Json& object, const std::string& path, const char* key, Need need,
                 Eigen::Vector2d* out) const {
    return Vector(object, path, key, need, 2, out->data());
  }
  Status Vector3(const Json& object, const std::string& path, const char* key, Need need,
                 Eigen::Vector3d* out) const {
    return Vector(object, path, key, need, 3, out->data());
  }

  Status NumberArray(const Json& object, const std::string& path, const char* key, Need need,
                     std::vector<double>* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Array(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    const std::string field = Child(path, key);
    std::vector<double> values(v->size());
    for (size_t i = 0; i < v->size(); ++i) {
      THINSLAB_RETURN_IF_ERROR(NumberValue((*v)[i], Element(field, i), &values[i]));
    }
    *out = std::move(values);
    return Status::Ok();
  }

  // {"rotation_wxyz": [w, x, y, z], "translation_m": [x, y, z]}; the quaternion is
  // normalised here, so it must be non-zero.
  Status Rigid(const Json& object, const std::string& path, const char* key, Need need,
               Rigid3d* out) const {
    const Json* v = nullptr;
    THINSLAB_RETURN_IF_ERROR(Object(object, path, key, need, &v));
    if (v == nullptr) return Status::Ok();
    const std::string field = Child(path, key);
    double wxyz[4];
    THINSLAB_RETURN_IF_ERROR(Vector(*v, field, "rotation_wxyz", Need::kRequired, 4, wxyz));
    Eigen::Vector3d t;
    THINSLAB_RETURN_IF_ERROR(Vector3(*v, field, "translation_m", Need::kRequired, &t));
    Eigen::Quaterniond q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
    const double norm = q.norm();
    if (!(norm > 1e-12) || !std::isfinite(norm)) {
      return Error(Child(field, "rotation_wxyz"),
                   "quaternion must be non-zero, got norm " + Num(norm));
    }
    NormalizeIfNeeded(&q);
    out->rotation = q;
    out->translation = t;
    return Status::Ok();
  }

  Status Parse(const Json& root, Session* session) const;
  Status ParseFrame(const Json& j, const std::string& path, FrameRecord* frame) const;

 private:
  Status ParseCamera(const Json& j, const std::string& path, CameraInfo* camera) const;
  Status ParseRig(const Json& j, const std::string& path, RigInfo* rig) const;
  Status ParseAcquisition(const Json& j, const std::string& path, AcquisitionInfo* acquisition) const;

  std::string file_;
};

Status ManifestParser::ParseCamera(const Json& j, const std::string& path,
                                   CameraInfo* camera) const {
  if (!j.is_object()) return ExpectedType(path, "an object", j);
  THINSLAB_RETURN_IF_ERROR(String(j, path, "id", Need::kRequired, &camera->id));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "model", Need::kRequired, &camera->model));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "serial", Need::kOptional, &camera->serial));
  THINSLAB_RETURN_IF_ERROR(Int(j, path, "width_px", Need::kRequired, &camera->width_px));
  THINSLAB_RETURN_IF_ERROR(Int(j, path, "height_px", Need::kRequired, &camera->height_px));
  THINSLAB_RETURN_IF_ERROR(Number(j, path, "fx_px", Need::kRequired, &camera->fx_px));
  THINSLAB_RETURN_IF_ERROR(Number(j, path, "fy_px", Need::kRequired, &camera->fy_px));
  THINSLAB_RETURN_IF_ERROR(Number(j, path, "cx_px", Need::kRequired, &camera->cx_px));
  THINSLAB_RETURN_IF_ERROR(Number(j, path, "cy_px", Need::kRequired, &camera->cy_px));
  THINSLAB_RETURN_IF_ERROR(
      NumberArray(j, path, "distortion", Need::kOptional, &camera->distortion));
  THINSLAB_RETURN_IF_ERROR(
      Rigid(j, path, "cam_from_sample", Need::kRequired, &camera->cam_from_sample));
  THINSLAB_RETURN_IF_ERROR(Int(j, path, "bit_depth", Need::kRequired, &camera->bit_depth));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "frame_values", Need::kOptional, &camera->frame_values));
  if (!Contains(FrameValueKinds(), camera->frame_values)) {  // Before the fields it makes optional.
    return Error(Child(path, "frame_values"), "must be " + OneOf(FrameValueKinds()) + ", got " + Quote(camera->frame_values));
  }
  THINSLAB_RETURN_IF_ERROR(
      Number(j, path, "black_level_dn", Need::kOptional, &camera->black_level_dn));
  // Linear frames need no saturation level: absent means nothing saturates.
  if (camera->linear_frames()) camera->saturation_dn = std::numeric_limits<double>::infinity();
  THINSLAB_RETURN_IF_ERROR(Number(j, path, "saturation_dn",
                                  camera->linear_frames() ? Need::kOptional : Need::kRequired,
                                  &camera->saturation_dn));
  THINSLAB_RETURN_IF_ERROR(
      Number(j, path, "gain_e_per_dn", Need::kOptional, &camera->gain_e_per_dn));
  double read_noise = 0;
  const Json* read_noise_json = nullptr;
  THINSLAB_RETURN_IF_ERROR(Find(j, path, "read_noise_dn", Need::kOptional, &read_noise_json));
  if (read_noise_json != nullptr) {
    THINSLAB_RETURN_IF_ERROR(NumberValue(*read_noise_json, Child(path, "read_noise_dn"), &read_noise));
    camera->read_noise_dn = read_noise;
  }
  // Optional {"name": number, ...}; absent in manifests written before it existed.
  const Json* stats = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(j, path, "stream_statistics", Need::kOptional, &stats));
  if (stats != nullptr) {
    const std::string stats_path = Child(path, "stream_statistics");
    for (auto it = stats->begin(); it != stats->end(); ++it) {
      double value = 0;
      THINSLAB_RETURN_IF_ERROR(NumberValue(it.value(), Child(stats_path, it.key()), &value));
      camera->stream_statistics[it.key()] = value;
    }
  }
  return Status::Ok();
}

Status ManifestParser::ParseRig(const Json& j, const std::string& path, RigInfo* rig) const {
  const Json* cameras = nullptr;
  THINSLAB_RETURN_IF_ERROR(Array(j, path, "cameras", Need::kRequired, &cameras));
  const std::string cameras_path = Child(path, "cameras");
  rig->cameras.assign(cameras->size(), CameraInfo());
  for (size_t i = 0; i < cameras->size(); ++i) {
    THINSLAB_RETURN_IF_ERROR(
        ParseCamera((*cameras)[i], Element(cameras_path, i), &rig->cameras[i]));
  }

  const Json* sample = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(j, path, "sample", Need::kRequired, &sample));
  const std::string sp = Child(path, "sample");
  SampleInfo& s = rig->sample;
  THINSLAB_RETURN_IF_ERROR(Vector2(*sample, sp, "region_min_m", Need::kRequired, &s.region_min_m));
  THINSLAB_RETURN_IF_ERROR(Vector2(*sample, sp, "region_max_m", Need::kRequired, &s.region_max_m));
  THINSLAB_RETURN_IF_ERROR(Number(*sample, sp, "pixel_pitch_m", Need::kRequired, &s.pixel_pitch_m));
  THINSLAB_RETURN_IF_ERROR(
      Number(*sample, sp, "glass_thickness_m", Need::kOptional, &s.glass_thickness_m));
  THINSLAB_RETURN_IF_ERROR(Number(*sample, sp, "glass_ior", Need::kOptional, &s.glass_ior));
  THINSLAB_RETURN_IF_ERROR(
      String(*sample, sp, "contaminant_side", Need::kOptional, &s.contaminant_side));

  const Json* board = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(j, path, "board", Need::kOptional, &board));
  if (board != nullptr) {
    const std::string bp = Child(path, "board");
    rig->board.present = true;
    THINSLAB_RETURN_IF_ERROR(
        Number(*board, bp, "distance_m", Need::kRequired, &rig->board.distance_m));
    THINSLAB_RETURN_IF_ERROR(Number(*board, bp, "albedo", Need::kRequired, &rig->board.albedo));
  }

  const Json* projector = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(j, path, "projector", Need::kOptional, &projector));
  if (projector != nullptr) {
    const std::string pp = Child(path, "projector");
    ProjectorInfo& p = rig->projector;
    p.present = true;
    THINSLAB_RETURN_IF_ERROR(String(*projector, pp, "kind", Need::kRequired, &p.kind));
    THINSLAB_RETURN_IF_ERROR(
        Vector3(*projector, pp, "direction_in_sample", Need::kRequired, &p.direction_in_sample));
    NormalizeIfNeeded(&p.direction_in_sample);
  }

  const Json* laser = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(j, path, "laser", Need::kOptional, &laser));
  if (laser != nullptr) {
    const std::string lp = Child(path, "laser");
    LaserInfo& l = rig->laser;
    l.present = true;
    THINSLAB_RETURN_IF_ERROR(
        Vector3(*laser, lp, "origin_in_sample", Need::kRequired, &l.origin_in_sample));
    THINSLAB_RETURN_IF_ERROR(
        Vector3(*laser, lp, "direction_in_sample", Need::kRequired, &l.direction_in_sample));
    NormalizeIfNeeded(&l.direction_in_sample);
    THINSLAB_RETURN_IF_ERROR(
        Number(*laser, lp, "beam_radius_m", Need::kRequired, &l.beam_radius_m));
    THINSLAB_RETURN_IF_ERROR(Number(*laser, lp, "wavelength_m", Need::kRequired, &l.wavelength_m));
  }

  const Json* monitor = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(j, path, "monitor", Need::kOptional, &monitor));
  if (monitor != nullptr) {
    const std::string mp = Child(path, "monitor");
    MonitorInfo& m = rig->monitor;
    m.present = true;
    THINSLAB_RETURN_IF_ERROR(
        Rigid(*monitor, mp, "sample_from_monitor", Need::kRequired, &m.sample_from_monitor));
    THINSLAB_RETURN_IF_ERROR(
        Number(*monitor, mp, "pixel_pitch_m", Need::kRequired, &m.pixel_pitch_m));
    THINSLAB_RETURN_IF_ERROR(Int(*monitor, mp, "width_px", Need::kRequired, &m.width_px));
    THINSLAB_RETURN_IF_ERROR(Int(*monitor, mp, "height_px", Need::kRequired, &m.height_px));
    THINSLAB_RETURN_IF_ERROR(Number(*monitor, mp, "dot_radius_px", Need::kOptional, &m.dot_radius_px));
  }
  return Status::Ok();
}

Status ManifestParser::ParseFrame(const Json& j, const std::string& path,
                                  FrameRecord* frame) const {
  if (!j.is_object()) return ExpectedType(path, "an object", j);
  THINSLAB_RETURN_IF_ERROR(Int(j, path, "index", Need::kRequired, &frame->index));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "camera", Need::kRequired, &frame->camera_id));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "kind", Need::kRequired, &frame->kind));
  frame->sample_state = "none";
  THINSLAB_RETURN_IF_ERROR(String(j, path, "sample_state", Need::kOptional, &frame->sample_state));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "file", Need::kRequired, &frame->file));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "variance_file", Need::kOptional, &frame->variance_file));
  // Optional for linear frames (ReadSession gives them 1 us); NaN marks it absent here.
  frame->exposure_time_us = kExposureAbsent;
  THINSLAB_RETURN_IF_ERROR(
      Number(j, path, "exposure_time_us", Need::kOptional, &frame->exposure_time_us));
  THINSLAB_RETURN_IF_ERROR(Number(j, path, "gain_db", Need::kOptional, &frame->gain_db));

  const Json* light = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(j, path, "light", Need::kOptional, &light));
  if (light != nullptr) {
    const std::string lp = Child(path, "light");
    LightState& l = frame->light;
    THINSLAB_RETURN_IF_ERROR(
        String(*light, lp, "projector_pattern", Need::kOptional, &l.projector_pattern));
    THINSLAB_RETURN_IF_ERROR(Bool(*light, lp, "laser_on", Need::kOptional, &l.laser_on));
    const Json* dot = nullptr;
    THINSLAB_RETURN_IF_ERROR(Find(*light, lp, "dot_px", Need::kOptional, &dot));
    if (dot != nullptr) {
      Eigen::Vector2d dot_px;
      THINSLAB_RETURN_IF_ERROR(Vector2(*light, lp, "dot_px", Need::kRequired, &dot_px));
      l.dot_px = dot_px;
    }
    THINSLAB_RETURN_IF_ERROR(Number(*light, lp, "dot_radiance", Need::kOptional, &l.dot_radiance));
  }

  THINSLAB_RETURN_IF_ERROR(
      String(j, path, "timestamp_utc", Need::kRequired, &frame->timestamp_utc));
  THINSLAB_RETURN_IF_ERROR(Counter(j, path, "camera_frame_id", Need::kOptional, &frame->camera_frame_id));
  THINSLAB_RETURN_IF_ERROR(Counter(j, path, "camera_timestamp_ns", Need::kOptional, &frame->camera_timestamp_ns));
  std::string status;
  THINSLAB_RETURN_IF_ERROR(String(j, path, "status", Need::kRequired, &status));
  if (status == "ok") {
    frame->status = FrameStatus::kOk;
  } else if (status == "failed") {
    frame->status = FrameStatus::kFailed;
  } else if (status == "retried") {
    frame->status = FrameStatus::kRetried;
  } else {
    return Error(Child(path, "status"), "unknown value " + Quote(status) + " (expected " +
                                            OneOf(FrameStatusNames()) + ")");
  }
  THINSLAB_RETURN_IF_ERROR(String(j, path, "error", Need::kOptional, &frame->error));
  THINSLAB_RETURN_IF_ERROR(Bool(j, path, "validation", Need::kOptional, &frame->validation));
  return Status::Ok();
}

Status ManifestParser::ParseAcquisition(const Json& j, const std::string& path,
                                        AcquisitionInfo* acquisition) const {
  acquisition->present = true;
  THINSLAB_RETURN_IF_ERROR(String(j, path, "state", Need::kRequired, &acquisition->state));
  THINSLAB_RETURN_IF_ERROR(String(j, path, "plan", Need::kOptional, &acquisition->plan));
  THINSLAB_RETURN_IF_ERROR(Int(j, path, "planned_frames", Need::kOptional, &acquisition->planned_frames));
  THINSLAB_RETURN_IF_ERROR(Int(j, path, "camera_captures", Need::kOptional, &acquisition->camera_captures));
  THINSLAB_RETURN_IF_ERROR(Int(j, path, "discarded_frames", Need::kOptional, &acquisition->discarded_frames));
  const Json* events = nullptr;
  THINSLAB_RETURN_IF_ERROR(Array(j, path, "events", Need::kOptional, &events));
  if (events == nullptr) return Status::Ok();
  const std::string events_path = Child(path, "events");
  acquisition->events.assign(events->size(), AcquisitionEvent());
  for (size_t i = 0; i < events->size(); ++i) {
    const Json& e = (*events)[i];
    const std::string ep = Element(events_path, i);
    if (!e.is_object()) return ExpectedType(ep, "an object", e);
    AcquisitionEvent& event = acquisition->events[i];
    THINSLAB_RETURN_IF_ERROR(String(e, ep, "time_utc", Need::kRequired, &event.time_utc));
    THINSLAB_RETURN_IF_ERROR(String(e, ep, "event", Need::kRequired, &event.event));
    THINSLAB_RETURN_IF_ERROR(String(e, ep, "device", Need::kOptional, &event.device));
    THINSLAB_RETURN_IF_ERROR(String(e, ep, "message", Need::kOptional, &event.message));
    THINSLAB_RETURN_IF_ERROR(Int(e, ep, "frames", Need::kOptional, &event.frames));
  }
  return Status::Ok();
}

Status ManifestParser::Parse(const Json& root, Session* session) const {
  if (!root.is_object()) return ExpectedType("", "an object", root);

  // Format and version first: a file of another major version may differ in every other
  // field, so nothing else is interpreted before the version is known to be readable.
  std::string format;
  THINSLAB_RETURN_IF_ERROR(String(root, "", "format", Need::kRequired, &format));
  if (format != kFormatName) {
    return Error("format", "expected " + Quote(kFormatName) + ", got " + Quote(format));
  }
  std::string version;
  THINSLAB_RETURN_IF_ERROR(String(root, "", "format_version", Need::kRequired, &version));
  if (!ParseVersion(version, &session->format_major, &session->format_minor)) {
    return Error("format_version",
                 "expected \"<major>.<minor>\" such as \"1.0\", got " + Quote(version));
  }
  if (session->format_major != kSessionFormatMajor) {
    return Status::Error(file_ + ": format_version " + version +
                         " is not supported by this reader (supports " +
                         std::to_string(kSessionFormatMajor) + ".x)");
  }
  // Minor versions of major 1 only add optional fields; unknown fields are ignored.

  THINSLAB_RETURN_IF_ERROR(String(root, "", "name", Need::kRequired, &session->name));
  THINSLAB_RETURN_IF_ERROR(String(root, "", "kind", Need::kRequired, &session->kind));
  THINSLAB_RETURN_IF_ERROR(String(root, "", "created_utc", Need::kRequired, &session->created_utc));
  THINSLAB_RETURN_IF_ERROR(String(root, "", "software", Need::kOptional, &session->software));

  const Json* rig = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(root, "", "rig", Need::kRequired, &rig));
  THINSLAB_RETURN_IF_ERROR(ParseRig(*rig, "rig", &session->rig));

  const Json* frames = nullptr;
  THINSLAB_RETURN_IF_ERROR(Array(root, "", "frames", Need::kRequired, &frames));
  session->frames.assign(frames->size(), FrameRecord());
  for (size_t i = 0; i < frames->size(); ++i) {
    THINSLAB_RETURN_IF_ERROR(ParseFrame((*frames)[i], Element("frames", i), &session->frames[i]));
    FrameRecord& frame = session->frames[i];
    const CameraInfo* camera = session->FindCamera(frame.camera_id);
    if (std::isnan(frame.exposure_time_us)) {
      if (camera != nullptr && camera->linear_frames()) {
        frame.exposure_time_us = 1.0;
      } else {
        return Error(Element("frames", i) + ".exposure_time_us",
                     "missing; it is required unless the frame's camera declares frame_values \"linear\"");
      }
    }
  }
  const Json* acquisition = nullptr;
  THINSLAB_RETURN_IF_ERROR(Object(root, "", "acquisition", Need::kOptional, &acquisition));
  if (acquisition != nullptr) {
    THINSLAB_RETURN_IF_ERROR(ParseAcquisition(*acquisition, "acquisition", &session->acquisition));
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------
// Writing.

OrderedJson Array2(const Eigen::Vector2d& v) { return OrderedJson::array({v.x(), v.y()}); }
OrderedJson Array3(const Eigen::Vector3d& v) { return OrderedJson::array({v.x(), v.y(), v.z()}); }

OrderedJson RigidToJson(const Rigid3d& r) {
  OrderedJson j = OrderedJson::object();
  j["rotation_wxyz"] =
      OrderedJson::array({r.rotation.w(), r.rotation.x(), r.rotation.y(), r.rotation.z()});
  j["translation_m"] = Array3(r.translation);
  return j;
}

OrderedJson FrameToJson(const FrameRecord& f) {
  OrderedJson fj = OrderedJson::object();
  fj["index"] = f.index;
  fj["camera"] = f.camera_id;
  fj["kind"] = f.kind;
  fj["sample_state"] = f.sample_state;
  fj["file"] = f.file;
  if (!f.variance_file.empty()) fj["variance_file"] = f.variance_file;
  fj["exposure_time_us"] = f.exposure_time_us;
  fj["gain_db"] = f.gain_db;
  OrderedJson light = OrderedJson::object();
  light["projector_pattern"] = f.light.projector_pattern;
  light["laser_on"] = f.light.laser_on;
  if (f.light.dot_px.has_value()) light["dot_px"] = Array2(*f.light.dot_px);
  light["dot_radiance"] = f.light.dot_radiance;
  fj["light"] = std::move(light);
  fj["timestamp_utc"] = f.timestamp_utc;
  if (f.camera_frame_id.has_value()) fj["camera_frame_id"] = *f.camera_frame_id;
  if (f.camera_timestamp_ns.has_value()) fj["camera_timestamp_ns"] = *f.camera_timestamp_ns;
  fj["status"] = FrameStatusName(f.status);
  fj["error"] = f.error;
  if (f.validation) fj["validation"] = true;
  return fj;
}

OrderedJson SessionToJson(const Session& session) {
  OrderedJson root = OrderedJson::object();
  root["format"] = kFormatName;
  root["format_version"] =
      std::to_string(kSessionFormatMajor) + "." + std::to_string(kSessionFormatMinor);
  root["name"] = session.name;
  root["kind"] = session.kind;
  root["created_utc"] = session.created_utc;
  root["software"] = session.software;

  const RigInfo& rig = session.rig;
  OrderedJson rig_json = OrderedJson::object();
  OrderedJson cameras = OrderedJson::array();
  for (const CameraInfo& c : rig.cameras) {
    OrderedJson cj = OrderedJson::object();
    cj["id"] = c.id;
    cj["model"] = c.model;
    cj["serial"] = c.serial;
    cj["width_px"] = c.width_px;
    cj["height_px"] = c.height_px;
    cj["fx_px"] = c.fx_px;
    cj["fy_px"] = c.fy_px;
    cj["cx_px"] = c.cx_px;
    cj["cy_px"] = c.cy_px;
    cj["distortion"] = OrderedJson::array();
    for (double d : c.distortion) cj["distortion"].push_back(d);
    cj["cam_from_sample"] = RigidToJson(c.cam_from_sample);
    cj["bit_depth"] = c.bit_depth;
    if (c.linear_frames()) cj["frame_values"] = c.frame_values;
    cj["black_level_dn"] = c.black_level_dn;
    if (std::isfinite(c.saturation_dn)) cj["saturation_dn"] = c.saturation_dn;
    cj["gain_e_per_dn"] = c.gain_e_per_dn;
    if (c.read_noise_dn.has_value()) cj["read_noise_dn"] = *c.read_noise_dn;
    if (!c.stream_statistics.empty()) {
      OrderedJson stats = OrderedJson::object();
      for (const auto& [name, value] : c.stream_statistics) stats[name] = value;
      cj["stream_statistics"] = std::move(stats);
    }
    cameras.push_back(std::move(cj));
  }
  rig_json["cameras"] = std::move(cameras);

  OrderedJson sample = OrderedJson::object();
  sample["region_min_m"] = Array2(rig.sample.region_min_m);
  sample["region_max_m"] = Array2(rig.sample.region_max_m);
  sample["pixel_pitch_m"] = rig.sample.pixel_pitch_m;
  sample["glass_thickness_m"] = rig.sample.glass_thickness_m;
  sample["glass_ior"] = rig.sample.glass_ior;
  sample["contaminant_side"] = rig.sample.contaminant_side;
  rig_json["sample"] = std::move(sample);

  if (rig.board.present) {
    OrderedJson b = OrderedJson::object();
    b["distance_m"] = rig.board.distance_m;
    b["albedo"] = rig.board.albedo;
    rig_json["board"] = std::move(b);
  }
  if (rig.projector.present) {
    OrderedJson p = OrderedJson::object();
    p["kind"] = rig.projector.kind;
    p["direction_in_sample"] = Array3(rig.projector.direction_in_sample);
    rig_json["projector"] = std::move(p);
  }
  if (rig.laser.present) {
    OrderedJson l = OrderedJson::object();
    l["origin_in_sample"] = Array3(rig.laser.origin_in_sample);
    l["direction_in_sample"] = Array3(rig.laser.direction_in_sample);
    l["beam_radius_m"] = rig.laser.beam_radius_m;
    l["wavelength_m"] = rig.laser.wavelength_m;
    rig_json["laser"] = std::move(l);
  }
  if (rig.monitor.present) {
    OrderedJson m = OrderedJson::object();
    m["sample_from_monitor"] = RigidToJson(rig.monitor.sample_from_monitor);
    m["pixel_pitch_m"] = rig.monitor.pixel_pitch_m;
    m["width_px"] = rig.monitor.width_px;
    m["height_px"] = rig.monitor.height_px;
    if (rig.monitor.dot_radius_px > 0) m["dot_radius_px"] = rig.monitor.dot_radius_px;
    rig_json["monitor"] = std::move(m);
  }
  root["rig"] = std::move(rig_json);

  OrderedJson frames = OrderedJson::array();
  for (const FrameRecord& f : session.frames) frames.push_back(FrameToJson(f));
  root["frames"] = std::move(frames);
  if (session.acquisition.present) {
    const AcquisitionInfo& acq = session.acquisition;
    OrderedJson aj = OrderedJson::object();
    aj["state"] = acq.state;
    aj["plan"] = acq.plan;
    aj["planned_frames"] = acq.planned_frames;
    aj["camera_captures"] = acq.camera_captures;
    aj["discarded_frames"] = acq.discarded_frames;
    OrderedJson events = OrderedJson::array();
    for (const AcquisitionEvent& e : acq.events) {
      OrderedJson ej = OrderedJson::object();
      ej["time_utc"] = e.time_utc;
      ej["event"] = e.event;
      ej["device"] = e.device;
      ej["message"] = e.message;
      ej["frames"] = e.frames;
      events.push_back(std::move(ej));
    }
    aj["events"] = std::move(events);
    root["acquisition"] = std::move(aj);
  }
  return root;
}

// JSON cannot hold NaN or infinity (nlohmann would write null, which no reader accepts).
Status CheckFinite(const OrderedJson& j, const std::string& path, const std::string& file) {
  if (j.is_number_float() && !std::isfinite(j.get<double>())) {
    return Status::Error(file + ": " + path + ": non-finite value; refusing to write");
  }
  if (j.is_object()) {
    for (const auto& item : j.items()) {
      THINSLAB_RETURN_IF_ERROR(CheckFinite(item.value(), Child(path, item.key()), file));
    }
  } else if (j.is_array()) {
    for (size_t i = 0; i < j.size(); ++i) {
      THINSLAB_RETURN_IF_ERROR(CheckFinite(j[i], Element(path, i), file));
    }
  }
  return Status::Ok();
}

std::string Lowercase(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

// ---------------------------------------------------------------------------------------

Status ReadSession(const std::string& session_dir, Session* session) {
  const std::string file = ManifestPath(session_dir);
  std::string bytes;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(file, &bytes));
  Json root;
  try {
    root = Json::parse(bytes);
  } catch (const Json::parse_error& e) {
    return Status::Error(file + ": malformed JSON at byte " + std::to_string(e.byte) + ": " +
                         e.what());
  } catch (const std::exception& e) {
    return Status::Error(file + ": cannot parse JSON: " + e.what());
  }
  Session parsed;
  try {
    THINSLAB_RETURN_IF_ERROR(ManifestParser(file).Parse(root, &parsed));
  } catch (const std::exception& e) {
    // The parser checks every type before converting, so this is not expected.
    return Status::Error(file + ": unexpected error while reading: " + e.what());
  }
  THINSLAB_RETURN_IF_ERROR(ValidateSession(parsed, session_dir));
  *session = std::move(parsed);
  return Status::Ok();
}

Status WriteSession(const std::string& session_dir, const Session& session) {
  const std::string file = ManifestPath(session_dir);
  std::string text;
  try {
    const OrderedJson root = SessionToJson(session);
    THINSLAB_RETURN_IF_ERROR(CheckFinite(root, "", file));
    // Invalid UTF-8 in device strings is replaced rather than thrown on.
    text = root.dump(2, ' ', false, OrderedJson::error_handler_t::replace) + "\n";
  } catch (const std::exception& e) {
    return Status::Error(file + ": cannot encode JSON: " + e.what());
  }
  if (!session_dir.empty() && !DirectoryExists(session_dir)) {
    THINSLAB_RETURN_IF_ERROR(CreateDirectories(session_dir));
  }
  return WriteFileAtomically(file, text);
}

Status FrameRecordToJson(const FrameRecord& frame, std::string* json) {
  try {
    const OrderedJson j = FrameToJson(frame);
    THINSLAB_RETURN_IF_ERROR(CheckFinite(j, "frames[" + std::to_string(frame.index) + "]", "frame record"));
    *json = j.dump(-1, ' ', false, OrderedJson::error_handler_t::replace);
  } catch (const std::exception& e) {
    return Status::Error("frame record " + std::to_string(frame.index) + ": cannot encode JSON: " + e.what());
  }
  return Status::Ok();
}

Status ParseFrameRecordJson(const std::string& json, const std::string& where, FrameRecord* frame) {
  Json j;
  try {
    j = Json::parse(json);
  } catch (const Json::parse_error& e) {
    return Status::Error(where + ": malformed JSON at byte " + std::to_string(e.byte) + ": " + e.what());
  } catch (const std::exception& e) {
    return Status::Error(where + ": cannot parse JSON: " + e.what());
  }
  FrameRecord parsed;
  try {
    THINSLAB_RETURN_IF_ERROR(ManifestParser(where).ParseFrame(j, "frame", &parsed));
  } catch (const std::exception& e) {
    return Status::Error(where + ": unexpected error while reading: " + e.what());
  }
  *frame = std::move(parsed);
  return Status::Ok();
}

Status ValidateSession(const Session& session, const std::string& session_dir) {
  const std::string file = ManifestPath(session_dir);
  auto error = [&file](const std::string& path, const std::string& message) {
    return Status::Error(file + ": " + path + ": " + message);
  };

  if (session.format_major != kSessionFormatMajor) {
    return Status::Error(file + ": format_version " + std::to_string(session.format_major) + "." +
                         std::to_string(session.format_minor) +
                         " is not supported by this reader (supports " +
                         std::to_string(kSessionFormatMajor) + ".x)");
  }

  // Cameras.
  const RigInfo& rig = session.rig;
  if (rig.cameras.empty()) return error("rig.cameras", "at least one camera is required");
  std::map<std::string, size_t> camera_index;
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraInfo& c = rig.cameras[i];
    const std::string p = Element("rig.cameras", i);
    if (c.id.empty()) return error(p + ".id", "must be a non-empty string");
    if (!camera_index.emplace(c.id, i).second) {
      return error(p + ".id", "duplicate camera id " + Quote(c.id) + " (also " +
                                  Element("rig.cameras", camera_index[c.id]) + ")");
    }
    if (c.width_px <= 0)
      return error(p + ".width_px", "must be > 0, got " + std::to_string(c.width_px));
    if (c.height_px <= 0)
      return error(p + ".height_px", "must be > 0, got " + std::to_string(c.height_px));
    if (!(c.fx_px > 0)) return error(p + ".fx_px", "must be > 0, got " + Num(c.fx_px));
    if (!(c.fy_px > 0)) return error(p + ".fy_px", "must be > 0, got " + Num(c.fy_px));
    if (!std::isfinite(c.cx_px)) return error(p + ".cx_px", "must be finite");
    if (!std::isfinite(c.cy_px)) return error(p + ".cy_px", "must be finite");
    const size_t nd = c.distortion.size();
    if (nd != 0 && nd != 4 && nd != 5) {
      return error(p + ".distortion",
                   "must have 0, 4 (k1, k2, p1, p2) or 5 (k1, k2, p1, p2, k3) "
                   "coefficients, got " +
                       std::to_string(nd));
    }
    for (size_t k = 0; k < nd; ++k) {
      if (!std::isfinite(c.distortion[k]))
        return error(Element(p + ".distortion", k), "must be finite");
    }
    const double qn = c.cam_from_sample.rotation.norm();
    if (!(qn > 1e-12) || !std::isfinite(qn)) {
      return error(p + ".cam_from_sample.rotation_wxyz", "quaternion must be non-zero");
    }
    if (!c.cam_from_sample.translation.allFinite()) {
      return error(p + ".cam_from_sample.translation_m", "must be finite");
    }
    const auto& depths = BitDepths();
    if (std::find(depths.begin(), depths.end(), c.bit_depth) == depths.end()) {
      return error(p + ".bit_depth",
                   "must be 8, 10, 12, 14, 16 (integer frames) or 32 (float "
                   "EXR frames), got " +
                       std::to_string(c.bit_depth));
    }
    if (IsIntegerDepth(c.bit_depth)) {
      const double full_scale = std::ldexp(1.0, c.bit_depth);
      if (!(c.black_level_dn >= 0)) {
        return error(p + ".black_level_dn", "must be >= 0, got " + Num(c.black_level_dn));
      }
      if (!(c.saturation_dn > c.black_level_dn)) {
        return error(p + ".saturation_dn", "must be > black_level_dn (" + Num(c.black_level_dn) +
                                               "), got " + Num(c.saturation_dn));
      }
      if (c.saturation_dn > full_scale) {
        return error(p + ".saturation_dn", "must be <= 2^bit_depth = " + Num(full_scale) + " for " +
                                               std::to_string(c.bit_depth) +
                                               "-bit frames (DN are stored in the low "
                                               "bits), got " +
                                               Num(c.saturation_dn));
      }
    } else {
      if (!std::isfinite(c.black_level_dn)) return error(p + ".black_level_dn", "must be finite");
      // Linear frames without a saturation level hold +infinity (nothing saturates).
      if (!std::isfinite(c.saturation_dn) && !(c.linear_frames() && c.saturation_dn > 0)) {
        return error(p + ".saturation_dn", "must be finite");
      }
    }
    if (!Contains(FrameValueKinds(), c.frame_values)) {
      return error(p + ".frame_values", "must be " + OneOf(FrameValueKinds()) + ", got " + Quote(c.frame_values));
    }
    if (c.linear_frames() && c.bit_depth != 32) {
      return error(p + ".frame_values", "\"linear\" frames are float EXR frames and need bit_depth 32, got " +
                                            std::to_string(c.bit_depth));
    }
    if (c.linear_frames() && !(c.saturation_dn > c.black_level_dn)) {
      return error(p + ".saturation_dn", "must be > black_level_dn (" + Num(c.black_level_dn) + "), got " +
                                             Num(c.saturation_dn));
    }
    if (!(c.gain_e_per_dn >= 0) || !std::isfinite(c.gain_e_per_dn)) {
      return error(p + ".gain_e_per_dn", "must be >= 0 (0 = unknown), got " + Num(c.gain_e_per_dn));
    }
    if (c.read_noise_dn.has_value() && !(*c.read_noise_dn >= 0 && std::isfinite(*c.read_noise_dn))) {
      return error(p + ".read_noise_dn", "must be >= 0 (absent = unknown), got " + Num(*c.read_noise_dn));
    }
  }

  // Sample.
  const SampleInfo& s = rig.sample;
  if (!s.region_min_m.allFinite()) return error("rig.sample.region_min_m", "must be finite");
  if (!s.region_max_m.allFinite()) return error("rig.sample.region_max_m", "must be finite");
  for (int k = 0; k < 2; ++k) {
    if (!(s.region_max_m[k] > s.region_min_m[k])) {
      return error(Element("rig.sample.region_max_m", k),
                   "must be > region_min_m[" + std::to_string(k) + "] (" + Num(s.region_min_m[k]) +
                       "), got " + Num(s.region_max_m[k]));
    }
  }
  if (!(s.pixel_pitch_m > 0) || !std::isfinite(s.pixel_pitch_m)) {
    return error("rig.sample.pixel_pitch_m", "must be > 0, got " + Num(s.pixel_pitch_m));
  }
  if (!(s.glass_thickness_m >= 0) || !std::isfinite(s.glass_thickness_m)) {
    return error("rig.sample.glass_thickness_m", "must be >= 0, got " + Num(s.glass_thickness_m));
  }
  if (!(s.glass_ior >= 1) || !std::isfinite(s.glass_ior)) {
    return error("rig.sample.glass_ior", "must be >= 1, got " + Num(s.glass_ior));
  }
  if (!Contains(ContaminantSides(), s.contaminant_side)) {
    return error("rig.sample.contaminant_side",
                 "must be " + OneOf(ContaminantSides()) + ", got " + Quote(s.contaminant_side));
  }

  // Optional devices.
  if (rig.board.present) {
    if (!(rig.board.distance_m > 0 && rig.board.distance_m <= kMaxBoardDistanceM)) {
      return error("rig.board.distance_m", "must be in (0, " + Num(kMaxBoardDistanceM) + "] m, got " +
                                               Num(rig.board.distance_m));
    }
    if (!(rig.board.albedo > 0 && rig.board.albedo <= 1)) {
      return error("rig.board.albedo", "must be in (0, 1], got " + Num(rig.board.albedo));
    }
  }
  if (rig.projector.present) {
    if (!Contains(ProjectorKinds(), rig.projector.kind)) {
      return error("rig.projector.kind",
                   "must be " + OneOf(ProjectorKinds()) + ", got " + Quote(rig.projector.kind));
    }
    const double n = rig.projector.direction_in_sample.norm();
    if (!(n > 0) || !std::isfinite(n)) {
      return error("rig.projector.direction_in_sample", "must be a non-zero finite vector");
    }
    // The light must cross the sample towards the board: a direction in (or near) the sample
    // plane casts no shadow map (a fit would "succeed" on nothing).
    if (!(rig.projector.direction_in_sample.z() / n < -kMinProjectorCosine)) {
      return error("rig.projector.direction_in_sample",
                   "must point through the sample towards the board (z < 0, at most " +
                       Num(std::acos(kMinProjectorCosine) * 180 / 3.14159265358979323846) +
                       " degrees from the normal), got " + Array3Text(rig.projector.direction_in_sample));
    }
  }
  if (rig.laser.present) {
    if (!rig.laser.origin_in_sample.allFinite()) {
      return error("rig.laser.origin_in_sample", "must be finite");
    }
    const double n = rig.laser.direction_in_sample.norm();
    if (!(n > 0) || !std::isfinite(n)) {
      return error("rig.laser.direction_in_sample", "must be a non-zero finite vector");
    }
    if (!(rig.laser.beam_radius_m >= 0) || !std::isfinite(rig.laser.beam_radius_m)) {
      return error("rig.laser.beam_radius_m",
                   "must be >= 0 (0 = unknown), got " + Num(rig.laser.beam_radius_m));
    }
    if (!(rig.laser.wavelength_m >= 0) || !std::isfinite(rig.laser.wavelength_m)) {
      return error("rig.laser.wavelength_m",
                   "must be >= 0 (0 = unknown), got " + Num(rig.laser.wavelength_m));
    }
  }
  if (rig.monitor.present) {
    const MonitorInfo& m = rig.monitor;
    const double qn = m.sample_from_monitor.rotation.norm();
    if (!(qn > 1e-12) || !std::isfinite(qn)) {
      return error("rig.monitor.sample_from_monitor.rotation_wxyz", "quaternion must be non-zero");
    }
    if (!m.sample_from_monitor.translation.allFinite()) {
      return error("rig.monitor.sample_from_monitor.translation_m", "must be finite");
    }
    if (!(m.pixel_pitch_m > 0) || !std::isfinite(m.pixel_pitch_m)) {
      return error("rig.monitor.pixel_pitch_m", "must be > 0, got " + Num(m.pixel_pitch_m));
    }
    if (m.width_px <= 0)
      return error("rig.monitor.width_px", "must be > 0, got " + std::to_string(m.width_px));
    if (m.height_px <= 0)
      return error("rig.monitor.height_px", "must be > 0, got " + std::to_string(m.height_px));
    if (!(m.dot_radius_px >= 0 && m.dot_radius_px <= 1000)) {
      return error("rig.monitor.dot_radius_px", "must be in [0, 1000] monitor px (0 = not given), got " +
                                                    Num(m.dot_radius_px));
    }
  }

  // Frames.
  const int num_frames = static_cast<int>(session.frames.size());
  std::vector<int> position_of_index(session.frames.size(), -1);
  for (int i = 0; i < num_frames; ++i) {
    const FrameRecord& f = session.frames[i];
    const std::string p = Element("frames", i);
    if (f.index < 0 || f.index >= num_frames) {
      return error(p + ".index", std::to_string(f.index) + " is outside [0, " +
                                     std::to_string(num_frames) +
                                     "): frame indices must be contiguous from 0");
    }
    if (position_of_index[f.index] >= 0) {
      return error(p + ".index", "duplicate index " + std::to_string(f.index) + " (also " +
                                     Element("frames", position_of_index[f.index]) + ")");
    }
    position_of_index[f.index] = i;
    if (camera_index.count(f.camera_id) == 0) {
      std::string known;
      for (const auto& c : rig.cameras) known += (known.empty() ? "" : ", ") + c.id;
      return error(p + ".camera",
                   "unknown camera id " + Quote(f.camera_id) + " (rig.cameras has: " + known + ")");
    }
    if (f.kind.empty()) return error(p + ".kind", "must be a non-empty string");
    if (!Contains(SampleStates(), f.sample_state)) {
      return error(p + ".sample_state",
                   "must be " + OneOf(SampleStates()) + ", got " + Quote(f.sample_state));
    }
    if (!std::isfinite(f.gain_db)) return error(p + ".gain_db", "must be finite");
    if (f.light.dot_px.has_value() && !f.light.dot_px->allFinite()) {
      return error(p + ".light.dot_px", "must be finite");
    }
    if (!std::isfinite(f.light.dot_radiance))
      return error(p + ".light.dot_radiance", "must be finite");
    constexpr uint64_t kCounterLimit = uint64_t(1) << 63;
    if (f.camera_frame_id.value_or(0) >= kCounterLimit) {
      return error(p + ".camera_frame_id", "must be < 2^63, got " + std::to_string(*f.camera_frame_id));
    }
    if (f.camera_timestamp_ns.value_or(0) >= kCounterLimit) {
      return error(p + ".camera_timestamp_ns", "must be < 2^63, got " + std::to_string(*f.camera_timestamp_ns));
    }
    if (f.status == FrameStatus::kFailed) continue;
    if (!(f.exposure_time_us > 0) || !std::isfinite(f.exposure_time_us)) {
      return error(p + ".exposure_time_us", "must be > 0, got " + Num(f.exposure_time_us));
    }
    std::string resolved;
    const std::string reason = ResolveFrameFile(session_dir, f.file, &resolved);
    if (!reason.empty()) return error(p + ".file", reason + " (status " + FrameStatusName(f.status) + ")");
    if (!f.variance_file.empty()) {
      if (Lowercase(fs::path(f.variance_file).extension().string()) != ".exr") {
        return error(p + ".variance_file", "must be an .exr file, got " + Quote(f.variance_file));
      }
      const std::string variance_reason = ResolveFrameFile(session_dir, f.variance_file, &resolved);
      if (!variance_reason.empty()) return error(p + ".variance_file", variance_reason);
    }
  }
  if (session.acquisition.present) {
    const AcquisitionInfo& acq = session.acquisition;
    if (!Contains(AcquisitionStates(), acq.state)) {
      return error("acquisition.state", "must be " + OneOf(AcquisitionStates()) + ", got " + Quote(acq.state));
    }
    if (acq.planned_frames < 0) {
      return error("acquisition.planned_frames", "must be >= 0, got " + std::to_string(acq.planned_frames));
    }
    if (acq.camera_captures < 0 || acq.discarded_frames < 0) {
      return error("acquisition", "camera_captures and discarded_frames must be >= 0");
    }
  }
  return Status::Ok();
}

std::string SummarizeSession(const Session& session) {
  std::ostringstream out;
  out << "Session " << Quote(session.name) << " (kind " << session.kind << ", format_version "
      << session.format_major << "." << session.format_minor << ")\n";
  out << "  created " << (session.created_utc.empty() ? "?" : session.created_utc);
  if (!session.software.empty()) out << " by " << session.software;
  out << "\n";

  const RigInfo& rig = session.rig;
  out << "Cameras: " << rig.cameras.size() << "\n";
  for (const CameraInfo& c : rig.cameras) {
    out << "  " << c.id << ": " << c.width_px << "x" << c.height_px << " px, "
        << (c.bit_depth == 32 ? std::string("float") : std::to_string(c.bit_depth) + "-bit")
        << ", fx " << Num(c.fx_px) << " px, fy " << Num(c.fy_px) << " px, model " << c.model;
    if (!c.serial.empty()) out << ", serial " << c.serial;
    if (c.linear_frames()) out << ", linear frames";
    out << ", black " << Num(c.black_level_dn) << " DN, saturation "
        << (std::isfinite(c.saturation_dn) ? Num(c.saturation_dn) + " DN" : std::string("none"));
    out << ", gain " << (c.gain_e_per_dn > 0 ? Num(c.gain_e_per_dn) + " e/DN" : std::string("unknown"));
    if (c.read_noise_dn.has_value()) out << ", read noise " << Num(*c.read_noise_dn) << " DN";
    out << "\n";
  }
  const SampleInfo& s = rig.sample;
  out << "Sample region: [" << Num(s.region_min_m.x()) << ", " << Num(s.region_max_m.x()) << "] x ["
      << Num(s.region_min_m.y()) << ", " << Num(s.region_max_m.y()) << "] m, pitch "
      << Num(s.pixel_pitch_m) << " m, contaminant on the " << s.contaminant_side << " side\n";
  out << "Board: ";
  if (rig.board.present) {
    out << "present (distance " << Num(rig.board.distance_m) << " m, albedo "
        << Num(rig.board.albedo) << ")\n";
  } else {
    out << "absent\n";
  }
  out << "Projector: ";
  if (rig.projector.present) {
    const Eigen::Vector3d& d = rig.projector.direction_in_sample;
    out << "present (" << rig.projector.kind << ", direction (" << Num(d.x()) << ", " << Num(d.y())
        << ", " << Num(d.z()) << "))\n";
  } else {
    out << "absent\n";
  }
  out << "Laser: ";
  if (rig.laser.present) {
    out << "present (beam radius " << Num(rig.laser.beam_radius_m) << " m, wavelength "
        << Num(rig.laser.wavelength_m) << " m)\n";
  } else {
    out << "absent\n";
  }
  out << "Monitor: ";
  if (rig.monitor.present) {
    out << "present (" << rig.monitor.width_px << "x" << rig.monitor.height_px << " px, pitch "
        << Num(rig.monitor.pixel_pitch_m) << " m)\n";
  } else {
    out << "absent\n";
  }

  std::map<std::pair<std::string, std::string>, int> counts;
  int failed = 0, retried = 0, usable = 0;
  double min_exposure = std::numeric_limits<double>::infinity();
  double max_exposure = -std::numeric_limits<double>::infinity();
  for (const FrameRecord& f : session.frames) {
    if (f.status == FrameStatus::kFailed) {
      ++failed;
      continue;
    }
    if (f.status == FrameStatus::kRetried) ++retried;
    ++usable;
    ++counts[{f.kind, f.sample_state}];
    min_exposure = std::min(min_exposure, f.exposure_time_us);
    max_exposure = std::max(max_exposure, f.exposure_time_us);
  }
  out << "Frames: " << session.frames.size() << " (" << usable << " usable, " << failed
      << " failed, " << retried << " retried)\n";
  for (const auto& [key, n] : counts) {
    out << "  " << key.first << " / " << key.second << ": " << n << "\n";
  }
  if (usable > 0) {
    out << "Exposure: " << Num(min_exposure) << " .. " << Num(max_exposure) << " us\n";
  }
  if (session.acquisition.present) {
    const AcquisitionInfo& acq = session.acquisition;
    out << "Acquisition: " << acq.state << ", " << usable << " of " << acq.planned_frames
        << " planned frames, " << acq.camera_captures << " captures (" << acq.discarded_frames
        << " discarded before the display change was seen)\n";
    for (const AcquisitionEvent& e : acq.events) {
      out << "  " << e.time_utc << " " << e.event << " at " << e.frames << " frames";
      if (!e.device.empty()) out << ": " << e.device;
      if (!e.message.empty()) out << ": " << e.message;
      out << "\n";
    }
  }
  return out.str();
}

namespace {

// libpng prints decode errors ("libpng error: Read Error") on stderr itself before OpenCV
// returns an empty image; thinslab reports the failure once, through Status, naming the file.
class ScopedSilenceStderr {
 public:
  ScopedSilenceStderr() : lock_(Mutex()) {
    std::fflush(stderr);
    saved_ = ::dup(STDERR_FILENO);
    const int null_fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (saved_ >= 0 && null_fd >= 0) ::dup2(null_fd, STDERR_FILENO);
    if (null_fd >= 0) ::close(null_fd);
  }
  ~ScopedSilenceStderr() {
    std::fflush(stderr);
    if (saved_ >= 0) {
      ::dup2(saved_, STDERR_FILENO);
      ::close(saved_);
    }
  }

 private:
  static std::mutex& Mutex() {
    static std::mutex mutex;
    return mutex;
  }
  std::lock_guard<std::mutex> lock_;
  int saved_ = -1;
};

// One EXR frame file (the frame or its variance): channel "Y" or its only channel, the camera's
// size, finite values.
Status ReadFrameExr(const std::string& path, const CameraInfo& camera, Image* out) {
  Image exr;
  THINSLAB_RETURN_IF_ERROR(ReadExr(path, &exr));
  int c = exr.ChannelIndex("Y");
  if (c < 0 && exr.num_channels() == 1) c = 0;
  if (c < 0) {
    std::string names;
    for (const auto& n : exr.channel_names()) names += (names.empty() ? "" : ", ") + n;
    return Status::Error(path + ": no channel \"Y\" and more than one channel (" + names +
                         "); frame EXRs hold one linear channel named \"Y\"");
  }
  const int w = camera.width_px, h = camera.height_px;
  if (exr.width() != w || exr.height() != h) {
    return Status::Error(path + ": image is " + std::to_string(exr.width()) + "x" + std::to_string(exr.height()) +
                         " px but camera " + camera.id + " is " + std::to_string(w) + "x" + std::to_string(h) + " px");
  }
  *out = Image(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = exr.at(x, y, c);
      if (!std::isfinite(v)) {
        return Status::Error(path + ": non-finite value at pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                             ")");
      }
      out->at(x, y) = v;
    }
  }
  return Status::Ok();
}

}  // namespace

Status LoadFrameVariance(const std::string& session_dir, const Session& session, const FrameRecord& frame,
                         Image* variance) {
  *variance = Image();
  if (frame.variance_file.empty()) return Status::Ok();
  const std::string frame_name = "frame " + std::to_string(frame.index);
  const CameraInfo* camera = session.FindCamera(frame.camera_id);
  if (camera == nullptr) {
    return Status::Error(ManifestPath(session_dir) + ": " + frame_name + ": unknown camera id " +
                         Quote(frame.camera_id));
  }
  std::string path;
  const std::string reason = ResolveFrameFile(session_dir, frame.variance_file, &path);
  if (!reason.empty()) {
    return Status::Error(JoinPath(session_dir, frame.variance_file) + ": " + frame_name + " variance_file: " + reason);
  }
  THINSLAB_RETURN_IF_ERROR(ReadFrameExr(path, *camera, variance));
  for (size_t i = 0; i < variance->data().size(); ++i) {
    if (variance->data()[i] < 0) {
      const int w = camera->width_px;
      return Status::Error(path + ": " + frame_name + " variance_file: negative variance " +
                           Num(variance->data()[i]) + " at pixel (" + std::to_string(i % w) + ", " +
                           std::to_string(i / w) + ")");
    }
  }
  return Status::Ok();
}

Status LoadFrame(const std::string& session_dir, const Session& session, const FrameRecord& frame,
                 Image* image_dn) {
  const std::string manifest = ManifestPath(session_dir);
  const std::string frame_name = "frame " + std::to_string(frame.index);
  if (frame.status == FrameStatus::kFailed) {
    return Status::Error(manifest + ": " + frame_name + " has status failed and no image");
  }
  const CameraInfo* camera = session.FindCamera(frame.camera_id);
  if (camera == nullptr) {
    return Status::Error(manifest + ": " + frame_name + ": unknown camera id " +
                         Quote(frame.camera_id));
  }
  std::string path;
  const std::string reason = ResolveFrameFile(session_dir, frame.file, &path);
  if (!reason.empty()) {
    return Status::Error(JoinPath(session_dir, frame.file) + ": " + frame_name + ": " + reason);
  }

  const int w = camera->width_px, h = camera->height_px;
  auto size_error = [&](int got_w, int got_h) {
    return Status::Error(path + ": image is " + std::to_string(got_w) + "x" +
                         std::to_string(got_h) + " px but camera " + camera->id + " is " +
                         std::to_string(w) + "x" + std::to_string(h) + " px");
  };
  const double black = camera->black_level_dn;
  const std::string ext = Lowercase(fs::path(frame.file).extension().string());

  if (ext == ".exr") {
    THINSLAB_RETURN_IF_ERROR(ReadFrameExr(path, *camera, image_dn));
    for (float& v : image_dn->data()) v = static_cast<float>(static_cast<double>(v) - black);
    return Status::Ok();
  }

  if (ext != ".png" && ext != ".tif" && ext != ".tiff") {
    return Status::Error(path + ": unsupported frame file extension " + Quote(ext) +
                         " (expected .png, .tif, .tiff or .exr)");
  }
  if (!IsIntegerDepth(camera->bit_depth)) {
    return Status::Error(path + ": camera " + camera->id + " has bit_depth " +
                         std::to_string(camera->bit_depth) +
                         " (float frames); its frames must be EXR, not integer images");
  }
  cv::Mat m;
  try {
    ScopedSilenceStderr silence;
    m = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const std::exception& e) {
    return Status::Error(path + ": cannot decode image (corrupt or truncated?): " + OpenCvErrorText(e));
  }
  if (m.empty()) return Status::Error(path + ": cannot decode image (corrupt or truncated?)");
  if (m.channels() != 1) {
    return Status::Error(
        path + ": image has " + std::to_string(m.channels()) +
        " channels; frames must be single-channel (raw or monochrome), not colour");
  }
  if (m.cols != w || m.rows != h) return size_error(m.cols, m.rows);
  const int expected_depth = camera->bit_depth <= 8 ? CV_8U : CV_16U;
  if (m.depth() != expected_depth) {
    const std::string got = m.depth() == CV_8U    ? "8-bit"
                            : m.depth() == CV_16U ? "16-bit"
                                                  : "a non-integer or signed sample type";
    return Status::Error(path + ": image is " + got + " but camera " + camera->id +
                         " has bit_depth " + std::to_string(camera->bit_depth) + ", which needs " +
                         (expected_depth == CV_8U ? "8-bit" : "16-bit") + " samples");
  }
  double max_value = 0;
  cv::minMaxLoc(m, nullptr, &max_value);
  const double max_dn = std::ldexp(1.0, camera->bit_depth) - 1;
  if (max_value > max_dn) {
    return Status::Error(path + ": value " + Num(max_value) + " exceeds the " +
                         std::to_string(camera->bit_depth) + "-bit range of camera " + camera->id +
                         " (max " + Num(max_dn) +
                         "); frames hold DN in the low bits, not shifted to the top");
  }
  Image out(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double v =
          expected_depth == CV_8U ? m.at<std::uint8_t>(y, x) : m.at<std::uint16_t>(y, x);
      out.at(x, y) = static_cast<float>(v - black);
    }
  }
  *image_dn = std::move(out);
  return Status::Ok();
}

Status WriteRawFrame(const std::string& path, const Image& raw_dn, int bit_depth) {
  if (!IsIntegerDepth(bit_depth) ||
      std::find(BitDepths().begin(), BitDepths().end(), bit_depth) == BitDepths().end()) {
    return Status::Error(path + ": bit_depth " + std::to_string(bit_depth) +
                         " cannot be written as an integer PNG (8, 10, 12, 14 or 16; write float "
                         "frames with WriteExr)");
  }
  if (Lowercase(fs::path(path).extension().string()) != ".png") {
    return Status::Error(path + ": WriteRawFrame writes PNG; the file name must end in .png");
  }
  if (raw_dn.empty()) return Status::Error(path + ": refusing to write an empty image");
  if (raw_dn.num_channels() != 1) {
    return Status::Error(path + ": raw frames are single-channel, got " +
                         std::to_string(raw_dn.num_channels()) + " channels");
  }
  const int w = raw_dn.width(), h = raw_dn.height();
  const double max_dn = std::ldexp(1.0, bit_depth) - 1;
  const bool wide = bit_depth > 8;
  cv::Mat m(h, w, wide ? CV_16U : CV_8U);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = raw_dn.at(x, y);
      if (!std::isfinite(v)) {
        return Status::Error(path + ": non-finite value at pixel (" + std::to_string(x) + ", " +
                             std::to_string(y) + "); refusing to write");
      }
      const double dn = std::clamp(std::round(static_cast<double>(v)), 0.0, max_dn);
      if (wide) {
        m.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(dn);
      } else {
        m.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(dn);
      }
    }
  }
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty() && !DirectoryExists(parent.string())) {
    THINSLAB_RETURN_IF_ERROR(CreateDirectories(parent.string()));
  }
  return WritePngAtomically(path, m);
}

}  // namespace thinslab
