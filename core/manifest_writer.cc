// SPDX-License-Identifier: Apache-2.0
// Writing session.json in the field order of docs/format.md.
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

namespace thinslab {
namespace {

using namespace session_format;  // NOLINT: the format's shared vocabulary.

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

}  // namespace

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

}  // namespace thinslab
