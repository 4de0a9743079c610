// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/rig_io.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "thinslab/core/file.h"

namespace thinslab {

namespace {

using Json = nlohmann::json;
using OrderedJson = nlohmann::ordered_json;

// Field readers: each error names file and JSON path.
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  Status Err(const std::string& path, const std::string& what) const {
    return Status::Error(file_ + ": " + path + ": " + what);
  }
  Status Number(const Json& j, const std::string& path, const char* key, double* out, bool positive = false) const {
    const std::string p = path + "." + key;
    if (!j.contains(key) || j[key].is_null()) return Err(p, "missing");
    if (!j[key].is_number()) return Err(p, "expected a number");
    const double v = j[key].get<double>();
    if (!std::isfinite(v)) return Err(p, "not finite");
    if (positive && !(v > 0)) return Err(p, "expected a positive number, got " + std::to_string(v));
    *out = v;
    return Status::Ok();
  }
  Status Int(const Json& j, const std::string& path, const char* key, int* out, int min_value) const {
    const std::string p = path + "." + key;
    if (!j.contains(key) || j[key].is_null()) return Err(p, "missing");
    if (!j[key].is_number_integer()) return Err(p, "expected an integer");
    const long long v = j[key].get<long long>();
    if (v < min_value || v > 1000000000) return Err(p, "expected an integer >= " + std::to_string(min_value));
    *out = static_cast<int>(v);
    return Status::Ok();
  }
  Status Numbers(const Json& j, const std::string& path, const char* key, int n, std::vector<double>* out) const {
    const std::string p = path + "." + key;
    if (!j.contains(key) || !j[key].is_array()) return Err(p, "expected an array of numbers");
    if (n >= 0 && static_cast<int>(j[key].size()) != n) {
      return Err(p, "expected " + std::to_string(n) + " numbers, got " + std::to_string(j[key].size()));
    }
    out->clear();
    for (size_t k = 0; k < j[key].size(); ++k) {
      if (!j[key][k].is_number() || !std::isfinite(j[key][k].get<double>())) {
        return Err(p + "[" + std::to_string(k) + "]", "expected a finite number");
      }
      out->push_back(j[key][k].get<double>());
    }
    return Status::Ok();
  }
  Status Vec(const Json& j, const std::string& path, const char* key, Eigen::Vector2d* out) const {
    std::vector<double> v;
    THINSLAB_RETURN_IF_ERROR(Numbers(j, path, key, 2, &v));
    *out = Eigen::Vector2d(v[0], v[1]);
    return Status::Ok();
  }
  Status Vec(const Json& j, const std::string& path, const char* key, Eigen::Vector3d* out) const {
    std::vector<double> v;
    THINSLAB_RETURN_IF_ERROR(Numbers(j, path, key, 3, &v));
    *out = Eigen::Vector3d(v[0], v[1], v[2]);
    return Status::Ok();
  }
  Status Rigid(const Json& j, const std::string& path, const char* key, Rigid3d* out) const {
    const std::string p = path + "." + key;
    if (!j.contains(key) || !j[key].is_object()) return Err(p, "expected a rigid transform object");
    std::vector<double> q;
    THINSLAB_RETURN_IF_ERROR(Numbers(j[key], p, "rotation_wxyz", 4, &q));
    Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
    if (!(quat.norm() > 1e-12)) return Err(p + ".rotation_wxyz", "quaternion must be non-zero");
    out->rotation = quat.normalized();
    return Vec(j[key], p, "translation_m", &out->translation);
  }
  Status Bool(const Json& j, const std::string& path, const char* key, bool* out) const {
    if (!j.contains(key) || j[key].is_null()) return Status::Ok();  // Optional, default kept.
    if (!j[key].is_boolean()) return Err(path + "." + key, "expected true or false");
    *out = j[key].get<bool>();
    return Status::Ok();
  }

 private:
  std::string file_;
};

OrderedJson RigidJson(const Rigid3d& r) {
  const Eigen::Quaterniond q = r.rotation.normalized();
  return OrderedJson{{"rotation_wxyz", {q.w(), q.x(), q.y(), q.z()}},
                     {"translation_m", {r.translation.x(), r.translation.y(), r.translation.z()}}};
}

}  // namespace

