// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/session_calibration.h"

#include <cmath>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"

namespace thinslab {

bool SessionCalibrationOptions::Check(std::string* error) const {
  if (mode != "auto" && mode != "none") {
    *error = "calibration = '" + mode + "' (--calibration, SessionCalibrationOptions::mode). Violated constraint: 'auto' or 'none'";
    return false;
  }
  if (mode == "none" && (!rig_path.empty() || !response_path.empty())) {
    *error = "calibration = 'none' contradicts an explicit rig or response file";
    return false;
  }
  return true;
}

std::string SessionCalibration::Describe() const {
  std::string out;
  if (!rig_file.empty()) {
    std::string parts;
    auto add = [&](bool used, const char* name) {
      if (!used) return;
      parts += (parts.empty() ? "" : ", ") + std::string(name);
    };
    add(intrinsics, "intrinsics");
    add(pose, "pose");
    add(monitor.present, "monitor");
    out = rig_file + " (" + (parts.empty() ? "no section used" : parts) + ")";
  }
  if (!response_file.empty()) {
    out += (out.empty() ? "" : ", ") + response_file + " (" + response.method + ")";
  }
  if (!flat_field_file.empty()) out += (out.empty() ? "" : ", ") + flat_field_file;
  return out.empty() ? "none (manifest geometry, linear camera)" : out;
}

Status LoadCameraResponse(const std::string& session_dir, const std::string& path_option, const CameraInfo& camera,
                          CameraResponse* response, std::string* used_path) {
  used_path->clear();
  *response = CameraResponse();
  std::string path = path_option;
  if (path == "linear") return Status::Ok();
  if (path.empty()) {
    path = JoinPath(JoinPath(session_dir, "calib"), "response.json");
    if (!FileExists(path)) return Status::Ok();
  }
  THINSLAB_RETURN_IF_ERROR(ReadResponse(path, response));
  if (!response->camera_id.empty() && response->camera_id != camera.id) {
    return Status::Error(path + ": camera: '" + response->camera_id + "', but the session's camera is '" + camera.id +
                         "'");
  }
  if (response->bit_depth != 0 && response->bit_depth != camera.bit_depth) {
    return Status::Error(path + ": bit_depth: " + std::to_string(response->bit_depth) + ", but camera '" + camera.id +
                         "' has bit_depth " + std::to_string(camera.bit_depth));
  }
  if (std::abs(response->black_level_dn - camera.black_level_dn) > 1e-9) {
    return Status::Error(path + ": black_level_dn: " + std::to_string(response->black_level_dn) + ", but camera '" +
                         camera.id + "' has " + std::to_string(camera.black_level_dn));
  }
  *used_path = path;
  return Status::Ok();
}

Status LoadSessionCalibration(const std::string& session_dir, const SessionCalibrationOptions& options,
                              CameraInfo* camera, SessionCalibration* calibration) {
  *calibration = SessionCalibration();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (options.mode == "none") return Status::Ok();

  std::string rig_path = options.rig_path;
  if (rig_path.empty()) {
    rig_path = JoinPath(JoinPath(session_dir, "calib"), "rig.json");
  } else if (!FileExists(rig_path)) {
    return Status::Error(rig_path + ": rig calibration file not found");
  }
  if (FileExists(rig_path)) {
    RigCalibration rig;
    THINSLAB_RETURN_IF_ERROR(ReadRigCalibration(rig_path, &rig));
    THINSLAB_RETURN_IF_ERROR(ApplyRigCalibration(rig, camera).WithContext(rig_path));
    calibration->rig_file = rig_path;
    calibration->intrinsics = rig.camera.present;
    calibration->pose = rig.pose.present;
    calibration->monitor = rig.monitor;
  }
  THINSLAB_RETURN_IF_ERROR(LoadCameraResponse(session_dir, options.response_path, *camera, &calibration->response,
                                              &calibration->response_file));
  const std::string flat_path = JoinPath(JoinPath(session_dir, "calib"), "flat_field.exr");
  if (!options.flat_field || !FileExists(flat_path)) return Status::Ok();
  Image flat;
  THINSLAB_RETURN_IF_ERROR(ReadExr(flat_path, &flat));
  const int flat_c = flat.ChannelIndex("flat"), valid_c = flat.ChannelIndex("valid");
  if (flat_c < 0 || valid_c < 0) return Status::Error(flat_path + ": expected channels 'flat' and 'valid'");
  if (flat.width() != camera->width_px || flat.height() != camera->height_px) {
    return Status::Error(flat_path + ": " + std::to_string(flat.width()) + "x" + std::to_string(flat.height()) +
                         ", camera '" + camera->id + "' is " + std::to_string(camera->width_px) + "x" +
                         std::to_string(camera->height_px));
  }
  const auto id = flat.attributes().find("camera");
  if (id != flat.attributes().end() && id->second != camera->id) {
    return Status::Error(flat_path + ": camera attribute '" + id->second + "', the session's camera is '" + camera->id +
                         "'");
  }
  calibration->flat_field = Image(flat.width(), flat.height());
  for (int y = 0; y < flat.height(); ++y) {
    for (int x = 0; x < flat.width(); ++x) {
      const float v = flat.at(x, y, flat_c);
      calibration->flat_field.at(x, y) = flat.at(x, y, valid_c) > 0 && std::isfinite(v) && v > 0 ? v : 0.0f;
    }
  }
  calibration->flat_field_file = flat_path;
  return Status::Ok();
}

void LinearizeFrame(const CameraResponse* response, Image* dn) {
  if (response == nullptr || response->IsIdentity()) return;
  for (float& v : dn->data()) v = static_cast<float>(response->Linearize(v));
}

}  // namespace thinslab
