// SPDX-License-Identifier: Apache-2.0
// Turns a laser-lobe session (acquire/laser_lobe_session.h) into HDR board images: each
// exposure bracket (flat field, contaminated lobe, clean glass) is merged (calib/hdr_merge.h)
// and rectified onto the board grid of the manifest's sample region.
#pragma once

#include <string>

#include "thinslab/calib/exposure_check.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct LaserLobePreparationOptions {
  int supersample = 3;  // Rectification sub-samples per board pixel side.
  // Sample-to-board distance [m] replacing the manifest's rig.board.distance_m; 0 = the
  // manifest's. It is also the plane the frames are rectified onto (z = -distance).
  double board_distance_m = 0;
  // Pitch of the board grid the lobe is rectified onto [m], replacing the manifest's
  // rig.sample.pixel_pitch_m; 0 = the manifest's. The grid keeps the manifest's region.
  double board_pitch_m = 0;
  // SESSION/calib/rig.json (camera intrinsics and pose) and response.json (linearisation).
  SessionCalibrationOptions calibration;
  // Also keep each HDR image in camera pixels (BoardHdr::camera_*), for predictions imaged in
  // the camera (`thinslab predict`).
  bool keep_camera_hdr = false;
  bool Check(std::string* error) const;
};

struct BoardHdr {
  Image radiance;       // DN per microsecond, on the board grid.
  Image variance;       // Of `radiance`: (DN per microsecond)^2, camera pixels independent.
  Image all_saturated;  // 1 where every exposure saturated.
  // With keep_camera_hdr: the same before rectification, in camera pixels.
  Image camera_radiance, camera_variance, camera_all_saturated;
  int num_frames = 0;
  int num_exposures = 0;  // Distinct exposure times.
  // Does the camera apply the exposures it reports (calib/exposure_check.h)? Measured on the
  // bracket itself when it has >= 2 exposures; ExposureCheck::Warning() says when not.
  ExposureCheck exposure_check;
  bool empty() const { return num_frames == 0; }
};

struct LaserLobeImages {
  BoardHdr lobe;    // Laser on, contaminated sample.
  BoardHdr clean;   // Laser on, clean glass (optional).
  BoardHdr flat;    // Board flat field (optional).
  // Laser on, contaminated, frames marked validation (never fitted; `fit phase` reports how well
  // the fitted lobe predicts it); empty when the capture has none.
  BoardHdr validation_lobe;
  Image outside;    // 1 where the board pixel is outside the camera view.
  Eigen::Vector2d grid_min_m = Eigen::Vector2d::Zero();
  double pixel_pitch_m = 0;
  double board_distance_m = 0;
  double beam_radius_m = 0;
  double read_noise_dn = 0;
  FrameNoiseModel noise;  // Of the camera's frames (calib/frame_noise.h), in summary.json.
  CameraInfo camera;               // The manifest camera with the calibration applied.
  SessionCalibration calibration;  // What was applied.
};

Status PrepareLaserLobe(const std::string& session_dir, const Session& session,
                        const LaserLobePreparationOptions& options, LaserLobeImages* images);

}  // namespace thinslab
