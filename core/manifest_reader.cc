// SPDX-License-Identifier: Apache-2.0
// Reading session.json (docs/format.md is the normative description; keep the two in step).
#include "thinslab/core/manifest_io.h"

#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <utility>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/session_format.h"
#include "thinslab/core/session_validation.h"

namespace thinslab {
namespace {

using namespace session_format;  // NOLINT: the format's shared vocabulary.

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

}  // namespace

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

}  // namespace thinslab