Status ReadRigCalibration(const std::string& path, RigCalibration* rig) {
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &text));
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::parse_error& e) {
    return Status::Error(path + ": not valid JSON: " + e.what());
  }
  const Reader r(path);
  if (!root.is_object()) return r.Err("(top level)", "expected an object");
  if (!root.contains("format") || root["format"] != kRigCalibrationFormat) {
    return r.Err("format", std::string("must be \"") + kRigCalibrationFormat + "\"");
  }
  if (!root.contains("format_version") || !root["format_version"].is_string() ||
      root["format_version"].get<std::string>().rfind("1.", 0) != 0) {
    return r.Err("format_version", "expected \"1.<minor>\"");
  }
  RigCalibration out;
  if (root.contains("camera") && !root["camera"].is_null()) {
    const Json& j = root["camera"];
    const std::string p = "camera";
    if (j.is_object() && j.contains("provenance")) {
      if (!j["provenance"].is_object()) return r.Err(p + ".provenance", "expected an object");
      out.camera.provenance_json = j["provenance"].dump();
    }
    RigCameraCalibration& c = out.camera;
    c.present = true;
    if (j.contains("id") && j["id"].is_string()) c.camera_id = j["id"].get<std::string>();
    THINSLAB_RETURN_IF_ERROR(r.Int(j, p, "width_px", &c.width_px, 1));
    THINSLAB_RETURN_IF_ERROR(r.Int(j, p, "height_px", &c.height_px, 1));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "fx_px", &c.fx_px, true));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "fy_px", &c.fy_px, true));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "cx_px", &c.cx_px));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "cy_px", &c.cy_px));
    THINSLAB_RETURN_IF_ERROR(r.Numbers(j, p, "distortion", -1, &c.distortion));
    if (c.distortion.size() != 0 && c.distortion.size() != 4 && c.distortion.size() != 5) {
      return r.Err(p + ".distortion", "expected 0, 4 or 5 coefficients");
    }
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "fx_std_px", &c.fx_std_px));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "fy_std_px", &c.fy_std_px));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "cx_std_px", &c.cx_std_px));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "cy_std_px", &c.cy_std_px));
    THINSLAB_RETURN_IF_ERROR(
        r.Numbers(j, p, "distortion_std", static_cast<int>(c.distortion.size()), &c.distortion_std));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "rms_reprojection_px", &c.rms_reprojection_px));
    THINSLAB_RETURN_IF_ERROR(r.Int(j, p, "num_views", &c.num_views, 0));
    if (j.contains("board") && j["board"].is_object()) {
      THINSLAB_RETURN_IF_ERROR(r.Int(j["board"], p + ".board", "inner_cols", &c.board_inner_cols, 0));
      THINSLAB_RETURN_IF_ERROR(r.Int(j["board"], p + ".board", "inner_rows", &c.board_inner_rows, 0));
      THINSLAB_RETURN_IF_ERROR(r.Number(j["board"], p + ".board", "square_m", &c.board_square_m));
    }
  }
  if (root.contains("pose") && !root["pose"].is_null()) {
    const Json& j = root["pose"];
    const std::string p = "pose";
    if (j.is_object() && j.contains("provenance")) {
      if (!j["provenance"].is_object()) return r.Err(p + ".provenance", "expected an object");
      out.pose.provenance_json = j["provenance"].dump();
    }
    RigPoseCalibration& c = out.pose;
    c.present = true;
    THINSLAB_RETURN_IF_ERROR(r.Rigid(j, p, "cam_from_sample", &c.cam_from_sample));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "rms_reprojection_px", &c.rms_reprojection_px));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "max_reprojection_px", &c.max_reprojection_px));
    THINSLAB_RETURN_IF_ERROR(r.Int(j, p, "num_points", &c.num_points, 0));
    THINSLAB_RETURN_IF_ERROR(r.Vec(j, p, "rotation_std_rad", &c.rotation_std_rad));
    THINSLAB_RETURN_IF_ERROR(r.Vec(j, p, "translation_std_m", &c.translation_std_m));
  }
  if (root.contains("monitor") && !root["monitor"].is_null()) {
    const Json& j = root["monitor"];
    const std::string p = "monitor";
    if (j.is_object() && j.contains("provenance")) {
      if (!j["provenance"].is_object()) return r.Err(p + ".provenance", "expected an object");
      out.monitor.provenance_json = j["provenance"].dump();
    }
    RigMonitorCalibration& c = out.monitor;
    c.present = true;
    THINSLAB_RETURN_IF_ERROR(r.Rigid(j, p, "sample_from_monitor", &c.sample_from_monitor));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "pixel_pitch_m", &c.pixel_pitch_m, true));
    THINSLAB_RETURN_IF_ERROR(r.Int(j, p, "width_px", &c.width_px, 1));
    THINSLAB_RETURN_IF_ERROR(r.Int(j, p, "height_px", &c.height_px, 1));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "dot_radius_px", &c.dot_radius_px, true));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "rms_residual_m", &c.rms_residual_m));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "max_residual_m", &c.max_residual_m));
    THINSLAB_RETURN_IF_ERROR(r.Number(j, p, "homography_rms_px", &c.homography_rms_px));
    for (const auto& [key, value] : {std::pair<const char*, double*>{"grid_scale", &c.grid_scale},
                                     {"distance_error_m", &c.distance_error_m},
                                     {"distance_error_sigma_m", &c.distance_error_sigma_m},
                                     {"distance_correction_m", &c.distance_correction_m}}) {
      if (j.contains(key)) THINSLAB_RETURN_IF_ERROR(r.Number(j, p, key, value, key == std::string("grid_scale")));
    }
    if (!j.contains("dots") || !j["dots"].is_array()) return r.Err(p + ".dots", "expected an array");
    for (size_t k = 0; k < j["dots"].size(); ++k) {
      const Json& d = j["dots"][k];
      const std::string dp = p + ".dots[" + std::to_string(k) + "]";
      if (!d.is_object()) return r.Err(dp, "expected an object");
      DotRecord rec;
      THINSLAB_RETURN_IF_ERROR(r.Vec(d, dp, "dot_px", &rec.dot_px));
      THINSLAB_RETURN_IF_ERROR(r.Bool(d, dp, "detected", &rec.detected));
      THINSLAB_RETURN_IF_ERROR(r.Bool(d, dp, "clipped", &rec.clipped));
      THINSLAB_RETURN_IF_ERROR(r.Bool(d, dp, "placed_from_geometry", &rec.placed_from_geometry));
      if (rec.detected) THINSLAB_RETURN_IF_ERROR(r.Vec(d, dp, "centroid_px", &rec.centroid_px));
      if (rec.detected || rec.placed_from_geometry) {
        THINSLAB_RETURN_IF_ERROR(r.Vec(d, dp, "position_in_sample_m", &rec.position_in_sample_m));
      }
      if (rec.measured()) {
        THINSLAB_RETURN_IF_ERROR(r.Number(d, dp, "radiance_dn_per_us", &rec.radiance_dn_per_us));
        THINSLAB_RETURN_IF_ERROR(r.Bool(d, dp, "saturated", &rec.saturated));
        THINSLAB_RETURN_IF_ERROR(r.Number(d, dp, "residual_m", &rec.residual_m));
      }
      c.dots.push_back(rec);
    }
  }
  *rig = std::move(out);
  return Status::Ok();
}

