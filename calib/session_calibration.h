// SPDX-License-Identifier: Apache-2.0
// The calibration the fit stage applies to a capture (docs/format.md, "Calibration read by the
// fits"): SESSION/calib/rig.json replaces the manifest camera's intrinsics, distortion and pose
// and supplies the measured CRT dot geometry; SESSION/calib/response.json linearises every
// frame; SESSION/calib/flat_field.exr is the projector flat field of shadow-map sessions. The preparations
// (calib/shadow_map_preparation.h, calib/laser_lobe_preparation.h, fit/dmf_processing.h) load it, so every fit of a
// calibrated session uses the same numbers the calibration commands wrote, and say which files they used.
#pragma once

#include <string>

#include "thinslab/calib/response_io.h"
#include "thinslab/calib/rig_io.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct SessionCalibrationOptions {
  // "auto": use SESSION/calib/rig.json and SESSION/calib/response.json where they exist;
  // "none": the manifest's geometry and a linear camera (the files are ignored).
  std::string mode = "auto";
  std::string rig_path;       // Explicit rig.json ("" = SESSION/calib/rig.json in auto mode).
  std::string response_path;  // Explicit response.json, or "linear" ("" = SESSION/calib/response.json).
  // Also load SESSION/calib/flat_field.exr if present (set by the shadow-map preparation).
  bool flat_field = false;

  bool Check(std::string* error) const;
};

struct SessionCalibration {
  std::string rig_file;           // rig.json used ("" = none).
  bool intrinsics = false;        // Its camera section replaced the manifest's intrinsics.
  bool pose = false;              // Its pose section replaced the manifest's cam_from_sample.
  RigMonitorCalibration monitor;  // Its monitor section (present = false if none).
  std::string response_file;      // response.json used ("" = linear camera).
  CameraResponse response;
  std::string flat_field_file;  // flat_field.exr loaded ("" = none).
  Image flat_field;             // Its "flat" channel, 0 where its "valid" is 0; camera grid.

  const CameraResponse* response_or_null() const { return response_file.empty() ? nullptr : &response; }
  // One line for reports: "rig.json (intrinsics, pose), response.json (debevec)" or "none".
  std::string Describe() const;
};

// Applies the calibration to `camera` (a copy of a manifest camera of the session in
// `session_dir`). Errors name the file and field: a rig.json or response.json that does not
// parse, or that belongs to another camera (id, image size, bit depth, black level); an explicit
// path that does not exist.
Status LoadSessionCalibration(const std::string& session_dir, const SessionCalibrationOptions& options,
                              CameraInfo* camera, SessionCalibration* calibration);

// The response alone: `path_option` "linear" = none; "" = SESSION/calib/response.json if it
// exists; else that file, which must exist. Checked against `camera` as above.
Status LoadCameraResponse(const std::string& session_dir, const std::string& path_option, const CameraInfo& camera,
                          CameraResponse* response, std::string* used_path);

// Raw (black-subtracted) DN to linear DN, in place; identity for nullptr or a linear response.
void LinearizeFrame(const CameraResponse* response, Image* dn);

}  // namespace thinslab