Status ReadRigCalibrationIfExists(const std::string& path, RigCalibration* rig) {
  if (!FileExists(path)) {
    *rig = RigCalibration();
    return Status::Ok();
  }
  return ReadRigCalibration(path, rig);
}

Status WriteRigCalibration(const std::string& path, const RigCalibration& rig) {
  OrderedJson root;
  root["format"] = kRigCalibrationFormat;
  root["format_version"] = kRigCalibrationVersion;
  if (rig.camera.present) {
    const RigCameraCalibration& c = rig.camera;
    OrderedJson j;
    j["id"] = c.camera_id;
    j["width_px"] = c.width_px;
    j["height_px"] = c.height_px;
    j["fx_px"] = c.fx_px;
    j["fy_px"] = c.fy_px;
    j["cx_px"] = c.cx_px;
    j["cy_px"] = c.cy_px;
    j["distortion"] = c.distortion;
    j["fx_std_px"] = c.fx_std_px;
    j["fy_std_px"] = c.fy_std_px;
    j["cx_std_px"] = c.cx_std_px;
    j["cy_std_px"] = c.cy_std_px;
    j["distortion_std"] = c.distortion_std;
    j["rms_reprojection_px"] = c.rms_reprojection_px;
    j["num_views"] = c.num_views;
    j["board"] = OrderedJson{{"inner_cols", c.board_inner_cols}, {"inner_rows", c.board_inner_rows},
                             {"square_m", c.board_square_m}};
    if (!c.provenance_json.empty()) j["provenance"] = OrderedJson::parse(c.provenance_json);
    root["camera"] = j;
  }
  if (rig.pose.present) {
    const RigPoseCalibration& c = rig.pose;
    OrderedJson j;
    j["cam_from_sample"] = RigidJson(c.cam_from_sample);
    j["rms_reprojection_px"] = c.rms_reprojection_px;
    j["max_reprojection_px"] = c.max_reprojection_px;
    j["num_points"] = c.num_points;
    j["rotation_std_rad"] = {c.rotation_std_rad.x(), c.rotation_std_rad.y(), c.rotation_std_rad.z()};
    j["translation_std_m"] = {c.translation_std_m.x(), c.translation_std_m.y(), c.translation_std_m.z()};
    if (!c.provenance_json.empty()) j["provenance"] = OrderedJson::parse(c.provenance_json);
    root["pose"] = j;
  }
  if (rig.monitor.present) {
    const RigMonitorCalibration& c = rig.monitor;
    OrderedJson j;
    j["sample_from_monitor"] = RigidJson(c.sample_from_monitor);
    j["pixel_pitch_m"] = c.pixel_pitch_m;
    j["width_px"] = c.width_px;
    j["height_px"] = c.height_px;
    j["dot_radius_px"] = c.dot_radius_px;
    j["rms_residual_m"] = c.rms_residual_m;
    j["max_residual_m"] = c.max_residual_m;
    j["homography_rms_px"] = c.homography_rms_px;
    j["grid_scale"] = c.grid_scale;
    j["distance_error_m"] = c.distance_error_m;
    j["distance_error_sigma_m"] = c.distance_error_sigma_m;
    j["distance_correction_m"] = c.distance_correction_m;
    OrderedJson dots = OrderedJson::array();
    for (const DotRecord& d : c.dots) {
      OrderedJson e;
      e["dot_px"] = {d.dot_px.x(), d.dot_px.y()};
      e["detected"] = d.detected;
      if (d.clipped) e["clipped"] = true;
      if (d.placed_from_geometry) e["placed_from_geometry"] = true;
      if (d.detected) e["centroid_px"] = {d.centroid_px.x(), d.centroid_px.y()};
      if (d.detected || d.placed_from_geometry) {
        e["position_in_sample_m"] = {d.position_in_sample_m.x(), d.position_in_sample_m.y(), d.position_in_sample_m.z()};
      }
      if (d.measured()) {
        e["radiance_dn_per_us"] = d.radiance_dn_per_us;
        e["saturated"] = d.saturated;
        e["residual_m"] = d.residual_m;
      }
      dots.push_back(e);
    }
    j["dots"] = dots;
    if (!c.provenance_json.empty()) j["provenance"] = OrderedJson::parse(c.provenance_json);
    root["monitor"] = j;
  }
  // Full double precision so a read-back reproduces the values exactly.
  return WriteFileAtomically(path, root.dump(2) + "\n");
}

Status ApplyRigCalibration(const RigCalibration& rig, CameraInfo* camera) {
  if (rig.camera.present) {
    if (rig.camera.camera_id != camera->id) {
      return Status::Error("rig.json camera.id is '" + rig.camera.camera_id + "', the session's camera is '" +
                           camera->id + "'");
    }
    if (rig.camera.width_px != camera->width_px || rig.camera.height_px != camera->height_px) {
      return Status::Error("rig.json camera is " + std::to_string(rig.camera.width_px) + "x" +
                           std::to_string(rig.camera.height_px) + ", camera '" + camera->id + "' is " +
                           std::to_string(camera->width_px) + "x" + std::to_string(camera->height_px));
    }
    camera->fx_px = rig.camera.fx_px;
    camera->fy_px = rig.camera.fy_px;
    camera->cx_px = rig.camera.cx_px;
    camera->cy_px = rig.camera.cy_px;
    camera->distortion = rig.camera.distortion;
  }
  if (rig.pose.present) camera->cam_from_sample = rig.pose.cam_from_sample;
  return Status::Ok();
}

}  // namespace thinslab
